"""Exposure from geometry: the photo's pose from PatchMatch correspondences, and a robust ratio on co-visible points.

Eq. 1's histogram match (:mod:`.exposure`) compares the whole cloud with the whole photo; when they frame different
parts of the room (a photo of a bright window, a cloud that is mostly dark floor) it is far off. Here the
exposure comes from the same surfaces seen by both:

1. :func:`correspondences`: view pixels whose PatchMatch match is reliable: the source patch is textured (its
   luminance spread is at least ``min_texture``), not clipped, and its SSD per value is small. Each gives a 3-D
   point (the id buffer) and a photo pixel (the field's centre).
2. :func:`estimate_pose`: the photo's pinhole pose by RANSAC PnP (``cv2.solvePnPRansac``, EPnP) on those pairs, for
   a range of horizontal fields of view (square pixels, principal point at the centre), the one with the most
   inliers, refined by ``cv2.solvePnP`` (Levenberg-Marquardt) on its inliers. Fails (None) below ``min_inliers``
   inliers or an inlier fraction below ``min_fraction``.
3. :func:`ratio_exposure`: with the pose, the cloud is splatted from the photo's viewpoint (id buffer) and each
   photo pixel showing an unclipped point (linear LDR luminance in ``(low, high)``) gives
   ``log Y_ldr(point) - log Y_photo(pixel)``; ``alpha = exp(median)``, ``spread = 1.4826 MAD`` (log units).
   Without a pose the correspondences' own pairs are used (``correspondences`` method).

All ratios are of CIE Y (Rec. 709 primaries), linear.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from probeless.color import REC709_Y
from probeless.errors import HdrError

MIN_TEXTURE = 0.01     # luminance standard deviation over the source patch [linear LDR units]
MAX_SSD_VALUE = 4e-4   # SSD per patch value (RMS 0.02) for a reliable correspondence
UNCLIPPED = (0.02, 0.85)
FOV_CANDIDATES = tuple(range(30, 145, 5))  # horizontal field of view searched [deg]
MIN_INLIERS = 30
MIN_FRACTION = 0.1
MIN_SAMPLES = 50


@dataclasses.dataclass(frozen=True)
class PhotoPose:
    """``K`` (3, 3) and ``world_from_camera`` (4, 4) of the photo; ``inliers`` / ``pairs`` of the RANSAC;
    ``fov_deg`` its horizontal field of view; ``source``: ``estimated`` or ``given``."""

    K: np.ndarray
    world_from_camera: np.ndarray
    inliers: int
    pairs: int
    fov_deg: float
    source: str = "estimated"


@dataclasses.dataclass(frozen=True)
class RatioExposure:
    """``alpha`` (cloud = alpha x photo), ``spread`` (1.4826 MAD of the log ratios), ``samples`` used, ``method``
    (``pose`` or ``correspondences``)."""

    alpha: float
    spread: float
    samples: int
    method: str

    @property
    def confidence(self) -> str:
        """``high`` (>= 500 samples, spread <= 0.1), ``medium`` (>= 100, <= 0.3) or ``low``."""
        if self.samples >= 500 and self.spread <= 0.1:
            return "high"
        if self.samples >= 100 and self.spread <= 0.3:
            return "medium"
        return "low"


def _lum(img) -> np.ndarray:
    return np.asarray(img, np.float32) @ REC709_Y.astype(np.float32)


def patch_std(lum: np.ndarray, patch: int) -> np.ndarray:
    """(H, W) standard deviation of ``lum`` over the ``patch`` x ``patch`` box around each pixel (OpenCV box)."""
    import cv2

    y = np.asarray(lum, np.float32)
    m = cv2.blur(y, (patch, patch), borderType=cv2.BORDER_REPLICATE)
    m2 = cv2.blur(y * y, (patch, patch), borderType=cv2.BORDER_REPLICATE)
    return np.sqrt(np.maximum(m2 - m * m, 0.0))


def correspondences(points, views, fields, photo_ldr, *, max_pairs: int = 4000, seed: int = 0):
    """Reliable (3-D point index, photo pixel) pairs of every view: ``(ids (M,), xy (M, 2) float64)`` (module doc,
    step 1); ``fields`` are :class:`~.patchmatch.Field` s of the views (None entries are skipped)."""
    ids, xys = [], []
    ylim = _lum(photo_ldr)
    for v, f in zip(views, fields):
        if f is None:
            continue
        y = _lum(np.clip(v.color, 0.0, 1.0))
        per_value = f.ssd / (f.patch ** 2 * (3 if f.mode == "rgb" else 1))
        xy = np.asarray(f.xy, np.float64)
        tx = np.clip(np.rint(xy[..., 0]).astype(int), 0, ylim.shape[1] - 1)
        ty = np.clip(np.rint(xy[..., 1]).astype(int), 0, ylim.shape[0] - 1)
        ok = ((v.point_id >= 0) & (patch_std(y, f.patch) >= MIN_TEXTURE) & (per_value <= MAX_SSD_VALUE)
              & (y > UNCLIPPED[0]) & (y < UNCLIPPED[1]) & (ylim[ty, tx] < 0.95))
        ids.append(v.point_id[ok].astype(np.int64))
        xys.append(xy[ok])
    if not ids:
        return np.zeros(0, np.int64), np.zeros((0, 2))
    ids, xys = np.concatenate(ids), np.concatenate(xys)
    if len(ids) > max_pairs:
        keep = np.random.default_rng(seed).choice(len(ids), max_pairs, replace=False)
        ids, xys = ids[keep], xys[keep]
    return ids, xys


def intrinsics(width: int, height: int, fov_deg: float) -> np.ndarray:
    """(3, 3) pinhole K: horizontal ``fov_deg``, square pixels, principal point at the centre (pixel centres at
    integers)."""
    f = (width / 2.0) / np.tan(np.radians(fov_deg) / 2.0)
    return np.array([[f, 0.0, (width - 1) / 2.0], [0.0, f, (height - 1) / 2.0], [0.0, 0.0, 1.0]])


def estimate_pose(obj: np.ndarray, img: np.ndarray, size, *, reproj_px: float | None = None,
                  fovs=FOV_CANDIDATES, min_inliers: int = MIN_INLIERS, min_fraction: float = MIN_FRACTION,
                  seed: int = 0) -> PhotoPose | None:
    """The photo's pose from 3-D points ``obj`` (M, 3) [m] seen at pixels ``img`` (M, 2) of a ``size`` (W, H)
    photo (module doc, step 2), or None."""
    import cv2

    w, h = int(size[0]), int(size[1])
    obj = np.ascontiguousarray(obj, np.float64)
    img = np.ascontiguousarray(img, np.float64)
    if len(obj) < max(6, min_inliers):
        return None
    px = max(2.0, 0.008 * max(w, h)) if reproj_px is None else float(reproj_px)
    cv2.setRNGSeed(seed)
    best = None
    for fov in fovs:
        K = intrinsics(w, h, fov)
        ok, rvec, tvec, inl = cv2.solvePnPRansac(obj, img, K, None, iterationsCount=300, reprojectionError=px,
                                                 confidence=0.999, flags=cv2.SOLVEPNP_EPNP)
        n = 0 if (not ok or inl is None) else len(inl)
        if best is None or n > best[0]:
            best = (n, fov, rvec, tvec, inl)
    n, fov, rvec, tvec, inl = best
    if n < min_inliers or n < min_fraction * len(obj):
        return None
    K = intrinsics(w, h, fov)
    idx = inl.ravel()
    ok, rvec, tvec = cv2.solvePnP(obj[idx], img[idx], K, None, rvec, tvec, useExtrinsicGuess=True,
                                  flags=cv2.SOLVEPNP_ITERATIVE)
    R, _ = cv2.Rodrigues(rvec)
    pose = np.eye(4)
    pose[:3, :3] = R.T
    pose[:3, 3] = (-R.T @ tvec).ravel()
    if not np.isfinite(pose).all():
        return None
    return PhotoPose(K, pose, int(n), int(len(obj)), float(fov))


def log_ratio_exposure(ldr_y: np.ndarray, photo_y: np.ndarray, method: str,
                       unclipped=UNCLIPPED) -> RatioExposure | None:
    """Median of ``log ldr_y - log photo_y`` over pairs with ``ldr_y`` in ``unclipped`` and ``photo_y > 0``;
    None below :data:`MIN_SAMPLES` pairs."""
    a = np.asarray(ldr_y, np.float64).ravel()
    b = np.asarray(photo_y, np.float64).ravel()
    ok = (a > unclipped[0]) & (a < unclipped[1]) & (b > 0) & np.isfinite(b)
    if ok.sum() < MIN_SAMPLES:
        return None
    r = np.log(a[ok]) - np.log(b[ok])
    med = float(np.median(r))
    return RatioExposure(float(np.exp(med)), float(1.4826 * np.median(np.abs(r - med))), int(ok.sum()), method)


def photo_visibility(points, ldr, spacing, pose: PhotoPose, size):
    """The cloud splatted from the photo's viewpoint: its :class:`~.splat.View` (ids per photo pixel)."""
    from probeless.hdr.splat import SplatRenderer

    renderer = SplatRenderer()
    try:
        return renderer.render(points, ldr, spacing, pose.K, pose.world_from_camera, (int(size[0]), int(size[1])))
    finally:
        renderer.release()


def ratio_exposure(ldr, photo_hdr, *, photo_view=None, ids=None, xy=None) -> RatioExposure | None:
    """Exposure from co-visible unclipped surfaces (module doc, step 3): through ``photo_view`` (the cloud splatted
    at the photo's pose) when given, else through the correspondence pairs ``ids`` / ``xy``."""
    ldr_y = _lum(ldr)
    photo_y = _lum(photo_hdr)
    if photo_view is not None:
        if photo_view.point_id.shape != photo_y.shape:
            raise HdrError(f"ratio_exposure: the photo view is {photo_view.point_id.shape}, the photo "
                           f"{photo_y.shape}")
        pid = photo_view.point_id
        m = pid >= 0
        return log_ratio_exposure(ldr_y[pid[m]], photo_y[m], "pose")
    if ids is None or len(ids) == 0:
        return None
    x = np.clip(np.rint(xy[:, 0]).astype(int), 0, photo_y.shape[1] - 1)
    y = np.clip(np.rint(xy[:, 1]).astype(int), 0, photo_y.shape[0] - 1)
    return log_ratio_exposure(ldr_y[ids], photo_y[y, x], "correspondences")
