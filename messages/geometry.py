"""Geometry: stamped poses and the room floorplan.

Conventions (the maths is in :mod:`probeless.geom.rotation`): a transform named
``target_from_source`` is a 4x4 float64 rigid matrix mapping points expressed in frame *source* to
frame *target*: ``p_target = T @ p_source`` (homogeneous column vectors). Quaternions are float64
``[x, y, z, w]`` (scipy convention) with ``w >= 0``. The world frame is z-up, metres, floor at z = 0.
A floorplan obeys the rules of :mod:`probeless.geom.floorplan`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from probeless.errors import GeometryError, SchemaError
from probeless.geom.floorplan import check_ceiling_height, check_floorplan
from probeless.geom.polygon import signed_area
from probeless.geom.rotation import quat_from_matrix, transform_from
from probeless.messages.base import Message, array, message
from probeless.messages.header import Header


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
    # floor polygon (x, y), counter-clockwise seen from above, not closed [m, world]
    vertices: np.ndarray = array("float64", (None, 2))
    ceiling_height: float   # ceiling z above the floor [m, world]

    def validate(self) -> None:
        try:
            check_floorplan(self.vertices, "Floorplan.vertices")
            check_ceiling_height(self.ceiling_height, "Floorplan.ceiling_height")
        except GeometryError as exc:
            raise SchemaError(str(exc)) from None

    @property
    def area(self) -> float:
        """Signed floor area by the shoelace formula, > 0 for counter-clockwise [m^2]."""
        return signed_area(self.vertices)
