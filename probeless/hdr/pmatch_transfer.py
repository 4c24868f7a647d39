"""The PatchMatch transfer with its checks (paper 001, §4.1, made to fail loudly): exposure from geometry, pose-
verified samples, flat clipped interiors.

:func:`pmatch_transfer` runs, for the ``pmatch-*`` methods of :func:`probeless.hdr.expand.expand_cloud`:

1. PatchMatch of each view into ``I_LDR = clamp(alpha0 I_HDR)`` (``alpha0``: given, or Eq. 1's histogram match);
2. exposure from geometry (:mod:`.geometry`): reliable correspondences, the photo's pose by RANSAC PnP, the robust
   log ratio over co-visible unclipped points; when it differs from ``alpha0`` by more than :data:`REMATCH`, the
   views are matched again against the photo exposed with it (the SSD threshold is in ``I_LDR`` units, so a wrong
   exposure rejects every match: the "expanded 0" of issue 27);
3. samples per point: with a pose, the over-exposed points the photo sees take the photo's pixels that show them
   (``points_expanded_pose``), and PatchMatch samples of points the photo sees are not used; otherwise (points the
   photo does not see, or no pose) a PatchMatch sample is kept when its SSD is under ``ssd_threshold``; with a pose,
   a flat clipped interior pixel (no texture, all clipped: it matches any clipped patch of the photo with SSD 0, so
   a lamp's interior fetches a window's) takes its nearest rim match instead (:func:`rim_field`), or no sample
   (Poisson fills it). Without a pose the paper's field is kept as it is for those pixels too: measured on the
   coarse-model tests, the rim rule alone lowered the irradiance gain there.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from probeless.hdr import geometry as geo
from probeless.hdr.exposure import expose
from probeless.hdr.transfer import inverse_ssd_weights, overexposed, project_views

PATCH = 7
ITERATIONS = 5
MAX_SPREAD = 0.5  # log units: a geometric exposure whose ratios spread more is not used
REMATCH = 0.05  # re-match when the geometric exposure differs from the first one by more than 5 %


@dataclasses.dataclass
class PmatchOutcome:
    """``samples`` (N, 3) cloud units, ``counts`` (N,), ``alpha``, ``exposure`` (report fields), ``pose``
    (:class:`~.geometry.PhotoPose` or None), ``photo_sees`` (N,) bool or None, ``view_hdr`` per view, ``diag``:
    counts for the report and the warnings."""

    samples: np.ndarray
    counts: np.ndarray
    alpha: float
    exposure: dict
    pose: object
    photo_sees: np.ndarray | None
    view_hdr: list
    diag: dict


def match_views(views, photo_ldr, mode: str) -> list:
    """One :class:`~.patchmatch.Field` per view (``seed`` = view index)."""
    from probeless.hdr.patchmatch import patchmatch

    return [patchmatch(np.clip(v.color, 0.0, 1.0), photo_ldr, patch=PATCH, iterations=ITERATIONS, seed=i,
                       mode=mode) for i, v in enumerate(views)]


def geometric_exposure(pts, ldr, spacing, views, fields, photo, photo_ldr=None, photo_pose=None):
    """``(RatioExposure or None, PhotoPose or None, photo View or None, pairs)``: :mod:`.geometry` steps 1-3. An
    estimated pose whose co-visible ratios spread more than :data:`MAX_SPREAD` (log units) is rejected as wrong.
    Without a pose there is no exposure from geometry (the correspondences' own ratios follow the exposure they were
    matched at, so they cannot correct it)."""
    size = (photo.shape[1], photo.shape[0])
    pose, pairs = photo_pose, 0
    if pose is None:
        ids, xy = geo.correspondences(pts, views, fields, photo_ldr)
        pairs = int(len(ids))
        if pairs:
            pose = geo.estimate_pose(pts[ids], xy, size)
    if pose is None:
        return None, None, None, pairs
    pview = geo.photo_visibility(pts, ldr, spacing, pose, size)
    rex = geo.ratio_exposure(ldr, photo, photo_view=pview)
    if photo_pose is None and (rex is None or rex.spread > MAX_SPREAD):
        return None, None, None, pairs
    return rex, pose, pview, pairs


def rim_field(field, flat: np.ndarray, rim: np.ndarray, photo_ldr: np.ndarray):
    """``(xy (H, W, 2), ok (H, W))``: flat clipped interior pixels (``flat``) matched through their nearest rim pixel
    (``rim``: accepted, textured matches; ``scipy.ndimage.distance_transform_edt``): the rim's centre moved by the
    rim's rotation and scale of the pixel offset, as PatchMatch's propagation does. ``ok``: the predicted centre is
    inside the photo and clipped there too (luminance of ``photo_ldr`` > 0.9)."""
    from scipy.ndimage import distance_transform_edt

    xy = np.array(field.xy, np.float32)
    ok = np.zeros(flat.shape, bool)
    if not rim.any() or not flat.any():
        return xy, ok
    _, (iy, ix) = distance_transform_edt(~rim, return_indices=True)
    fy, fx = np.nonzero(flat)
    ry, rx = iy[fy, fx], ix[fy, fx]
    dx, dy = (fx - rx).astype(np.float32), (fy - ry).astype(np.float32)
    a, sc = field.angle[ry, rx], field.scale[ry, rx]
    px = field.xy[ry, rx, 0] + sc * (np.cos(a) * dx - np.sin(a) * dy)
    py = field.xy[ry, rx, 1] + sc * (np.sin(a) * dx + np.cos(a) * dy)
    ht, wt = photo_ldr.shape[:2]
    inside = (px >= 0) & (px <= wt - 1) & (py >= 0) & (py <= ht - 1)
    yl = photo_ldr @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    clipped = yl[np.clip(np.rint(py), 0, ht - 1).astype(int), np.clip(np.rint(px), 0, wt - 1).astype(int)] > 0.9
    xy[fy, fx, 0], xy[fy, fx, 1] = px, py
    ok[fy, fx] = inside & clipped
    return xy, ok


def choose_exposure(rex, alpha: float, method: str, fixed: bool) -> tuple[float, str]:
    """The geometric exposure when there is one whose ratios spread at most :data:`MAX_SPREAD`, else ``alpha``."""
    if not fixed and rex is not None and rex.spread <= MAX_SPREAD:
        return rex.alpha, rex.method
    return alpha, method


def pmatch_transfer(pts, ldr, spacing, views, photo, *, mode: str, alpha0: float, exposure_method: str,
                    ssd_threshold: float, photo_pose=None, fixed_alpha: bool = False) -> PmatchOutcome:
    """Steps 1-3 of the module doc. ``alpha0``: the starting exposure (``exposure_method``: ``histogram`` or
    ``given``); ``fixed_alpha``: keep it (``--exposure``), the geometry then serves the transfer only;
    ``photo_pose``: a known :class:`~.geometry.PhotoPose`, ``"estimate"`` (RANSAC PnP on the correspondences;
    opt-in: not validated, see docs/hdr/generalisation.md) or None (Eq. 1's exposure, the paper's field)."""
    from probeless.hdr.patchmatch import fetch

    n = len(pts)
    alpha, method, rematched, pairs = alpha0, exposure_method, False, 0
    rex = pose = pview = None
    estimate = isinstance(photo_pose, str) and photo_pose == "estimate"
    if estimate:
        photo_pose = None
    if photo_pose is not None:  # known pose: the exposure before any matching
        rex, pose, pview, _ = geometric_exposure(pts, ldr, spacing, views, [], photo, None, photo_pose)
        alpha, method = choose_exposure(rex, alpha0, exposure_method, fixed_alpha)
    photo_ldr = expose(photo, alpha)
    fields = match_views(views, photo_ldr, mode)
    if photo_pose is None and estimate:
        rex, pose, pview, pairs = geometric_exposure(pts, ldr, spacing, views, fields, photo, photo_ldr)
        alpha, method = choose_exposure(rex, alpha0, exposure_method, fixed_alpha)
        if abs(np.log(alpha / alpha0)) > np.log1p(REMATCH):
            photo_ldr = expose(photo, alpha)
            fields = match_views(views, photo_ldr, mode)
            rematched = True
    exposure = {"exposure_method": method, "alpha_histogram": alpha0 if exposure_method == "histogram" else None,
                "alpha_geometry": None if rex is None else rex.alpha,
                "exposure_spread": None if rex is None else rex.spread,
                "exposure_samples": 0 if rex is None else rex.samples,
                "exposure_confidence": "given" if method == "given" else (
                    "low" if rex is None or method == "histogram" else rex.confidence),
                "exposure_rematched": rematched, "correspondences": pairs,
                "photo_pose": None if pose is None else {
                    "source": pose.source, "fov_deg": pose.fov_deg, "inliers": pose.inliers, "pairs": pose.pairs,
                    "position": pose.world_from_camera[:3, 3].tolist()}}

    over = overexposed(ldr)
    sees = None
    if pview is not None:
        sees = np.zeros(n, bool)
        sees[pview.point_id[pview.point_id >= 0]] = True
    ids, vals, weights, view_hdr = [], [], [], []
    diag = {"pixels_over_ssd": 0, "pixels_flat_clipped": 0, "pixels_flat_from_rim": 0}
    ywts = np.array([0.2126, 0.7152, 0.0722], np.float32)
    for v, f in zip(views, fields):
        pid = v.point_id
        on = pid >= 0
        y = np.clip(v.color, 0.0, 1.0) @ ywts
        flat = on & (geo.patch_std(y, PATCH) < geo.MIN_TEXTURE) & (y > 0.9)
        good = on & (f.ssd <= ssd_threshold)
        rim = good & ~flat
        if sees is None:  # no pose, nothing to verify a rim's match with: the paper's field, flat interiors too
            flat = np.zeros_like(flat)
            rim = good
        xy, from_rim = rim_field(f, flat, rim, photo_ldr)
        h = fetch(dataclasses.replace(f, xy=xy), photo) * np.float32(alpha)
        w = inverse_ssd_weights(f.ssd)
        if from_rim.any():  # a rim-propagated pixel takes its rim pixel's weight, not its own (SSD 0) one
            w = np.where(from_rim, np.float32(1.0 / (ssd_threshold + 1e-6)), w)
        keep = rim | from_rim
        over_px = on & over[np.maximum(pid, 0)]
        diag["pixels_over_ssd"] += int((over_px & ~good & ~flat).sum())
        diag["pixels_flat_clipped"] += int((flat & ~from_rim).sum())
        diag["pixels_flat_from_rim"] += int(from_rim.sum())
        if sees is not None:
            keep &= ~sees[np.maximum(pid, 0)]
        ids.append(np.where(keep, pid, -1))
        vals.append(h)
        weights.append(np.where(keep, w, 1.0))
        view_hdr.append(np.where(keep[..., None], h, 0.0).astype(np.float32))
    if pview is not None:  # the photo's own pixels, for the points it sees
        ids.append(pview.point_id)
        vals.append(photo * np.float32(alpha))
        weights.append(np.ones(pview.point_id.shape, np.float32))
    samples, counts = project_views(ids, vals, n, weights)
    return PmatchOutcome(samples, counts, float(alpha), exposure, pose, sees, view_hdr, diag)
