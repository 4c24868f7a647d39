"""The RGB-D camera's trajectory: smooth interpolation of keyframe positions and look-at points.

Positions and look-at points are each interpolated with a C1 cubic Hermite spline whose tangents
are Catmull-Rom (non-uniform) inside and zero at the first and last keyframe, so the camera eases
in and out. The camera looks from the position to the look-at point with the world z axis up
(OpenCV camera: x right, y down, z forward).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from probeless.errors import SceneError
from probeless.scene.spec import Keyframe

WORLD_UP = np.array([0.0, 0.0, 1.0])


def _tangents(times: np.ndarray, values: np.ndarray) -> np.ndarray:
    m = np.zeros_like(values)
    for i in range(1, len(times) - 1):
        m[i] = (values[i + 1] - values[i - 1]) / (times[i + 1] - times[i - 1])
    return m


def hermite(times: np.ndarray, values: np.ndarray, t: float) -> np.ndarray:
    """Spline value at ``t`` (clamped to the keyframe range) through ``values`` (K, D) at ``times`` (K,)."""
    if len(times) == 1 or t <= times[0]:
        return values[0].copy()
    if t >= times[-1]:
        return values[-1].copy()
    i = int(np.searchsorted(times, t, side="right") - 1)
    h = times[i + 1] - times[i]
    s = (t - times[i]) / h
    m = _tangents(times, values)
    h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
    return h00 * values[i] + h10 * h * m[i] + h01 * values[i + 1] + h11 * h * m[i + 1]


def look_at(position: np.ndarray, target: np.ndarray) -> np.ndarray:
    """world_from_camera (4, 4) of an OpenCV camera at ``position`` looking at ``target``, world z up."""
    forward = target - position
    forward = forward / np.linalg.norm(forward)
    right = np.cross(forward, WORLD_UP)
    if np.linalg.norm(right) < 1e-9:
        raise SceneError(f"camera at {position.tolist()} looks straight up or down: its roll is undefined")
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    T = np.eye(4)
    T[:3, :3] = np.stack([right, down, forward], axis=1)
    T[:3, 3] = position
    return T


def camera_pose(keyframes: Sequence[Keyframe], t: float) -> np.ndarray:
    """world_from_camera (4, 4) of the RGB-D camera at scene time ``t`` [s]."""
    times = np.array([k.t for k in keyframes])
    position = hermite(times, np.array([k.position for k in keyframes]), t)
    target = hermite(times, np.array([k.look_at for k in keyframes]), t)
    return look_at(position, target)
