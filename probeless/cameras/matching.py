"""Point matches between an RGB-D frame and a fisheye image, in the region both cameras see.

The fisheye image is resampled (a LUT of ``fisheye.project`` of pinhole rays, then cv2.remap)
into a *perspective view*: a virtual pinhole at the fisheye's centre with the RGB-D camera's
intrinsics and, through the guessed ``fisheye_from_rgbd`` rotation, its orientation. The view
then looks much like the RGB image (same scale and orientation, shifted only by the small
baseline), which is what SIFT needs. SIFT features of both images (with a low contrast threshold,
0.01: indoor walls have little texture and the view is blurred by the fisheye's lower resolution)
are matched with Lowe's ratio test; RGB keypoints are lifted to 3-D with the depth (keypoints on
depth edges are dropped), and a RANSAC PnP in the view removes gross mismatches. View keypoints
are mapped back to raw fisheye pixels exactly (the view ray, rotated into the fisheye frame,
projected by the model).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from probeless.cameras.base import CameraModel
from probeless.cameras.extrinsics import default_init
from probeless.errors import CalibrationError


@dataclass(frozen=True)
class Matches:
    """Correspondences between an RGB-D frame and a fisheye image."""

    points_rgbd: np.ndarray     # (N, 3) points in the RGB-D camera frame [m]
    pixels_fisheye: np.ndarray  # (N, 2) raw fisheye pixels (u, v)
    pixels_rgb: np.ndarray      # (N, 2) RGB pixels (u, v)
    pixels_view: np.ndarray     # (N, 2) pixels in the perspective view
    candidates: int             # matches passing the ratio test and the depth check, before RANSAC

    def __len__(self) -> int:
        return len(self.points_rgbd)


def _no_matches(candidates: int) -> Matches:
    return Matches(np.zeros((0, 3)), np.zeros((0, 2)), np.zeros((0, 2)), np.zeros((0, 2)), candidates)


def view_rays(K: np.ndarray, width: int, height: int) -> np.ndarray:
    """(H * W, 3) rays K^-1 (u, v, 1) of every pixel centre of a pinhole view, row-major."""
    v, u = np.mgrid[0:height, 0:width].astype(np.float64)
    pix = np.stack([u.ravel(), v.ravel(), np.ones(u.size)], axis=1)
    return pix @ np.linalg.inv(K).T


def perspective_view(fisheye_img: np.ndarray, fisheye: CameraModel, K: np.ndarray, size: tuple[int, int],
                     fisheye_from_view: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(view image, valid mask uint8) of a pinhole (K, size = (W, H)) at the fisheye centre, rotated
    by ``fisheye_from_view`` (3x3); pixels whose ray misses the fisheye image are 0 in both."""
    w, h = size
    px, valid = fisheye.project(view_rays(K, w, h) @ np.asarray(fisheye_from_view).T)
    valid &= fisheye.in_image(np.where(valid[:, None], px, -1e9))
    px[~valid] = -1e6
    maps = px.reshape(h, w, 2).astype(np.float32)
    view = cv2.remap(fisheye_img, maps[..., 0], maps[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)
    mask = valid.reshape(h, w).astype(np.uint8) * 255
    return view, mask


def to_gray(img: np.ndarray) -> np.ndarray:
    """uint8 grey image of a uint8 RGB(A) or grey one."""
    img = np.asarray(img)
    if img.ndim == 3 and img.shape[2] == 1:
        img = img[..., 0]
    if img.ndim == 3:
        img = cv2.cvtColor(img[..., :3], cv2.COLOR_RGB2GRAY)
    if img.dtype != np.uint8:
        raise ValueError(f"images must be uint8, got {img.dtype}")
    return img


def lift(pixels: np.ndarray, depth_m: np.ndarray, K: np.ndarray, max_jump: float) -> tuple[np.ndarray, np.ndarray]:
    """(N, 3) points at the depth of the nearest pixel and (N,) ok: depth valid and, within 3x3,
    varying by at most ``max_jump`` x depth (not on an occlusion edge)."""
    h, w = depth_m.shape
    c = np.clip(np.rint(pixels[:, 0]).astype(int), 1, w - 2)
    r = np.clip(np.rint(pixels[:, 1]).astype(int), 1, h - 2)
    d = np.nan_to_num(depth_m.astype(np.float64), nan=0.0)
    patch = np.stack([d[r + dr, c + dc] for dr in (-1, 0, 1) for dc in (-1, 0, 1)], axis=1)
    z = d[r, c]
    ok = (z > 0) & (patch.min(axis=1) > 0) & (patch.max(axis=1) - patch.min(axis=1) <= max_jump * z)
    rays = np.column_stack([pixels, np.ones(len(pixels))]) @ np.linalg.inv(K).T
    return rays * z[:, None], ok


def match_rgbd_fisheye(rgb: np.ndarray, depth_m: np.ndarray, rgbd_K: np.ndarray, fisheye_img: np.ndarray,
                       fisheye: CameraModel, init: np.ndarray | None = None, *, ratio: float = 0.75,
                       ransac_px: float = 6.0, max_depth_jump: float = 0.05, n_features: int = 4000,
                       contrast: float = 0.01) -> Matches:
    """Matches between one RGB-D frame (uint8 RGB or grey, depth in metres registered to it, pinhole
    K without distortion) and one fisheye image taken from the same rig pose.

    ``init`` is the guessed fisheye_from_rgbd (default :func:`~probeless.cameras.extrinsics.default_init`);
    only its rotation is used, to point the perspective view.
    """
    gray = to_gray(rgb)
    if np.shape(depth_m) != gray.shape:
        raise CalibrationError(f"RGB image is {gray.shape[1]}x{gray.shape[0]} but the depth image "
                               f"{np.shape(depth_m)[::-1]}: they must be registered")
    K = np.asarray(rgbd_K, dtype=np.float64)
    R = (default_init() if init is None else np.asarray(init, dtype=np.float64))[:3, :3]
    size = (gray.shape[1], gray.shape[0])
    view, view_mask = perspective_view(to_gray(fisheye_img), fisheye, K, size, R)
    sift = cv2.SIFT_create(nfeatures=n_features, contrastThreshold=contrast)
    erode = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (15, 15))
    rgb_mask = ((depth_m > 0) & (cv2.dilate(view_mask, erode) > 0)).astype(np.uint8) * 255
    kp_r, des_r = sift.detectAndCompute(gray, rgb_mask)
    kp_v, des_v = sift.detectAndCompute(view, cv2.erode(view_mask, erode))
    if des_r is None or des_v is None or len(kp_r) < 2 or len(kp_v) < 2:
        return _no_matches(0)
    pairs = [m for m, n in (p for p in cv2.BFMatcher(cv2.NORM_L2).knnMatch(des_r, des_v, k=2) if len(p) == 2)
             if m.distance < ratio * n.distance]
    px_r = np.array([kp_r[m.queryIdx].pt for m in pairs], dtype=np.float64).reshape(-1, 2)
    px_v = np.array([kp_v[m.trainIdx].pt for m in pairs], dtype=np.float64).reshape(-1, 2)
    pts, ok = lift(px_r, depth_m, K, max_depth_jump)
    pts, px_r, px_v = pts[ok], px_r[ok], px_v[ok]
    candidates = len(pts)
    if candidates < 6:
        return _no_matches(candidates)
    found, _, _, idx = cv2.solvePnPRansac(pts, px_v, K, None, reprojectionError=ransac_px, iterationsCount=500,
                                          confidence=0.999, flags=cv2.SOLVEPNP_EPNP)
    if not found or idx is None:
        return _no_matches(candidates)
    keep = np.sort(idx.ravel())
    rays_f = np.column_stack([px_v[keep], np.ones(len(keep))]) @ np.linalg.inv(K).T @ R.T
    px_f, valid = fisheye.project(rays_f)
    keep, px_f = keep[valid], px_f[valid]
    return Matches(pts[keep], px_f, px_r[keep], px_v[keep], candidates)
