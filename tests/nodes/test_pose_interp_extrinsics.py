"""pose_interp's extrinsics come from one place: a calibration file, the params, or the fisheye_from_rgbd input."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from nodes.tracking.pose_interp import PoseInterp
from probeless.cameras.extrinsics import save_extrinsics
from probeless.errors import ParamError
from probeless.messages.geometry import PoseStamped
from probeless.messages.header import Header
from probeless.messages.sensor import Image
from probeless.runtime.params import check_params
from probeless.runtime.testing import run_node

MS = 1_000_000


def rigid(translation, rotvec_deg) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(np.radians(rotvec_deg)).as_matrix()
    T[:3, 3] = translation
    return T


FISHEYE_FROM_RGBD = rigid([0.01, -0.055, -0.03], [-88.0, 1.5, -2.0])


def world_from_rgbd(t_s: float) -> np.ndarray:
    return rigid([0.5 + 0.3 * t_s, 1.0, 1.4], [0.0, 0.0, 20.0 * t_s])


def stream(extrinsics_first: bool, T_in: np.ndarray | None) -> list:
    msgs = [("pose", PoseStamped(Header(k * 33 * MS, "world"), "rgbd", world_from_rgbd(k * 0.033))) for k in range(10)]
    frames = [("fisheye", Image(Header(13 * MS + k * 66 * MS, "fisheye"), np.zeros((2, 2, 3), np.uint8), "rgb8"))
              for k in range(4)]
    ext = [] if T_in is None else [("fisheye_from_rgbd", PoseStamped(Header(0, "fisheye"), "rgbd", T_in))]
    return ext + msgs + frames if extrinsics_first else msgs + frames + ext


def check_poses(ctx, T: np.ndarray) -> None:
    poses = ctx.outputs("fisheye_pose")
    assert len(poses) == 4
    for p in poses:
        t = p.header.stamp_ns / 1e9
        # independent: scipy Slerp between the bracketing poses, then the rigid offset
        k = int(t // 0.033)
        a, b = world_from_rgbd(k * 0.033), world_from_rgbd((k + 1) * 0.033)
        w = (t - k * 0.033) / 0.033
        from scipy.spatial.transform import Slerp

        R = Slerp([0, 1], Rotation.from_matrix([a[:3, :3], b[:3, :3]]))(w).as_matrix()
        expect = np.eye(4)
        expect[:3, :3], expect[:3, 3] = R, (1 - w) * a[:3, 3] + w * b[:3, 3]
        expect = expect @ np.linalg.inv(T)
        np.testing.assert_allclose(p.target_from_source, expect, atol=1e-9)


@pytest.mark.parametrize("extrinsics_first", [True, False])
def test_input_extrinsics_are_used_and_frames_wait_for_them(extrinsics_first):
    ctx = run_node(PoseInterp, stream(extrinsics_first, FISHEYE_FROM_RGBD), {"hold_frames": 8, "max_hold_s": 1.0})
    check_poses(ctx, FISHEYE_FROM_RGBD)


def test_calibration_file_is_used(tmp_path):
    path = tmp_path / "extrinsics.yaml"
    save_extrinsics(path, FISHEYE_FROM_RGBD)
    ctx = run_node(PoseInterp, stream(True, None), {"extrinsics": str(path)})
    check_poses(ctx, FISHEYE_FROM_RGBD)
    # the input agreeing with the file (within 1 mm / 0.1 deg) is accepted
    ctx = run_node(PoseInterp, stream(True, FISHEYE_FROM_RGBD @ rigid([0.0002, 0, 0], [0, 0, 0.02])),
                   {"extrinsics": str(path)})
    check_poses(ctx, FISHEYE_FROM_RGBD)


def test_calibration_that_disagrees_with_the_rig_is_an_error(tmp_path):
    path = tmp_path / "extrinsics.yaml"
    save_extrinsics(path, FISHEYE_FROM_RGBD)
    off = FISHEYE_FROM_RGBD @ rigid([0.02, 0, 0], [0, 0, 0])
    with pytest.raises(ParamError, match="20.0 mm.*does not match the rig"):
        run_node(PoseInterp, stream(True, off), {"extrinsics": str(path)})


def test_no_extrinsics_drops_every_frame_and_says_why():
    class Probe(PoseInterp):
        def close(self):
            super().close()
            self.ctx.counts = dict(self.counts)

    ctx = run_node(Probe, stream(True, None), {})
    assert ctx.outputs("fisheye_pose") == [] and ctx.counts["drop:no_extrinsics"] == 4


def test_params_rules():
    ok = check_params(PoseInterp.Params, {"translation": [0, 0, 0], "rpy_deg": [0, 0, 0]}, node_id="interp")
    assert not ok
    assert any("together" in str(e) for e in check_params(PoseInterp.Params, {"translation": [0, 0, 0]},
                                                          node_id="interp"))


def test_a_scene_files_rig_extrinsics_are_read():
    from probeless.cameras.extrinsics import from_rpy, load_extrinsics
    from tests.locations import REPO

    T = load_extrinsics(REPO / "launch/scenes/l_shaped_lounge.yaml")
    np.testing.assert_allclose(T, from_rpy([0.0, -0.06, -0.02], [-90, 0, 0]))
    np.testing.assert_allclose(T[:3, :3], Rotation.from_euler("x", -90, degrees=True).as_matrix(), atol=1e-12)
