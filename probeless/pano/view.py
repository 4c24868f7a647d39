"""Perspective views of a 360° frame: pinhole intrinsics, head path, stereo eyes, the background view.

Cameras follow OpenCV (x right, y down, z forward), as :func:`probeless.geom.projection.clip_from_camera`
and the object renderer do; a pose is ``world_from_camera`` (4x4, world z up, the equirect's frame:
see :mod:`probeless.pano.equirect`). Pixel centres sit at integer coordinates.
"""

from __future__ import annotations

import functools
import math

import cv2
import numpy as np

from probeless.errors import ProbelessError
from probeless.pano.equirect import check_equirect, direction_to_pixel

HMD_EYE_SIZE = (1182, 1464)  # per-eye render size (width, height) of the paper's Oculus DK2 tests [px]


def intrinsics(fov_deg: float, width: int, height: int) -> np.ndarray:
    """3x3 pinhole K with horizontal field of view ``fov_deg``, square pixels, centred principal point."""
    if not 0.0 < fov_deg < 180.0 or width < 1 or height < 1:
        raise ProbelessError(f"intrinsics: need 0 < fov_deg < 180 and a positive size, got {fov_deg}, "
                             f"{width}x{height}")
    f = 0.5 * width / math.tan(math.radians(fov_deg) / 2.0)
    return np.array([[f, 0.0, (width - 1) / 2.0], [0.0, f, (height - 1) / 2.0], [0.0, 0.0, 1.0]])


def look_rotation(yaw_deg: float, pitch_deg: float) -> np.ndarray:
    """3x3 world_from_camera rotation looking along azimuth ``yaw_deg`` (from +x towards +y) and
    elevation ``pitch_deg`` (up positive), no roll: camera x stays horizontal, y points down-ish."""
    y, p = math.radians(yaw_deg), math.radians(pitch_deg)
    forward = np.array([math.cos(p) * math.cos(y), math.cos(p) * math.sin(y), math.sin(p)])
    right = np.array([math.sin(y), -math.cos(y), 0.0])
    down = np.cross(forward, right)
    return np.stack([right, down, forward], axis=1)


def head_pose(t_s: float, *, yaw0_deg: float = 0.0, yaw_deg_per_s: float = 10.0, pitch_deg: float = -5.0,
              pitch_amp_deg: float = 3.0, pitch_period_s: float = 4.0, position=(0.0, 0.0, 0.0)) -> np.ndarray:
    """4x4 world_from_head at time ``t_s`` of the scripted path: a steady yaw sweep
    (``yaw0 + rate t``) with a slight nod, pitch ``pitch_deg + amp sin(2 pi t / period)``."""
    pitch = pitch_deg + pitch_amp_deg * math.sin(2.0 * math.pi * t_s / pitch_period_s)
    pose = np.eye(4)
    pose[:3, :3] = look_rotation(yaw0_deg + yaw_deg_per_s * t_s, pitch)
    pose[:3, 3] = position
    return pose


def stereo_eye_poses(world_from_head: np.ndarray, ipd_m: float) -> tuple[np.ndarray, np.ndarray]:
    """(left, right) world_from_eye: the head pose moved by -/+ ``ipd_m / 2`` along the head's x axis."""
    eyes = []
    for side in (-0.5, 0.5):
        shift = np.eye(4)
        shift[0, 3] = side * ipd_m
        eyes.append(np.asarray(world_from_head, np.float64) @ shift)
    return eyes[0], eyes[1]


def side_by_side(left: np.ndarray, right: np.ndarray) -> np.ndarray:
    """The two eye images next to each other (left eye on the left), the HMD's frame layout."""
    if left.shape != right.shape:
        raise ProbelessError(f"side_by_side: eye images differ in shape, {left.shape} vs {right.shape}")
    return np.concatenate([left, right], axis=1)


def view_rays(K: np.ndarray, rotation: np.ndarray, width: int, height: int) -> np.ndarray:
    """(height, width, 3) world directions of the pixel centres of pinhole ``K`` turned by ``rotation``."""
    v, u = np.mgrid[0:height, 0:width].astype(np.float64)
    cam = np.stack([u, v, np.ones_like(u)], axis=-1) @ np.linalg.inv(K).T
    return cam @ np.asarray(rotation, np.float64).T


@functools.lru_cache(maxsize=8)
def _view_map(key: bytes, width: int, height: int, src_w: int, src_h: int) -> tuple[np.ndarray, np.ndarray]:
    m = np.frombuffer(key, np.float64)
    u, v = direction_to_pixel(view_rays(m[:9].reshape(3, 3), m[9:].reshape(3, 3), width, height), src_w, src_h)
    # remap samples integer-centred source pixels; v clamped to the edge rows (the texture's CLAMP in v)
    return (u - 0.5).astype(np.float32), np.clip(v - 0.5, 0.0, src_h - 1.0).astype(np.float32)


def view_equirect(frame: np.ndarray, world_from_camera: np.ndarray, fov_deg: float, width: int, height: int,
                  K: np.ndarray | None = None) -> np.ndarray:
    """(height, width, C) pinhole view of the equirect ``frame`` (uint8 or float32) for a camera orientation.

    Bilinear, wrapping around in longitude and clamped at the poles; translation is ignored (the
    panorama is at infinity). ``K`` overrides ``fov_deg``. The remap table is cached per view.
    """
    img = check_equirect(frame, "view_equirect")
    K = intrinsics(fov_deg, width, height) if K is None else np.asarray(K, np.float64)
    rot = np.asarray(world_from_camera, np.float64)[:3, :3]
    key = np.concatenate([K.reshape(-1), rot.reshape(-1)]).tobytes()
    map_x, map_y = _view_map(key, int(width), int(height), img.shape[1], img.shape[0])
    out = cv2.remap(np.ascontiguousarray(img), map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP)
    return out.reshape(height, width, img.shape[2])
