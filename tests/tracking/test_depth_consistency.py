"""Depth consistency of a trajectory: analytic plane cases and real ICL frames with official ground truth."""

from __future__ import annotations

import numpy as np
import pytest
from locations import SHARED_DATA
from scipy.spatial.transform import Rotation

from probeless.tracking.depth_consistency import depth_consistency, pair_residuals

K = np.array([[200.0, 0, 79.5], [0, 200.0, 59.5], [0, 0, 1]])
ICL = SHARED_DATA / "rgbd" / "icl_livingroom1_micro"


def plane_depth(T_world_cam: np.ndarray, z_plane: float = 2.0, scale: float = 1000.0) -> np.ndarray:
    """uint16 depth image (160 x 120, K) of the world plane z = z_plane seen by a camera at T (looking +z)."""
    v, u = np.mgrid[0:120, 0:160].astype(np.float64)
    rays = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], axis=-1)
    R, c = T_world_cam[:3, :3], T_world_cam[:3, 3]
    d = rays @ R.T                                   # ray directions in the world
    t = (z_plane - c[2]) / d[..., 2]                 # ray parameter = camera depth (rays have z = 1)
    return np.round(t * scale).astype(np.uint16)


def pose(t=(0, 0, 0), rotvec=(0, 0, 0)) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    T[:3, 3] = t
    return T


def test_true_poses_explain_the_depth_and_an_offset_along_the_normal_shows_as_itself():
    poses = [pose((0.05 * k, -0.02 * k, 0.0), (0.01 * k, -0.02 * k, 0.0)) for k in range(4)]
    depths = [plane_depth(T) for T in poses]
    exact = depth_consistency(depths, poses, K, 1000.0, 1)
    assert exact.pairs == 3 and exact.median_m < 0.001  # only the 1 mm quantisation is left
    # moving every second pose 2 cm towards the plane predicts depths 2 cm off (a plane facing the camera)
    shifted = [T if k % 2 == 0 else T @ pose((0, 0, 0.02)) for k, T in enumerate(poses)]
    off = depth_consistency(depths, shifted, K, 1000.0, 1)
    assert off.median_m == pytest.approx(0.02, abs=0.002)


def test_residuals_are_signed_and_unknown_poses_are_skipped():
    T0, T1 = pose(), pose((0.0, 0.0, 0.1))
    d0, d1 = plane_depth(T0), plane_depth(T1)     # the second camera is 10 cm nearer the plane
    r = pair_residuals(d0, d1, K, 1000.0, np.linalg.inv(T1) @ T0)
    assert len(r) > 1000 and np.abs(np.median(r)) < 0.001
    r_wrong = pair_residuals(d0, d1, K, 1000.0, np.eye(4))  # claimed not to move: predicts 10 cm too far
    assert np.median(r_wrong) == pytest.approx(0.1, abs=0.002)
    c = depth_consistency([d0, d1, d0], [T0, None, T0], K, 1000.0, 1)
    assert c.pairs == 0 and c.median_m is None
    with pytest.raises(ValueError, match="gap"):
        depth_consistency([d0, d1], [T0, T1], K, 1000.0, 0)


def test_official_ground_truth_fits_real_frames_better_than_a_perturbed_copy():
    from probeless.tracking.sources import rgbd_samples

    samples = [s for s in rgbd_samples(ICL, max_frames=5)[0]]  # frames 0-4: official ground truth
    assert len(samples) == 5
    depths, gt = [s.depth for s in samples], [s.gt_world_from_rgbd for s in samples]
    tilted = [T @ pose(rotvec=(0.0, np.radians(0.5) * k, 0.0)) for k, T in enumerate(gt)]
    s0 = samples[0]
    good = depth_consistency(depths, gt, s0.K, s0.depth_scale, 1)
    bad = depth_consistency(depths, tilted, s0.K, s0.depth_scale, 1)
    assert good.median_m < 0.003 and bad.median_m > 2 * good.median_m
