"""Small pure helpers of the dense SLAM: intrinsics of subsampled frames, depth cleaning, motion
between poses, Open3D error messages and the raycast bias correction."""

from __future__ import annotations

import re

import numpy as np
from scipy.spatial.transform import Rotation

from probeless.errors import ProbelessError


def scaled_K(K: np.ndarray, n: int) -> np.ndarray:
    """Camera matrix of the image subsampled as ``img[::n, ::n]`` (pixel k -> k / n, centres)."""
    Ks = np.array(K, dtype=np.float64)
    Ks[:2] /= n
    return Ks


def clean_depth(depth: np.ndarray) -> np.ndarray:
    """uint16 depth: uint16 as is; float (same units) rounded, non-finite or negative -> 0."""
    if depth.dtype == np.uint16:
        return depth
    if not np.issubdtype(depth.dtype, np.floating):
        raise ProbelessError(f"DenseSlam.step: depth must be uint16 or float, got {depth.dtype}")
    d = np.where(np.isfinite(depth) & (depth > 0), depth, 0.0)
    return np.clip(np.round(d), 0, 65535).astype(np.uint16)


def open3d_message(exc: Exception) -> str:
    """The message of an Open3D error without colour codes and source location."""
    text = re.sub(r"\x1b\[[0-9;]*m", "", str(exc)).strip()
    return re.split(r"\.(?:cpp|h|cu):\d+: ", text)[-1].strip()


def motion(T_prev: np.ndarray, T: np.ndarray) -> tuple[float, float]:
    """(translation [m], rotation [deg]) of the relative motion between two poses."""
    rel = np.linalg.inv(T_prev) @ T
    cos = np.clip((np.trace(rel[:3, :3]) - 1.0) / 2.0, -1.0, 1.0)
    return float(np.linalg.norm(rel[:3, 3])), float(np.degrees(np.arccos(cos)))


def raycast_pose(T: np.ndarray, voxel_size: float) -> np.ndarray:
    """Pose to raycast from so that the raycast matches the model as integrated, seen from ``T``.

    Open3D's raycast (VoxelBlockGrid ray casting, 0.18-0.20) reads the TSDF of the voxel
    *containing* each sample (its lower corner, no interpolation) when it searches the zero
    crossing, which places surfaces on average half a voxel further along +x, +y and +z (world)
    than they were integrated. Left alone, tracking follows that shift and every integration
    adds to it: a drift of ~v/2 (1, 1, 1) per re-integration (measured: 4-6 mm per frame at
    the start of 7-Scenes with 1 cm voxels). Raycasting from a camera shifted by the same half
    voxel cancels it.
    """
    S = np.array(T, dtype=np.float64)
    S[:3, 3] += 0.5 * voxel_size
    return S


def _hat(w: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def _left_jacobian(w: np.ndarray) -> np.ndarray:
    """V(w) of SE(3)'s exponential: t = V(w) v for the twist (w, v) (series near w = 0)."""
    th = float(np.linalg.norm(w))
    W = _hat(w)
    if th < 1e-6:
        return np.eye(3) + W / 2 + W @ W / 6
    return np.eye(3) + (1 - np.cos(th)) / th ** 2 * W + (th - np.sin(th)) / th ** 3 * W @ W


def predict_pose(T0: np.ndarray, t0: float, T1: np.ndarray, t1: float, t: float, max_ratio: float = 10.0) -> np.ndarray:
    """world_from_camera at time ``t`` at the constant velocity (a constant body-frame twist) of
    T0 (at t0) -> T1 (at t1): ``T1 @ (inv(T0) @ T1)^s``, ``s = (t - t1) / (t1 - t0)`` clamped to
    [0, max_ratio], the power taken on SE(3) (closed-form log and exp); T1 when the times give no
    velocity.
    """
    T1 = np.array(T1, dtype=np.float64)
    if not t1 > t0:
        return T1
    s = float(np.clip((t - t1) / (t1 - t0), 0.0, max_ratio))
    if s == 0.0:
        return T1
    d = np.linalg.inv(T0) @ T1
    w = Rotation.from_matrix(d[:3, :3]).as_rotvec()
    v = np.linalg.solve(_left_jacobian(w), d[:3, 3])
    step = np.eye(4)
    step[:3, :3] = Rotation.from_rotvec(s * w).as_matrix()
    step[:3, 3] = _left_jacobian(s * w) @ (s * v)
    return T1 @ step


def se3_exp(xi: np.ndarray) -> np.ndarray:
    """(4, 4) exp of the twist ``xi`` = (omega, v) (rotation vector [rad], then translation part)."""
    xi = np.asarray(xi, dtype=np.float64)
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(xi[:3]).as_matrix()
    T[:3, 3] = _left_jacobian(xi[:3]) @ xi[3:]
    return T
