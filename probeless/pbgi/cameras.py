"""Cameras looking at a virtual object: a short arc for the ``cloud_views`` node, one view for ``probeless pbgi
render``. Poses are world_from_camera (4, 4) with OpenCV axes (x right, y down, z forward)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from probeless.coarse.view import look_at
from probeless.errors import PbgiError


def _unit(v, what: str) -> np.ndarray:
    a = np.asarray(v, np.float64)
    n = np.linalg.norm(a) if a.shape == (3,) and np.isfinite(a).all() else 0.0
    if n < 1e-9:
        raise PbgiError(f"{what}: expected a non-zero 3-vector, got {v!r}")
    return a / n


def arc_poses(target, direction, distance: float, up, arc_deg: float, n: int) -> list[np.ndarray]:
    """``n`` cameras at ``distance`` [m] from ``target`` (3,) [m] looking at it, on an arc of ``arc_deg`` degrees
    about ``up`` centred on ``direction`` (from the target towards the middle camera); image up is ``up``."""
    d, u = _unit(direction, "direction"), _unit(up, "up")
    if abs(float(d @ u)) > 0.999:
        raise PbgiError("direction and up must not be parallel")
    t = np.asarray(target, np.float64)
    angles = np.radians(np.linspace(-arc_deg / 2, arc_deg / 2, n) if n > 1 else [0.0])
    return [look_at(t + distance * Rotation.from_rotvec(a * u).apply(d), t, up=u) for a in angles]


def facing_pose(target, radius: float, toward, distances: float = 4.0, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """A camera ``distances`` x ``radius`` [m] from ``target`` on the side of point ``toward`` (e.g. the cloud's
    centroid), looking at the target; along +x when ``toward`` is the target itself."""
    t = np.asarray(target, np.float64)
    d = np.asarray(toward, np.float64) - t
    d = d / np.linalg.norm(d) if np.linalg.norm(d) > 1e-6 else np.array([1.0, 0.0, 0.0])
    return look_at(t + distances * radius * d, t, up=_unit(up, "up"))


def fov_K(width: int, height: int, fov_deg: float = 50.0) -> np.ndarray:
    """(3, 3) pinhole intrinsics of a ``width`` x ``height`` image with a horizontal field of view ``fov_deg``."""
    f = (width / 2.0) / np.tan(np.radians(fov_deg) / 2.0)
    return np.array([[f, 0.0, (width - 1) / 2.0], [0.0, f, (height - 1) / 2.0], [0.0, 0.0, 1.0]])
