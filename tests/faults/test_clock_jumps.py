"""Fault injection: the host clock jumps backwards and forwards, and recorded stamps are non-monotonic.

The synchronisers (probeless/runtime/sync.py: every node that pairs messages by stamp uses them) and
pose_interp must neither crash nor mis-order: every emitted set has matching stamps, every input's
emitted stamps only go forward between jumps, every message is accounted for, and matching resumes
after a jump. The references are the stamps the test made and a constant-velocity motion evaluated
by scipy (not the code under test). The last test runs the real pose_interp node process.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from faults_common import launch_graph, write_graph
from scipy.spatial.transform import Rotation

from probeless.messages.geometry import PoseStamped
from probeless.messages.header import Header, Tick
from probeless.messages.sensor import Image
from probeless.nodes.tracking.pose_interp import PoseInterp
from probeless.runtime.sync import ApproximateTimeSync, ExactTimeSync
from probeless.runtime.testing import run_node

MS = 1_000_000
S = 1_000_000_000
T30 = 33_333_333


def host_stamps(n: int, period_ns: int, jumps: dict[int, int]) -> list[int]:
    """Stamps of ``n`` frames from a host clock that jumps by ``jumps[k]`` ns just before frame k."""
    offset, out = 0, []
    for k in range(n):
        offset += jumps.get(k, 0)
        out.append(10 * S + k * period_ns + offset)
    return out


class Collect:
    """Feeds a synchroniser, records emitted sets and unmatched reasons, checks conservation."""

    def __init__(self, cls, names, **kw):
        self.sets: list[dict] = []
        self.unmatched: list[tuple[str, int, str]] = []
        self.added = 0
        self.sync = cls(names, self.sets.append,
                        on_unmatched=lambda n, m, r: self.unmatched.append((n, m.header.stamp_ns, r)), **kw)

    def add(self, name: str, stamp: int, uid: int = 0) -> None:
        self.added += 1
        self.sync.add(name, Tick(Header(stamp, "t", uid), 1))

    def conserved(self) -> bool:
        s = self.sync
        return s.matched * len(s.names) + s.unmatched + s.queued == self.added

    def emitted(self, name: str) -> list[int]:
        return [m[name].header.stamp_ns for m in self.sets]


def epochs_monotonic(stamps: list[int], jump_ns: int) -> bool:
    """Non-decreasing except at backward jumps larger than ``jump_ns`` (the documented reset)."""
    return all(b >= a or a - b > jump_ns for a, b in zip(stamps, stamps[1:]))


@pytest.mark.parametrize("jumps", [{20: -5 * S}, {20: 10 * S}, {20: -5 * S, 40: 10 * S}, {10: -3 * S, 25: -3 * S}])
def test_exact_sync_keeps_matching_through_host_clock_jumps(jumps):
    stamps = host_stamps(60, T30, jumps)
    c = Collect(ExactTimeSync, ["rgb", "depth"])
    for t in stamps:  # both cameras on the same host clock, rgb arrives first
        c.add("rgb", t)
        c.add("depth", t)
    assert c.conserved()
    got = c.emitted("rgb")
    assert got == c.emitted("depth")
    assert got == stamps  # every frame paired, none lost at a jump, in arrival order
    assert c.sync.time_jumps == sum(1 for d in jumps.values() if d < 0)  # one reset per jump back


def test_exact_sync_before_the_fix_would_stall_after_a_jump_back():
    # what the jump handling replaces: with it switched off (a huge threshold) nothing after the jump matches
    stamps = host_stamps(40, T30, {20: -5 * S})
    c = Collect(ExactTimeSync, ["rgb", "depth"], jump_back_ns=100 * S)
    for t in stamps:
        c.add("rgb", t)
        c.add("depth", t)
    assert c.sync.matched == 20 and c.sync.unmatched_by_reason["out_of_order"] == 40


@pytest.mark.parametrize("wait", [True, False])
def test_approximate_sync_30_and_15_hz_across_a_jump_back_and_forward(wait):
    rgb = host_stamps(90, T30, {30: -4 * S, 60: 7 * S})
    depth = [t + 4 * MS for t in rgb[::2]]  # 15 Hz, 4 ms late, same host clock
    arrivals = sorted([(k * T30, "rgb", t) for k, t in enumerate(rgb)]
                      + [(2 * k * T30 + 6 * MS, "depth", t) for k, t in enumerate(depth)])
    c = Collect(ApproximateTimeSync, ["rgb", "depth"], slop_ns=10 * MS, wait_for_nearest=wait)
    for _, name, t in arrivals:
        c.add(name, t)
    c.sync.flush()
    assert c.conserved()
    pairs = list(zip(c.emitted("rgb"), c.emitted("depth")))
    assert all(abs(a - b) <= 10 * MS for a, b in pairs)  # never paired across a jump
    assert all(b - a == 4 * MS for a, b in pairs)        # each depth with its own rgb frame
    assert epochs_monotonic(c.emitted("rgb"), S) and epochs_monotonic(c.emitted("depth"), S)
    # every depth frame of every epoch is matched: 15 per epoch, 45 in all
    assert len(pairs) == 45
    assert c.sync.time_jumps >= 1


def test_small_disorder_is_out_of_order_never_a_reset():
    c = Collect(ExactTimeSync, ["a", "b"])
    for t in [0, 33, 66, 50, 99]:  # 50 ms arrives late on both inputs (a recording with non-monotonic stamps)
        c.add("a", t * MS)
        c.add("b", t * MS)
    assert c.emitted("a") == [0, 33 * MS, 66 * MS, 99 * MS]
    assert c.sync.unmatched_by_reason["out_of_order"] == 2 and c.sync.time_jumps == 0
    assert c.conserved()


def test_jump_drops_only_what_was_queued_from_before_it():
    c = Collect(ApproximateTimeSync, ["a", "b"], slop_ns=5 * MS)
    c.add("a", 20 * S)              # queued, waiting for b
    c.add("a", 21 * S)
    c.add("a", 3 * S)               # a's clock went back 18 s: the two queued ones can never match now
    c.add("b", 3 * S + MS)
    c.add("a", 3 * S + T30)         # (the nearest partner is known once a has passed b's stamp)
    assert [(n, r) for n, _, r in c.unmatched] == [("a", "time_jump"), ("a", "time_jump")]
    assert c.sets and c.emitted("a") == [3 * S] and c.emitted("b") == [3 * S + MS]
    with pytest.raises(ValueError, match="jump_back_ns"):
        ExactTimeSync(["a"], print, jump_back_ns=-1)


# --- pose_interp --------------------------------------------------------------------------------------
EXTR = np.eye(4)
EXTR[:3, 3] = [0.0, -0.06, -0.02]
VEL = np.array([0.3, -0.1, 0.05])      # m/s
OMEGA = np.array([0.0, 0.0, 0.4])      # rad/s about z


def truth(t_s: float) -> np.ndarray:
    """world_from_rgbd of a constant-velocity motion at true time ``t_s`` (scipy for the rotation)."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(OMEGA * t_s).as_matrix()
    T[:3, 3] = VEL * t_s
    return T


def interp_stream(jumps: dict[int, int], n: int = 60):
    """30 Hz poses and fisheye frames 13 ms later, all stamped by one host clock with ``jumps``;
    returns (events, {fisheye stamp: true time [s]})."""
    stamps = host_stamps(n, T30, jumps)
    true_t, events = {}, []
    img = np.zeros((2, 2, 3), np.uint8)
    for k, stamp in enumerate(stamps):
        t_true = k * T30 / 1e9
        events.append(("pose", PoseStamped(Header(stamp, "world"), "rgbd", truth(t_true))))
        fish = stamp + 13 * MS
        true_t[fish] = t_true + 0.013
        events.append(("fisheye", Image(Header(fish, "fisheye"), img, "rgb8")))
    return events, true_t


@pytest.mark.parametrize("jumps", [{20: -5 * S}, {20: 10 * S}, {15: 10 * S, 40: -10 * S}])
def test_pose_interp_through_host_clock_jumps_publishes_only_true_poses(jumps):
    events, true_t = interp_stream(jumps)
    ctx = run_node(PoseInterp, events, {"translation": EXTR[:3, 3].tolist(), "rpy_deg": [0.0, 0.0, 0.0],
                                        "max_extrapolation_s": 0.05, "max_gap_s": 0.25, "jump_back_s": 1.0})
    poses, frames = ctx.outputs("fisheye_pose"), ctx.outputs("fisheye")
    assert [p.header.stamp_ns for p in poses] == [f.header.stamp_ns for f in frames]
    for p in poses:  # never a pose interpolated across a jump: each is the true pose of its frame's true time
        want = truth(true_t[p.header.stamp_ns]) @ np.linalg.inv(EXTR)
        assert np.abs(p.target_from_source[:3, 3] - want[:3, 3]).max() < 1e-9
        assert np.abs(p.target_from_source[:3, :3] - want[:3, :3]).max() < 1e-9
    got = [p.header.stamp_ns for p in poses]
    assert epochs_monotonic(got, S)
    # at most the frame or two around each jump is lost (no bracket, or the hold of the old epoch)
    assert len(got) >= 60 - 2 * len(jumps)


# --- real processes ------------------------------------------------------------------------------------
@pytest.mark.graph
def test_real_pose_interp_process_survives_host_clock_jumps(tmp_path):
    g = write_graph(tmp_path, f"""
nodes:
  - id: rig
    node: injectors:JumpyRig
    inputs: {{tick: timer/hz/100}}
    params: {{count: 60, jump_at: [20, 40], jump_s: [-5.0, 10.0], truth_out: {tmp_path}/truth.json}}
  - id: interp
    node: pose_interp
    inputs:
      pose: {{source: rig/pose, policy: block, queue_size: 8}}
      fisheye: {{source: rig/fisheye, policy: block, queue_size: 8}}
    outputs: [fisheye_pose, fisheye]
    params: {{translation: [0.0, -0.06, -0.02], rpy_deg: [0.0, 0.0, 0.0], max_extrapolation_s: 0.05}}
  - id: sink
    node: injectors:StampLog
    inputs:
      fisheye_pose: {{source: interp/fisheye_pose, policy: block, queue_size: 8}}
      fisheye: {{source: interp/fisheye, policy: block, queue_size: 8}}
    params: {{out: {tmp_path}/sink.json}}
""")
    code, log = launch_graph(g, timeout_s=90)
    assert code == 0, log
    assert "Traceback" not in log
    rec = json.loads((tmp_path / "sink.json").read_text())
    poses = rec["fisheye_pose"]
    assert [p[0] for p in poses] == [f[0] for f in rec["fisheye"]]  # pose and frame in step, same stamps
    assert epochs_monotonic([p[0] for p in poses], S)
    assert len(poses) >= 60 - 4
    true_t = {stamp: t for stamp, t in json.loads((tmp_path / "truth.json").read_text())}
    for stamp, translation in poses:
        want = truth(true_t[stamp]) @ np.linalg.inv(EXTR)
        assert np.abs(np.array(translation) - want[:3, 3]).max() < 1e-9
