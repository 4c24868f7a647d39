"""Geometry: rigid transforms, stamped poses and the room floorplan, plus pure-numpy quaternion helpers.

Conventions: a transform named ``target_from_source`` is a 4x4 float64 rigid matrix mapping points
expressed in frame *source* to frame *target*: ``p_target = T @ p_source`` (homogeneous column
vectors). Quaternions are float64 ``[x, y, z, w]`` (scipy convention), Hamilton product, and
``quat_from_matrix`` returns the canonical sign ``w >= 0``. All helpers accept leading batch axes.
The world frame is z-up, metres, floor at z = 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from probeless.errors import ProbelessError, SchemaError
from probeless.messages.base import Message, array, message
from probeless.messages.header import Header


def quat_normalize(q: np.ndarray) -> np.ndarray:
    """Unit quaternion(s) ``q / |q|``; raises ProbelessError for a zero or non-finite quaternion."""
    q = np.asarray(q, dtype=np.float64)
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    if not np.all(np.isfinite(n)) or np.any(n == 0):
        raise ProbelessError("quat_normalize: zero-norm or non-finite quaternion")
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


def check_rigid(T: np.ndarray, where: str) -> None:
    """Raise SchemaError unless T is a finite 4x4 rigid transform (orthonormal, det +1, last row 0001)."""
    if not np.all(np.isfinite(T)):
        raise SchemaError(f"{where}: invalid pose, contains NaN or inf")
    if np.max(np.abs(T[3] - (0.0, 0.0, 0.0, 1.0))) > 1e-9:
        raise SchemaError(f"{where}: invalid pose, last row {T[3].tolist()} is not [0, 0, 0, 1]")
    R = T[:3, :3]
    if np.max(np.abs(R.T @ R - np.eye(3))) > 1e-6 or np.linalg.det(R) < 0:
        raise SchemaError(f"{where}: invalid pose, rotation is not orthonormal with det +1")


@message("geometry/PoseStamped", version=1)
@dataclass(frozen=True)
class PoseStamped(Message):
    """Pose of frame ``child_frame_id`` in frame ``header.frame_id`` at ``header.stamp_ns``."""

    header: Header          # frame_id = target frame, e.g. "world"; stamp = time the pose holds
    child_frame_id: str     # source frame, e.g. "rgbd"
    target_from_source: np.ndarray = array("float64", (4, 4))  # rigid transform, p_target = T @ p_source [m]

    def validate(self) -> None:
        check_rigid(self.target_from_source, "PoseStamped.target_from_source")

    @classmethod
    def from_rt(cls, header: Header, child_frame_id: str, R: np.ndarray, t: np.ndarray) -> PoseStamped:
        """Build from a 3x3 rotation and a translation [m], both target_from_source."""
        return cls(header, child_frame_id, transform_from(R, t))

    @property
    def rotation(self) -> np.ndarray:
        """3x3 rotation, target_from_source."""
        return self.target_from_source[:3, :3]

    @property
    def translation(self) -> np.ndarray:
        """Origin of the source frame in the target frame (3,) [m]."""
        return self.target_from_source[:3, 3]

    @property
    def quaternion(self) -> np.ndarray:
        """Rotation as ``[x, y, z, w]``, w >= 0."""
        return quat_from_matrix(self.rotation)


@message("geometry/Floorplan", version=1)
@dataclass(frozen=True)
class Floorplan(Message):
    """The room as an extruded polygon: floor at z = 0, ceiling at ``ceiling_height``."""

    header: Header          # frame_id = "world" (z-up)
    vertices: np.ndarray = array("float64", (None, 2))  # floor polygon (x, y), counter-clockwise seen from above, not closed [m, world]
    ceiling_height: float   # ceiling z above the floor [m, world]

    def validate(self) -> None:
        v = self.vertices
        if len(v) < 3:
            raise SchemaError(f"Floorplan.vertices: need at least 3 vertices, got {len(v)}")
        if not np.all(np.isfinite(v)):
            raise SchemaError("Floorplan.vertices: contains NaN or inf")
        if not (np.isfinite(self.ceiling_height) and self.ceiling_height > 0):
            raise SchemaError(f"Floorplan.ceiling_height: must be finite and > 0, got {self.ceiling_height}")
        if self.area <= 0:
            raise SchemaError(f"Floorplan.vertices: polygon is clockwise or degenerate (signed area {self.area:.6g} m^2),"
                              " vertices must be counter-clockwise")

    @property
    def area(self) -> float:
        """Signed floor area by the shoelace formula, > 0 for counter-clockwise [m^2]."""
        x, y = self.vertices[:, 0], self.vertices[:, 1]
        return float(0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
