"""Rotations and rigid transforms: quaternions, slerp, roll-pitch-yaw and 4x4 matrices, pure numpy.

Conventions: a transform named ``target_from_source`` is a 4x4 float64 rigid matrix mapping points
expressed in frame *source* to frame *target*: ``p_target = T @ p_source`` (homogeneous column
vectors). Quaternions are float64 ``[x, y, z, w]`` (scipy convention), Hamilton product, and
:func:`quat_from_matrix` returns the canonical sign ``w >= 0``. All helpers but :func:`slerp` and
:func:`rotation_from_rpy` accept leading batch axes.
"""

from __future__ import annotations

import numpy as np

from probeless.errors import GeometryError


def quat_normalize(q: np.ndarray) -> np.ndarray:
    """Unit quaternion(s) ``q / |q|``; raises GeometryError for a zero or non-finite quaternion."""
    q = np.asarray(q, dtype=np.float64)
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    if not np.all(np.isfinite(n)) or np.any(n == 0):
        raise GeometryError("quat_normalize: zero-norm or non-finite quaternion")
    return q / n


def quat_conjugate(q: np.ndarray) -> np.ndarray:
    """Conjugate ``[-x, -y, -z, w]`` (the inverse, for unit quaternions)."""
    q = np.asarray(q, dtype=np.float64)
    return np.concatenate([-q[..., :3], q[..., 3:]], axis=-1)


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a * b``: the rotation that applies ``b`` first, then ``a``."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    ax, ay, az, aw = np.moveaxis(a, -1, 0)
    bx, by, bz, bw = np.moveaxis(b, -1, 0)
    return np.stack([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz], axis=-1)


def matrix_from_quat(q: np.ndarray) -> np.ndarray:
    """3x3 rotation matrix of a quaternion ``[x, y, z, w]`` (normalised first)."""
    x, y, z, w = np.moveaxis(quat_normalize(q), -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], axis=-1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], axis=-1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=-2)


def quat_from_matrix(R: np.ndarray) -> np.ndarray:
    """Quaternion ``[x, y, z, w]`` with ``w >= 0`` of a rotation matrix, by Shepperd's method.

    Picks the largest of (trace, R00, R11, R22) as pivot so no division by a small number occurs,
    which keeps 180-degree rotations exact.
    """
    R = np.asarray(R, dtype=np.float64)
    r00, r01, r02 = R[..., 0, 0], R[..., 0, 1], R[..., 0, 2]
    r10, r11, r12 = R[..., 1, 0], R[..., 1, 1], R[..., 1, 2]
    r20, r21, r22 = R[..., 2, 0], R[..., 2, 1], R[..., 2, 2]
    trace = r00 + r11 + r22
    # Each candidate is 4 * q * (pivot component): same direction as q, best conditioned at its pivot.
    candidates = np.stack([
        np.stack([r21 - r12, r02 - r20, r10 - r01, 1 + trace], axis=-1),
        np.stack([1 + r00 - r11 - r22, r01 + r10, r02 + r20, r21 - r12], axis=-1),
        np.stack([r01 + r10, 1 - r00 + r11 - r22, r12 + r21, r02 - r20], axis=-1),
        np.stack([r02 + r20, r12 + r21, 1 - r00 - r11 + r22, r10 - r01], axis=-1),
    ], axis=-2)
    pivot = np.argmax(np.stack([trace, r00, r11, r22], axis=-1), axis=-1)
    q = np.take_along_axis(candidates, pivot[..., None, None], axis=-2)[..., 0, :]
    q = quat_normalize(q)
    return np.where(q[..., 3:] < 0, -q, q)


def slerp(q0: np.ndarray, q1: np.ndarray, s: float) -> np.ndarray:
    """Unit quaternion a fraction ``s`` along the shortest arc from ``q0`` to ``q1`` (any real s).

    q1 and -q1 are the same rotation: the relative rotation ``q0^-1 q1`` is taken with w >= 0, so
    the arc is the shorter one (angle <= 180 degrees) whatever the signs. s outside [0, 1]
    continues the arc at the same angular velocity (extrapolation). Identical rotations give q0
    exactly (sin(s a)/sin(a) is replaced by its limit). At exactly 180 degrees (w = 0) both arcs
    are equally short and the one towards q1 *as given* is taken; any noise on a pair that far
    apart picks the direction, so such a pair carries no usable angular velocity.
    """
    q0, q1 = quat_normalize(q0), quat_normalize(q1)
    r = quat_multiply(quat_conjugate(q0), q1)
    if r[3] < 0:
        r = -r
    n = float(np.linalg.norm(r[:3]))
    half = np.arctan2(n, r[3])  # half the relative angle, in [0, pi/2]
    k = np.sin(s * half) / n if n > 1e-12 else s
    step = np.array([*(k * r[:3]), np.cos(s * half)])
    return quat_normalize(quat_multiply(q0, step))


def rotation_from_rpy(rpy_deg: np.ndarray) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll), i.e. scipy ``Rotation.from_euler('xyz', rpy_deg, degrees=True)``."""
    r, p, y = np.radians(rpy_deg)
    rx = np.array([[1, 0, 0], [0, np.cos(r), -np.sin(r)], [0, np.sin(r), np.cos(r)]])
    ry = np.array([[np.cos(p), 0, np.sin(p)], [0, 1, 0], [-np.sin(p), 0, np.cos(p)]])
    rz = np.array([[np.cos(y), -np.sin(y), 0], [np.sin(y), np.cos(y), 0], [0, 0, 1]])
    return rz @ ry @ rx


def transform_from_rpy(translation, rpy_deg) -> np.ndarray:
    """4x4 rigid transform in the scene-file convention: p' = R p + t, R = :func:`rotation_from_rpy` (rpy_deg);
    used for ``fisheye_from_rgbd``. GeometryError unless 3 + 3 numbers."""
    t, rpy = np.asarray(translation, dtype=np.float64), np.asarray(rpy_deg, dtype=np.float64)
    if t.shape != (3,) or rpy.shape != (3,):
        raise GeometryError(f"transform_from_rpy: need 3 + 3 numbers, got translation {t.tolist()}, "
                            f"rpy_deg {rpy.tolist()}")
    return transform_from(rotation_from_rpy(rpy), t)


def transform_from(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """4x4 float64 rigid transform ``[[R, t], [0, 0, 0, 1]]``."""
    R, t = np.asarray(R, dtype=np.float64), np.asarray(t, dtype=np.float64)
    T = np.zeros(np.broadcast_shapes(R.shape[:-2], t.shape[:-1]) + (4, 4))
    T[..., :3, :3], T[..., :3, 3], T[..., 3, 3] = R, t, 1.0
    return T


def invert_transform(T: np.ndarray) -> np.ndarray:
    """Rigid inverse: ``source_from_target`` of a ``target_from_source`` (no general matrix inverse)."""
    T = np.asarray(T, dtype=np.float64)
    Rt = np.swapaxes(T[..., :3, :3], -1, -2)
    return transform_from(Rt, -np.einsum("...ij,...j->...i", Rt, T[..., :3, 3]))
