"""The whole HDR expansion of an LDR coloured point cloud from one uncalibrated HDR photo (paper 001, §4).

:func:`expand_cloud` chains the stages of :mod:`probeless.hdr`, each as its module defines it:

1. ``exposure``: :func:`~.exposure.match_exposure` of the photo to the cloud (``alpha``, ``I_LDR``);
2. ``views`` (view methods only): camera positions, given or placed over the over-exposed clusters
   (:func:`~.views.place_views`), and 90-degree square renderings of the LDR cloud with point ids
   (:class:`~.splat.SplatRenderer`);
3. ``transfer``: an HDR value per view pixel, then per point (:func:`~.transfer.project_views`) and onto
   the over-exposed points only (:func:`~.transfer.apply_transfer`):

   * ``landis`` / ``banterle``: the inverse tone mapping operator on each view rendering (``alpha = 1``);
   * ``landis-pc`` / ``banterle-pc``: the operator on the points' colours directly, no views;
   * ``pmatch-lum`` / ``pmatch-rgb``: generalized PatchMatch (:func:`~.patchmatch.patchmatch`, on luminance
     or RGB) of each view's LDR rendering into ``I_LDR``; the photo's radiance ``I_HDR`` is read through
     the field (:func:`~.patchmatch.fetch`), pixels whose patch SSD (sum over the 7 x 7 patch and the
     matched channels, linear 0..1 units) is above ``ssd_threshold`` (the paper's ``t_h = 1``) are
     rejected, the others averaged per point with weights ``1 / SSD``, times ``alpha``;

4. ``poisson``: :func:`~.poisson.poisson_fill` of the over-exposed points left without a valid value.

The paper's deep-network expansions (§6.2) are left out: they need pretrained weights that cannot be
fetched here. Radiance is in "cloud units": the LDR colours' linear scale (1 = LDR white).
"""

from __future__ import annotations

import dataclasses
import time
from typing import Callable

import numpy as np

from probeless.color import REC709_Y
from probeless.errors import HdrError
from probeless.hdr.exposure import match_exposure
from probeless.hdr.methods import DEFAULT_VIEWS, METHODS
from probeless.hdr.poisson import poisson_fill
from probeless.hdr.splat import SplatRenderer, View, check_cloud, point_spacing
from probeless.hdr.transfer import (
    apply_transfer,
    expand_points,
    expand_with_operator,
    overexposed,
    project_views,
    reject_cluster_outliers,
)
from probeless.hdr.views import (
    camera_looking_at,
    linear_colors,
    place_views,
    saturated_clusters,
    views_from_positions,
)

FOV_DEG = 90.0

Progress = Callable[[str, int, int], None]
"""``progress(stage, done, total)``: called as each stage starts (done 0) and advances."""


@dataclasses.dataclass(frozen=True, eq=False)
class ExpansionResult:
    """``radiance`` (N, 3) float32 linear >= 0 [cloud units]; ``valid`` (N,) bool: LDR-kept or given a value
    by the transfer or the Poisson fill; ``report``: JSON-ready dict (see :func:`expand_cloud`); ``views``:
    the LDR renderings (:class:`~.splat.View`) and ``view_hdr`` their per-pixel HDR estimates (H, W, 3) in
    cloud units (0 where rejected or background), empty for the ``-pc`` methods; ``expanded`` (N,) bool: the
    over-exposed points given a value by the transfer (``points_expanded``)."""

    radiance: np.ndarray
    valid: np.ndarray
    report: dict
    views: list = dataclasses.field(default_factory=list)
    view_hdr: list = dataclasses.field(default_factory=list)
    expanded: np.ndarray | None = None


def view_cameras(points, ldr, views, normals, size: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """[(position, look_at)]: ``views`` an int (placed over the clusters), (V, 3) positions (looking at the
    cloud's centroid) or (V, 2, 3) rows of (position, look_at)."""
    if views is None:
        views = DEFAULT_VIEWS
    if isinstance(views, (int, np.integer)) and not isinstance(views, bool):
        return place_views(points, ldr, int(views), normals=normals)
    v = np.asarray(views, np.float64)
    if v.ndim == 2 and v.shape[1] == 3:
        return views_from_positions(v, np.tile(points.astype(np.float64).mean(axis=0), (len(v), 1)))
    if v.ndim == 3 and v.shape[1:] == (2, 3):
        return views_from_positions(v[:, 0], v[:, 1])
    raise HdrError(f"views: expected a count, (V, 3) positions or (V, 2, 3) (position, look_at) rows, got {v.shape}")


def render_views(points, colors, spacing, cameras, size: int, tick=None) -> list[View]:
    """Square ``size`` px, 90-degree LDR renderings of the cloud from each (position, look_at)."""
    renderer = SplatRenderer()
    try:
        out = []
        for pos, tgt in cameras:
            K, pose = camera_looking_at(pos, tgt, FOV_DEG, (size, size))
            out.append(renderer.render(points, colors, spacing, K, pose, (size, size)))
            if tick:
                tick()
        return out
    finally:
        renderer.release()


def operator_peak(photo_hdr, alpha: float | None, max_lum: float | None) -> tuple[float, str]:
    """``(peak, source)``: the operators' ``max_lum`` in cloud units: ``max_lum`` when given (``flag``), else the
    photo's brightest luminance times ``alpha`` (``photo``)."""
    if max_lum is not None:
        if not (np.isfinite(max_lum) and max_lum > 1.0):
            raise HdrError(f"max_lum: expected a peak above LDR white (> 1), got {max_lum!r}")
        return float(max_lum), "flag"
    if photo_hdr is None:
        raise HdrError("the inverse tone mapping operators need a peak: give the HDR photo or max_lum")
    peak = float(np.max(np.asarray(photo_hdr, np.float32) @ REC709_Y)) * float(alpha)
    return max(peak, 1.0), "photo"


def start_exposure(photo_hdr, ldr, exposure: float | None):
    """``(alpha0, method, ExposureMatch or None)``: the given exposure, or Eq. 1's histogram match."""
    if exposure is not None:
        if not (np.isfinite(exposure) and exposure > 0):
            raise HdrError(f"exposure: expected a positive number, got {exposure!r}")
        return float(exposure), "given", None
    match = match_exposure(photo_hdr, ldr)
    return match.alpha, "histogram", match


def visible_in_views(rendered, n: int) -> np.ndarray:
    """(N,) bool: points that some view shows."""
    seen = np.zeros(n, bool)
    for v in rendered:
        seen[v.point_id[v.point_id >= 0]] = True
    return seen


def expansion_warnings(report: dict, diag: dict) -> list[str]:
    """The warnings of the report: fewer than half of the over-exposed points that some view (or the -pc methods:
    the cloud) holds were expanded, with the count and the reasons found."""
    out = []
    vis, done = report["points_overexposed_visible"], report["points_expanded"]
    if report["points_overexposed"] and done < 0.5 * max(vis, 1):
        reasons = []
        if not report["views"] and report["view_size"] is not None:
            reasons.append("no view could be placed (no free viewpoint with a line of sight to the clipped "
                           "clusters): give --view-positions")
        elif vis < report["points_overexposed"]:
            reasons.append(f"{report['points_overexposed'] - vis} over-exposed points are in no view")
        if diag.get("pixels_over_ssd"):
            reasons.append(f"{diag['pixels_over_ssd']} clipped view pixels matched with an SSD above the threshold "
                           f"(alpha {report.get('alpha')}, from {report.get('exposure_method')})")
        if diag.get("pixels_flat_clipped"):
            reasons.append(f"{diag['pixels_flat_clipped']} view pixels are flat clipped interiors (no texture to "
                           f"match; filled from their rim)")
        if report.get("photo_pose") is None and report["method"].startswith("pmatch"):
            reasons.append("the photo's pose is unknown (give --photo-pose), so the points it sees are not known")
        elif report.get("points_overexposed_in_photo") == 0:
            reasons.append("the photo sees none of the over-exposed points")
        out.append(f"{done} of {vis} over-exposed points that a view sees were expanded (< half): "
                   + ("; ".join(reasons) or "no reason found"))
    conf = report.get("exposure_confidence")
    if conf == "low" and report.get("exposure_method") == "histogram":
        out.append("the exposure comes from Eq. 1's histogram match only (no co-visible unclipped surfaces "
                   "found): alpha may be far off; give --exposure if it is known")
    return out


def expand_cloud(points, ldr_colors, photo_hdr, *, method: str, views=None, transfer: str = "rgb", normals=None,
                 size: int = 1024, ssd_threshold: float = 1.0, robust: bool = True, exposure: float | None = None,
                 max_lum: float | None = None, photo_pose=None,
                 progress: Progress | None = None) -> ExpansionResult:
    """HDR radiance for every point of the cloud (the stages of the module docstring).

    ``points`` (N, 3) [m]; ``ldr_colors`` (N, 3) linear 0..1 floats or uint8 sRGB codes; ``photo_hdr``
    (H, W, 3) linear radiance, any units (may be None for the operator methods when ``max_lum`` is given);
    ``views``: None (3), a count or explicit positions (:func:`view_cameras`); ``transfer``: ``rgb`` or
    ``lum`` (:func:`~.transfer.apply_transfer`, also the Poisson mode); ``size``: view width = height [px];
    ``robust`` (PatchMatch only; not in the paper): values disagreeing with the rest of their clipped cluster
    (:func:`~.transfer.reject_cluster_outliers`) are dropped before the Poisson fill (``points_rejected``);
    ``exposure``: the known alpha (cloud = alpha x photo), skipping its estimation; ``max_lum``: the operators'
    peak in cloud units (default: the photo's peak times alpha); ``photo_pose``: a known
    :class:`~.geometry.PhotoPose` of the photo, or ``"estimate"`` (RANSAC PnP on the PatchMatch correspondences,
    opt-in), or None (pmatch only).

    ``report``: ``method``, ``transfer``, ``alpha`` (None for methods that do not use it), ``exposure_method``
    (``geometry`` variants ``pose`` / ``correspondences``, ``histogram`` or ``given``) with its confidence,
    ``views``, ``points``, ``points_overexposed``, ``points_overexposed_visible`` (in some view or, with a pose, the
    photo; all for -pc),
    ``points_expanded`` (over-exposed points given a value by the transfer and kept), ``points_overexposed_in_photo``
    / ``points_expanded_in_photo`` (pmatch with a pose), ``points_rejected``, ``points_filled``,
    ``points_left_ldr``, ``unanchored_components``, ``clipped_negative``, ``radiance_max``, ``max_lum``
    (operators), ``warnings`` (list of strings), ``timings_ms`` per stage.
    """
    if method not in METHODS:
        raise HdrError(f"unknown method {method!r}; choices: {', '.join(METHODS)}")
    if transfer not in ("rgb", "lum"):
        raise HdrError(f"transfer: expected 'rgb' or 'lum', got {transfer!r}")
    if not (np.isfinite(ssd_threshold) and ssd_threshold > 0):
        raise HdrError(f"ssd_threshold: expected a positive number, got {ssd_threshold!r}")
    if not isinstance(size, (int, np.integer)) or not 16 <= size <= 8192:
        raise HdrError(f"size: expected an integer in 16..8192, got {size!r}")
    pts, _, _ = check_cloud(points, ldr_colors, None, "expand_cloud")
    ldr = linear_colors(ldr_colors)
    if ldr.min() < 0 or ldr.max() > 1.0 + 1e-6:
        raise HdrError(f"ldr_colors: linear LDR colours must be in 0..1, got {ldr.min():g}..{ldr.max():g}")
    ldr = np.clip(ldr, 0.0, 1.0)
    nrm = None if normals is None else np.asarray(normals, np.float32)
    report_fn = progress or (lambda stage, done, total: None)
    timings: dict[str, float] = {}
    pmatch = method.startswith("pmatch")
    per_point = method.endswith("-pc")
    photo = None if photo_hdr is None else np.asarray(photo_hdr, np.float32)

    t = time.perf_counter()
    report_fn("exposure", 0, 1)
    alpha, exp_method, match = None, None, None
    peak, peak_source = None, None
    if pmatch:
        if photo is None:
            raise HdrError(f"method {method}: needs the HDR photo")
        alpha, exp_method, match = start_exposure(photo, ldr, exposure)
    elif max_lum is None:
        if photo is None:
            raise HdrError(f"method {method}: needs the HDR photo (for its peak) or max_lum")
        alpha, exp_method, match = start_exposure(photo, ldr, exposure)
    if not pmatch:
        peak, peak_source = operator_peak(photo, alpha, max_lum)
    report_fn("exposure", 1, 1)
    timings["exposure"] = (time.perf_counter() - t) * 1e3

    cameras, rendered, view_hdr = [], [], []
    rejected, diag, extra = 0, {}, {}
    over = overexposed(ldr)
    if per_point:
        t = time.perf_counter()
        report_fn("transfer", 0, 1)
        hdr, valid = apply_transfer(ldr, expand_points(ldr, method[:-3], max_lum=peak, points=pts),
                                    np.ones(len(ldr), np.int64), 1.0, transfer)
        visible = np.ones(len(pts), bool)
        report_fn("transfer", 1, 1)
        timings["transfer"] = (time.perf_counter() - t) * 1e3
    else:
        t = time.perf_counter()
        report_fn("views", 0, 1)
        cameras = view_cameras(pts, ldr, views, nrm, int(size))
        spacing = point_spacing(pts)
        report_fn("views", 0, max(len(cameras), 1))
        ticks = iter(range(1, len(cameras) + 1))
        rendered = render_views(pts, ldr, spacing, cameras, int(size),
                                lambda: report_fn("views", next(ticks), len(cameras)))
        report_fn("views", max(len(cameras), 1), max(len(cameras), 1))  # done, even with no view
        visible = visible_in_views(rendered, len(pts))
        timings["views"] = (time.perf_counter() - t) * 1e3

        t = time.perf_counter()
        report_fn("transfer", 0, 1)
        if pmatch:
            from probeless.hdr.pmatch_transfer import pmatch_transfer

            out = pmatch_transfer(pts, ldr, spacing, rendered, photo, mode=method[7:], alpha0=alpha,
                                  exposure_method=exp_method, ssd_threshold=ssd_threshold, photo_pose=photo_pose,
                                  fixed_alpha=exposure is not None)
            samples, counts, alpha, view_hdr, diag = out.samples, out.counts, out.alpha, out.view_hdr, out.diag
            extra = dict(out.exposure)
            exp_method = extra.pop("exposure_method")
            sees = out.photo_sees
        else:
            ids = []
            for v in rendered:
                h = expand_with_operator(np.clip(v.color, 0.0, 1.0), method, max_lum=peak)
                ids.append(v.point_id)
                view_hdr.append(np.where(v.mask[..., None], h, 0.0).astype(np.float32))
            samples, counts = project_views(ids, view_hdr, len(pts), None)
            sees = None
        hdr, valid = apply_transfer(ldr, samples, counts, 1.0, transfer)
        if pmatch and robust:
            valid, rejected = reject_cluster_outliers(hdr, valid, saturated_clusters(pts, ldr, normals=nrm),
                                                      trusted=None if sees is None else sees & over)
        if sees is not None:
            visible |= sees  # the photo is one more view when its pose is known
            extra["points_overexposed_in_photo"] = int((over & sees).sum())
            extra["points_expanded_in_photo"] = int((over & sees & valid).sum())
        report_fn("transfer", 1, 1)
        timings["transfer"] = (time.perf_counter() - t) * 1e3

    t = time.perf_counter()
    report_fn("poisson", 0, 1)
    radiance, prep = poisson_fill(pts, hdr, ldr, valid, mode=transfer)
    report_fn("poisson", 1, 1)
    timings["poisson"] = (time.perf_counter() - t) * 1e3

    expanded = int((over & valid).sum())
    uses_alpha = pmatch or peak_source == "photo"
    report = {
        "method": method, "transfer": transfer, "alpha": alpha if uses_alpha else None,
        "exposure_method": exp_method if uses_alpha else None,
        "exposure_distance": None if (match is None or not uses_alpha) else match.distance,
        **({"max_lum": peak, "max_lum_source": peak_source} if not pmatch else {}),
        "views": [{"position": p.tolist(), "look_at": q.tolist()} for p, q in cameras],
        "view_size": None if per_point else int(size),
        "points": int(len(pts)), "points_overexposed": int(over.sum()),
        "points_overexposed_visible": int((over & visible).sum()), "points_expanded": expanded,
        **extra,
        "points_rejected": rejected,
        "points_filled": prep.filled, "points_left_ldr": prep.left_ldr,
        "unanchored_components": prep.unanchored_components, "clipped_negative": prep.clipped_negative,
        "radiance_max": float(radiance.max()), "timings_ms": timings,
    }
    if pmatch and "exposure_confidence" not in report:
        report["exposure_confidence"] = "given" if exp_method == "given" else "low"
    report["warnings"] = expansion_warnings(report, diag)
    final_valid = valid.copy()
    final_valid[~valid] = True
    if prep.left_ldr:
        # the points Poisson could not reach keep their LDR colour: mark them not valid
        left = (~valid) & np.all(radiance == ldr, axis=1)
        final_valid[left] = False
    return ExpansionResult(radiance, final_valid, report, rendered, view_hdr, over & valid)
