"""Noise-weighted point-to-plane refinement against poses known exactly (depth rendered from planes)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from probeless.tracking.slam_math import se3_exp
from probeless.tracking.weighted_icp import KINECT_SIGMA, depth_weights, refine_point_to_plane

K = np.array([[300.0, 0, 159.5], [0, 300.0, 119.5], [0, 0, 1]])
ROOM = (np.array([-1.5, -1.2, -1.0]), np.array([1.5, 1.0, 3.8]))      # walls seen from inside [m]
OBJECT = (np.array([0.25, 0.15, 1.0]), np.array([0.9, 0.7, 1.7]))     # a box near the camera, 3 faces in view [m]


def _slabs(c: np.ndarray, d: np.ndarray, lo: np.ndarray, hi: np.ndarray):
    """(entry, exit) ray parameters of the axis-aligned box [lo, hi] (slab method)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t0, t1 = (lo - c) / d, (hi - c) / d
    return np.minimum(t0, t1).max(axis=-1), np.maximum(t0, t1).min(axis=-1)


def render(cam_from_world: np.ndarray) -> np.ndarray:
    """(240, 320) depth [m] of the room (walls from inside) with the box in it, seen from the camera."""
    v, u = np.mgrid[0:240, 0:320].astype(np.float64)
    rays = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], -1)  # z = 1: t = depth
    world_from_cam = np.linalg.inv(cam_from_world)
    d, c = rays @ world_from_cam[:3, :3].T, world_from_cam[:3, 3]
    _, wall = _slabs(c, d, *ROOM)
    enter, leave = _slabs(c, d, *OBJECT)
    return np.where((enter < leave) & (enter > 0.05), enter, wall)


def pose_error(A: np.ndarray, B: np.ndarray) -> tuple[float, float]:
    E = np.linalg.inv(A) @ B
    return float(np.linalg.norm(E[:3, 3])), float(np.degrees(Rotation.from_matrix(E[:3, :3]).magnitude()))


def test_the_true_pose_is_a_fixed_point_of_the_room_scene():
    truth = se3_exp(np.array([0.004, 0.006, -0.003, 0.02, 0.01, -0.015]))
    T, used = refine_point_to_plane(render(np.linalg.inv(truth)), render(np.eye(4)), K, truth, iterations=10, step=2)
    dt, dr = pose_error(truth, T)
    assert used > 10000 and dt < 5e-4 and dr < 0.01


def test_recovers_a_known_motion_from_a_wrong_start():
    truth = se3_exp(np.array([0.01, -0.02, 0.015, 0.03, -0.02, 0.04]))  # target_from_source
    tgt = render(np.eye(4))
    src = render(np.linalg.inv(truth))  # the source camera sits at `truth` in the target's frame
    start = truth @ se3_exp(np.array([0.004, 0.003, -0.005, 0.01, 0.008, -0.01]))
    T, used = refine_point_to_plane(src, tgt, K, start, sigma=KINECT_SIGMA, iterations=20, step=2)
    dt, dr = pose_error(truth, T)
    assert used > 5000 and dt < 2e-4 and dr < 0.01
    assert pose_error(truth, start)[0] > 0.01  # it did move


def test_weighting_by_the_noise_model_beats_uniform_weights_on_heteroscedastic_depth():
    rng = np.random.default_rng(3)
    truth = se3_exp(np.array([0.004, 0.006, -0.003, 0.02, 0.01, -0.015]))
    tgt = render(np.eye(4))
    errors = {"noise model": [], "uniform": []}
    clean = render(np.linalg.inv(truth))
    a, b, z0 = KINECT_SIGMA
    for _ in range(6):  # Kinect-like noise: 2 mm on the box, 10-20 mm on the walls
        src = clean + rng.normal(0, 1, clean.shape) * (a + b * (clean - z0) ** 2)
        for name, model in (("noise model", KINECT_SIGMA), ("uniform", (1.0, 0.0, 0.0))):
            T, _ = refine_point_to_plane(src, tgt, K, truth, sigma=model, iterations=10, step=2)
            errors[name].append(pose_error(truth, T)[0])
    assert np.mean(errors["noise model"]) < 0.5 * np.mean(errors["uniform"])


def test_weights_follow_the_inverse_variance_and_too_little_data_leaves_the_pose():
    z = np.array([1.0, 2.0, 3.0])
    w = depth_weights(z, KINECT_SIGMA)
    s = KINECT_SIGMA[0] + KINECT_SIGMA[1] * (z - KINECT_SIGMA[2]) ** 2
    assert w.mean() == pytest.approx(1.0) and w[0] / w[2] == pytest.approx((s[2] / s[0]) ** 2)
    start = se3_exp(np.array([0.0, 0.0, 0.1, 0.0, 0.0, 0.0]))
    T, used = refine_point_to_plane(np.zeros((240, 320)), render(np.eye(4)), K, start)
    assert used == 0 and np.array_equal(T, start)
