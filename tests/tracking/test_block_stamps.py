"""Per-point fusion stamps of the dense model (issue 17 §5): the voxel-block stamp table against a plain
dict, and a camera that looks at wall A, then turns to wall B, checked against an independent
frustum + depth test of every extracted point against the frames that were fused."""

from __future__ import annotations

import time

import numpy as np
import open3d as o3d
import pytest
from scipy.spatial.transform import Rotation

from probeless.tracking.block_stamps import BlockStamps, blocks_of_points, pack_blocks
from probeless.tracking.dense import DenseSlam, SlamParams

W, H, F = 320, 240, 260.0
K = np.array([[F, 0, (W - 1) / 2], [0, F, (H - 1) / 2], [0, 0, 1]])
HALF = np.array([2.0, 1.5, 2.0])   # the room: |x| <= 2, |y| <= 1.5, |z| <= 2 [m]; the camera turns at its centre
TRUNC = 0.08                       # SlamParams' truncation: 8 voxels of 1 cm
# heading of each frame: wall A (z = 2), then wall B (x = 2); 4 frames each, as the extraction keeps voxels
# whose weight exceeds 3 (asserted below)
TURN_DEG = [0, 0, 0, 0, 30, 60, 90, 90, 90, 90]
STAMPS = [(k + 1) * 1_000_000_000 + 7 for k in range(len(TURN_DEG))]


def test_packed_keys_are_unique_and_the_table_matches_a_dict():
    rng = np.random.default_rng(0)
    coords = rng.integers(-(1 << 20), 1 << 20, size=(5000, 3))
    assert len(np.unique(pack_blocks(coords))) == len(np.unique(coords, axis=0))
    with pytest.raises(ValueError, match="beyond"):
        pack_blocks([[1 << 20, 0, 0]])
    table, ref = BlockStamps(0.01, 16), {}
    for stamp in (5, 9, 11, 12):
        touched = rng.integers(-6, 6, size=(40, 3))
        table.touch(touched, stamp)
        ref.update({tuple(c): stamp for c in touched})
    pts = rng.uniform(-1.2, 1.2, size=(3000, 3))
    expected = [ref.get(tuple(b), -1) for b in np.floor(pts / 0.16).astype(int)]  # 16 voxels of 1 cm
    assert table.lookup(pts, default=-1).tolist() == expected
    assert len(table) == len(ref) and -1 in expected and 12 in expected
    # a point sits in the cell of the voxel below it on every axis, whichever side of zero
    np.testing.assert_array_equal(blocks_of_points([[-1e-6, 0.159, 0.161]], 0.01, 16), [[-1, 0, 1]])


def pose(deg: float) -> np.ndarray:
    """world_from_camera: at the room's centre, turned ``deg`` about y (0: looking down +z at wall A)."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("y", deg, degrees=True).as_matrix()
    return T


def render_depth(T: np.ndarray) -> np.ndarray:
    """Exact depth [mm] of the box room from the camera at T (rays against the walls from inside)."""
    v, u = np.mgrid[0:H, 0:W].astype(np.float64)
    rays = np.stack([(u - K[0, 2]) / F, (v - K[1, 2]) / F, np.ones_like(u)], axis=-1)  # z = 1: t is the depth
    d = rays @ T[:3, :3].T
    with np.errstate(divide="ignore"):
        t = np.min(np.where(np.abs(d) > 1e-12, HALF / np.abs(d), np.inf), axis=-1)
    return np.round(t * 1000).astype(np.uint16)


class _TruePose:
    """Stands in for Open3D's odometry (the ``DenseSlam.odometry`` seam): returns the true motion, so
    that only the mapping and its stamps are under test (four flat walls leave ICP directions free)."""

    def __init__(self, slam: DenseSlam):
        self.slam, self.truth = slam, np.eye(4)

    def __call__(self, *args):
        rel = np.linalg.inv(self.slam.raycast_pose) @ self.truth
        return type("Result", (), {"transformation": o3d.core.Tensor(rel), "fitness": 1.0})()


def expected_stamps(points: np.ndarray, poses: list, depths: list) -> np.ndarray:
    """Independent reference: the stamp of the last frame whose view holds each point on its measured
    surface (in the frustum, nearest pixel's depth within the truncation band); 0 = none."""
    out = np.zeros(len(points), np.int64)
    for T, depth, stamp in zip(poses, depths, STAMPS):
        cam = (points - T[:3, 3]) @ T[:3, :3]
        z = cam[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.round(F * cam[:, 0] / z + K[0, 2])
            v = np.round(F * cam[:, 1] / z + K[1, 2])
        inside = (z > 0) & (u >= 0) & (u < W) & (v >= 0) & (v < H)
        measured = np.zeros(len(points))
        measured[inside] = depth[v[inside].astype(int), u[inside].astype(int)] / 1000.0
        out[inside & (measured > 0) & (np.abs(measured - z) < TRUNC)] = stamp
    return out


def test_points_keep_the_stamp_of_the_last_frame_that_saw_them():
    poses = [pose(d) for d in TURN_DEG]
    depths = [render_depth(T) for T in poses]
    rgb = np.full((H, W, 3), 128, np.uint8)
    # no raycasts after the first (the true poses need none): the test is about integration
    slam = DenseSlam(SlamParams(depth_weighting=False, max_rotation_deg=90.0, raycast_every=100), K, W, H, poses[0])
    slam.odometry = odometry = _TruePose(slam)
    for k, (T, depth, stamp) in enumerate(zip(poses, depths, STAMPS)):
        odometry.truth = T
        r = slam.step(rgb, depth, 1000.0, stamp)
        assert r.state == "ok" and np.allclose(r.world_from_rgbd, T, atol=1e-9)
        if k == 2:  # three observations of wall A: weight 3, not above the threshold 3 (model_extract)
            assert slam.model.extract_pointcloud(3.0).is_empty() and not slam.model.extract_pointcloud(2.0).is_empty()
    # the stamping's share of the integration (which counts it): touch the last frame's blocks again
    t0 = time.perf_counter()
    slam.block_stamps.touch(slam.model.frustum_block_coords.cpu().numpy(), STAMPS[-1])
    assert (time.perf_counter() - t0) * 1e3 < 0.1 * r.costs_ms["integrate"]
    pts, _ = slam.extract_pointcloud()
    verts, _, _ = slam.extract_mesh()
    stamps, vert_stamps = slam.fusion_stamps(pts), slam.fusion_stamps(verts)
    slam.release()
    p = pts.astype(np.float64)
    on_a = np.abs(p[:, 2] - 2.0) < 0.02
    on_b = np.abs(p[:, 0] - 2.0) < 0.02
    assert on_a.sum() > 20000 and on_b.sum() > 20000
    # wall A left of anything the turn saw keeps the stamp of the last frame looking at it...
    left_a = on_a & (p[:, 0] < -0.5)
    assert left_a.sum() > 5000 and np.all(stamps[left_a] == STAMPS[3])
    # ...while all of wall B has the last frame's, and so has the mesh there
    assert np.all(stamps[on_b] == STAMPS[-1])
    assert np.all(vert_stamps[np.abs(verts[:, 0] - 2.0) < 0.02] == STAMPS[-1])
    # against the frustum + depth test: equal for most points; a block shared with points a later frame
    # saw (at the edges of its view) is newer, never older
    ref = expected_stamps(p, poses, depths)
    assert np.all(ref > 0)  # every extracted point was seen
    assert np.mean(stamps == ref) > 0.9 and np.all(stamps >= ref)
    assert set(np.unique(stamps)) <= set(STAMPS)
