"""Pose interpolation: slerp against scipy and analytic motion, edge cases, PoseBuffer, the pose_interp node."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from probeless.errors import ParamError, ProbelessError
from probeless.geom.rotation import slerp, transform_from_rpy
from probeless.messages.geometry import PoseStamped
from probeless.messages.header import Header
from probeless.messages.sensor import Image
from probeless.nodes.tracking.pose_interp import PoseInterp
from probeless.runtime.testing import run_node
from probeless.tracking.interp import PoseBuffer, interpolate_pose

MS = 1_000_000
AXIS = np.array([1.0, -2.0, 0.5]) / np.linalg.norm([1.0, -2.0, 0.5])
OMEGA = np.radians(90.0)  # rad/s
R_BASE = Rotation.from_euler("xyz", [-100, 20, 35], degrees=True)
V, P0 = np.array([0.4, -0.2, 0.1]), np.array([1.0, 2.0, 1.5])
FISHEYE_FROM_RGBD = transform_from_rpy([0.0, -0.06, -0.02], [-90.0, 0.0, 0.0])


def true_pose(t: float) -> np.ndarray:
    """world_from_rgbd moving at constant linear velocity V and angular velocity OMEGA about AXIS."""
    T = np.eye(4)
    T[:3, :3] = (Rotation.from_rotvec(AXIS * OMEGA * t) * R_BASE).as_matrix()
    T[:3, 3] = P0 + V * t
    return T


def angle_deg(Ra: np.ndarray, Rb: np.ndarray) -> float:
    return float(np.degrees(Rotation.from_matrix(Ra.T @ Rb).magnitude()))


# -- slerp and interpolate_pose -------------------------------------------------------------


def test_slerp_matches_scipy_on_random_quaternions_with_random_signs():
    rng = np.random.default_rng(1)
    quats = Rotation.random(200, random_state=2).as_quat()
    for k in range(100):
        q0, q1 = quats[2 * k], quats[2 * k + 1]
        s = rng.uniform(0.0, 1.0)
        ref = Slerp([0.0, 1.0], Rotation.from_quat([q0, q1]))([s])[0]
        sign0, sign1 = rng.choice([-1.0, 1.0], 2)
        got = Rotation.from_quat(slerp(sign0 * q0, sign1 * q1, s))
        assert (got.inv() * ref).magnitude() < 1e-9


def test_interpolation_and_extrapolation_exact_at_constant_velocity():
    t0, t1 = 1.0, 1.0 + 1 / 30
    T0, T1 = true_pose(t0), true_pose(t1)
    for t in (t0, t1, 1.013, 1.02, t1 + 0.013, t1 + 0.05, t0 - 0.02, 2.0):  # inside, ahead, behind, far ahead
        T = interpolate_pose(T0, t0, T1, t1, t)
        ref = true_pose(t)
        assert angle_deg(T[:3, :3], ref[:3, :3]) < 1e-7
        assert np.abs(T[:3, 3] - ref[:3, 3]).max() < 1e-12


def test_interpolate_pose_in_integer_nanoseconds():
    T = interpolate_pose(true_pose(0.0), 0, true_pose(0.1), 100 * MS, 13 * MS)
    assert angle_deg(T[:3, :3], true_pose(0.013)[:3, :3]) < 1e-7


def test_slerp_identical_and_opposite_sign_quaternions_do_not_move():
    q = Rotation.from_euler("xyz", [10, 20, 30], degrees=True).as_quat()
    for s in (-1.0, 0.0, 0.3, 1.0, 2.5):
        for q1 in (q, -q):  # -q is the same rotation: no 360-degree turn
            got = Rotation.from_quat(slerp(q, q1, s))
            assert (got.inv() * Rotation.from_quat(q)).magnitude() < 1e-12


def test_sign_flip_gives_the_same_rotation_and_the_shortest_arc():
    rng = np.random.default_rng(3)
    for _ in range(50):
        q0, q1 = Rotation.random(2, random_state=int(rng.integers(1 << 30))).as_quat()
        full = (Rotation.from_quat(q0).inv() * Rotation.from_quat(q1)).magnitude()  # in [0, pi]
        for s in (0.25, 0.5, 1.5):
            a, b = Rotation.from_quat(slerp(q0, q1, s)), Rotation.from_quat(slerp(q0, -q1, s))
            assert (a.inv() * b).magnitude() < 1e-9
            expected = s * full if s * full <= np.pi else 2 * np.pi - s * full  # angle from q0, modulo a turn
            assert abs((Rotation.from_quat(q0).inv() * a).magnitude() - expected) < 1e-9


def test_slerp_near_and_at_180_degrees():
    identity = np.array([0.0, 0.0, 0.0, 1.0])
    near = Rotation.from_rotvec([0, 0, np.radians(179.0)]).as_quat()
    for q1 in (near, -near):  # the 179-degree arc, never the 181-degree one
        mid = Rotation.from_quat(slerp(identity, q1, 0.5))
        assert np.allclose(mid.as_rotvec(), [0, 0, np.radians(89.5)], atol=1e-12)
    half_turn = np.array([0.0, 0.0, 1.0, 0.0])  # 180 degrees about z: both arcs equally short
    for q1, direction in ((half_turn, 1.0), (-half_turn, -1.0)):  # documented: towards q1 as given
        mid = Rotation.from_quat(slerp(identity, q1, 0.5))
        assert np.allclose(mid.as_rotvec(), [0, 0, direction * np.pi / 2], atol=1e-12)
        end = Rotation.from_quat(slerp(identity, q1, 1.0))
        assert (end.inv() * Rotation.from_quat(half_turn)).magnitude() < 1e-12


def test_interpolate_pose_needs_two_stamps_and_rpy_matches_scipy():
    with pytest.raises(ProbelessError, match="both poses"):
        interpolate_pose(np.eye(4), 5, np.eye(4), 5, 6)
    T = transform_from_rpy([0.1, 0.2, 0.3], [-90, 10, 30])
    assert np.allclose(T[:3, :3], Rotation.from_euler("xyz", [-90, 10, 30], degrees=True).as_matrix(), atol=1e-12)
    assert np.allclose(T[:3, 3], [0.1, 0.2, 0.3])


# -- PoseBuffer -----------------------------------------------------------------------------


def test_pose_buffer_ordering_duplicates_stale_and_bound():
    buf = PoseBuffer(length=4, jump_back_ns=1000 * MS)
    outcomes = [buf.insert(t * MS, true_pose(t / 1000)) for t in (0, 66, 33, 100)]
    assert outcomes == ["appended", "appended", "out_of_order", "appended"]
    assert buf.stamps == [0, 33 * MS, 66 * MS, 100 * MS]
    assert buf.insert(33 * MS, true_pose(0.5)) == "duplicate"  # the re-estimate replaces the pose
    assert len(buf) == 4 and np.allclose(buf.poses[1], true_pose(0.5))
    assert buf.insert(133 * MS, true_pose(0.133)) == "appended"
    assert buf.stamps == [33 * MS, 66 * MS, 100 * MS, 133 * MS]  # bounded: the oldest went
    assert buf.insert(10 * MS, np.eye(4)) == "stale"
    assert buf.insert(50 * MS, true_pose(0.05)) == "out_of_order"
    assert buf.stamps == [50 * MS, 66 * MS, 100 * MS, 133 * MS]
    assert buf.counts == {"appended": 4, "out_of_order": 2, "duplicate": 1, "stale": 1}


def test_pose_buffer_time_jump_clears():
    buf = PoseBuffer(length=8, jump_back_ns=500 * MS)
    for t in range(0, 2000, 100):
        buf.insert(t * MS, true_pose(t / 1000))
    assert buf.insert(1550 * MS, np.eye(4)) == "out_of_order"  # within the jump threshold
    assert buf.insert(0, true_pose(0.0)) == "time_jump"
    assert buf.stamps == [0] and buf.counts["time_jump"] == 1


def test_pose_buffer_query_reasons():
    buf = PoseBuffer(length=8, max_gap_ns=200 * MS)
    assert buf.query(0, 50 * MS) == (None, "empty")
    buf.insert(0, true_pose(0.0))
    assert buf.query(10 * MS, 50 * MS) == (None, "single_pose")
    buf.insert(33 * MS, true_pose(0.033))
    buf.insert(400 * MS, true_pose(0.4))
    assert buf.query(0, 0)[1] == "exact" and np.array_equal(buf.query(0, 0)[0], true_pose(0.0))
    for t, limit, reason in ((20, 0, "interpolated"), (440, 50, "gap"), (-40, 50, "extrapolated"),
                             (460, 50, "beyond_extrapolation"), (-60, 50, "before_first"), (200, 50, "gap")):
        T, got = buf.query(t * MS, limit * MS)
        assert got == reason, (t, got)
        if T is not None and reason == "interpolated":
            assert angle_deg(T[:3, :3], true_pose(t / 1000)[:3, :3]) < 1e-7
    buf.insert(433 * MS, true_pose(0.433))  # the extrapolation uses the two newest, 33 ms apart
    T, reason = buf.query(460 * MS, 50 * MS)
    assert reason == "extrapolated" and np.abs(T[:3, 3] - true_pose(0.46)[:3, 3]).max() < 1e-12


# -- the node -------------------------------------------------------------------------------

PARAMS = {"translation": [0.0, -0.06, -0.02], "rpy_deg": [-90.0, 0.0, 0.0]}
PIXELS = np.zeros((2, 2, 3), np.uint8)


def pose_msg(t_ns: int, T: np.ndarray | None = None) -> tuple[str, PoseStamped]:
    return "pose", PoseStamped(Header(t_ns, "world"), "rgbd", true_pose(t_ns / 1e9) if T is None else T)


def fisheye_msg(t_ns: int) -> tuple[str, Image]:
    return "fisheye", Image(Header(t_ns, "fisheye"), PIXELS, "rgb8")


def live_stream(seconds: float, pose_lag_ns: int = 0) -> list:
    """RGB-D poses at 30 Hz and fisheye frames at 15 Hz (+13 ms), each delivered at its stamp (+ lag for poses)."""
    events = [(round(k * 1e9 / 30) + pose_lag_ns, pose_msg(round(k * 1e9 / 30))) for k in range(int(seconds * 30) + 1)]
    events += [(13 * MS + round(k * 1e9 / 15), fisheye_msg(13 * MS + round(k * 1e9 / 15)))
               for k in range(int(seconds * 15))]
    return [m for _, m in sorted(events, key=lambda e: e[0])]


def pairs(ctx) -> list[tuple[PoseStamped, Image]]:
    poses, frames = ctx.outputs("fisheye_pose"), ctx.outputs("fisheye")
    assert len(poses) == len(frames)
    assert [o for o, _ in ctx.published] == ["fisheye_pose", "fisheye"] * len(poses)  # pose, then its frame
    return list(zip(poses, frames))


def check_against_truth(pose: PoseStamped, frame: Image) -> None:
    assert pose.header.stamp_ns == frame.header.stamp_ns
    assert (pose.header.frame_id, pose.child_frame_id) == ("world", "fisheye")
    truth = true_pose(frame.header.stamp_ns / 1e9) @ np.linalg.inv(FISHEYE_FROM_RGBD)
    assert angle_deg(pose.rotation, truth[:3, :3]) < 1e-6
    assert np.abs(pose.translation - truth[:3, 3]).max() < 1e-9


class PoseInterpProbe(PoseInterp):
    """PoseInterp that leaves its counters on the context at close, for assertions."""

    def close(self) -> None:
        super().close()
        self.ctx.counts = dict(self.counts)


def run(stream: list, **params):
    return run_node(PoseInterpProbe, stream, {**PARAMS, **params})


def test_node_live_extrapolates_from_the_two_newest_poses():
    ctx = run(live_stream(1.0))
    got = pairs(ctx)
    assert len(got) == 15
    for pose, frame in got:
        check_against_truth(pose, frame)
    # the first frame (13 ms) follows a single pose: held until the 33 ms pose brackets it
    assert got[0][1].header.stamp_ns == 13 * MS
    assert ctx.counts == {"pose:appended": 31, "published:interpolated": 1, "published:extrapolated": 14}


def test_node_extrapolation_limit_and_held_frames_released_by_a_newer_pose():
    stream = [pose_msg(0), pose_msg(33 * MS), fisheye_msg(100 * MS), fisheye_msg(60 * MS), pose_msg(133 * MS)]
    ctx = run(stream, max_extrapolation_s=0.05)
    got = pairs(ctx)
    # 100 ms is 67 ms past the newest pose: held; 60 ms (27 ms past) goes out at once; the 133 ms pose releases 100 ms
    assert [f.header.stamp_ns for _, f in got] == [60 * MS, 100 * MS]
    for pose, frame in got:
        check_against_truth(pose, frame)
    assert ctx.counts == {"pose:appended": 3, "published:extrapolated": 1, "published:interpolated": 1}


def test_node_wait_for_bracket_only_interpolates():
    ctx = run(live_stream(1.0), wait_for_bracket=True)
    got = pairs(ctx)
    assert len(got) == 15
    for pose, frame in got:
        check_against_truth(pose, frame)
    assert ctx.counts["published:interpolated"] == 15 and "published:extrapolated" not in ctx.counts


def test_node_hold_expiry_overflow_and_close_are_counted():
    stream = [pose_msg(0), pose_msg(33 * MS)] + [fisheye_msg((100 + 66 * k) * MS) for k in range(5)]
    ctx = run(stream, hold_frames=2)
    assert ctx.published == []
    assert ctx.counts == {"pose:appended": 2, "drop:hold_overflow": 3, "drop:unresolved_at_close": 2}
    ctx = run(stream, max_hold_s=0.1)
    assert ctx.published == []
    assert ctx.counts == {"pose:appended": 2, "drop:hold_expired": 3, "drop:unresolved_at_close": 2}
    ctx = run(stream, hold_frames=0)
    assert ctx.counts == {"pose:appended": 2, "drop:hold_overflow": 5}


def test_node_duplicates_out_of_order_poses_and_gaps():
    stream = [pose_msg(0), pose_msg(66 * MS), pose_msg(33 * MS), pose_msg(33 * MS), fisheye_msg(40 * MS),
              fisheye_msg(40 * MS), pose_msg(600 * MS), fisheye_msg(300 * MS), fisheye_msg(20 * MS)]
    ctx = run(stream, max_gap_s=0.25)
    got = pairs(ctx)
    assert [f.header.stamp_ns for _, f in got] == [40 * MS, 20 * MS]  # 40 ms once; 20 ms out of order is fine
    for pose, frame in got:
        check_against_truth(pose, frame)
    assert ctx.counts == {"pose:appended": 3, "pose:out_of_order": 1, "pose:duplicate": 1,
                          "published:interpolated": 2, "drop:duplicate_stamp": 1, "drop:gap": 1}


def test_node_replay_loop_restarts_cleanly():
    one_pass = live_stream(0.5, pose_lag_ns=20 * MS)  # each pass starts with a fisheye frame before any pose
    ctx = run(one_pass + one_pass, jump_back_s=0.3)
    got = pairs(ctx)
    assert len(got) == 14
    for pose, frame in got:
        check_against_truth(pose, frame)
    assert [f.header.stamp_ns for _, f in got[:7]] == [f.header.stamp_ns for _, f in got[7:]]
    assert ctx.counts["pose:time_jump"] == 1 and not any(k.startswith("drop:") for k in ctx.counts)


def test_node_extrinsics_from_the_input_alone():
    other = transform_from_rpy([0.05, 0.0, 0.1], [-80.0, 5.0, 0.0])
    stream = [("fisheye_from_rgbd", PoseStamped(Header(0, "fisheye"), "rgbd", other)),
              pose_msg(0), pose_msg(33 * MS), fisheye_msg(13 * MS)]
    (pose, frame), = pairs(run(stream, translation=None, rpy_deg=None))
    assert pose.header.stamp_ns == frame.header.stamp_ns == 13 * MS
    truth = true_pose(0.013) @ np.linalg.inv(other)
    assert angle_deg(pose.rotation, truth[:3, :3]) < 1e-6 and np.abs(pose.translation - truth[:3, 3]).max() < 1e-9


def test_node_rejects_a_short_extrinsics_param():
    with pytest.raises(ParamError, match="translation"):
        run([], translation=[0.0, 0.1])


def test_node_fisheye_time_jump_drops_frames_held_from_the_previous_pass():
    stream = [pose_msg(0), pose_msg(33 * MS), fisheye_msg(900 * MS), fisheye_msg(13 * MS)]
    ctx = run(stream, jump_back_s=0.3)
    (pose, frame), = pairs(ctx)
    check_against_truth(pose, frame)
    assert ctx.counts == {"pose:appended": 2, "drop:time_jump": 1, "published:interpolated": 1}
