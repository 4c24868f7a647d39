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

from probeless.errors import HdrError
from probeless.hdr.exposure import match_exposure
from probeless.hdr.poisson import poisson_fill
from probeless.hdr.splat import SplatRenderer, View, check_cloud, point_spacing
from probeless.hdr.transfer import (
    apply_transfer,
    expand_points,
    expand_with_operator,
    inverse_ssd_weights,
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

METHODS = ("landis", "banterle", "landis-pc", "banterle-pc", "pmatch-lum", "pmatch-rgb")
DEFAULT_VIEWS = 3
FOV_DEG = 90.0
PATCH = 7
ITERATIONS = 5

Progress = Callable[[str, int, int], None]
"""``progress(stage, done, total)``: called as each stage starts (done 0) and advances."""


@dataclasses.dataclass(frozen=True, eq=False)
class ExpansionResult:
    """``radiance`` (N, 3) float32 linear >= 0 [cloud units]; ``valid`` (N,) bool: LDR-kept or given a value
    by the transfer or the Poisson fill; ``report``: JSON-ready dict (see :func:`expand_cloud`); ``views``:
    the LDR renderings (:class:`~.splat.View`) and ``view_hdr`` their per-pixel HDR estimates (H, W, 3) in
    cloud units (0 where rejected or background), empty for the ``-pc`` methods."""

    radiance: np.ndarray
    valid: np.ndarray
    report: dict
    views: list = dataclasses.field(default_factory=list)
    view_hdr: list = dataclasses.field(default_factory=list)


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


def pmatch_view(view: View, match, photo: np.ndarray, mode: str, ssd_threshold: float, seed: int = 0):
    """(HDR (H, W, 3) in the photo's units, ids (H, W) with rejected pixels set to -1, weights (H, W))."""
    from probeless.hdr.patchmatch import fetch, patchmatch

    field = patchmatch(np.clip(view.color, 0.0, 1.0), match.ldr_image, patch=PATCH, iterations=ITERATIONS,
                       seed=seed, mode=mode)
    hdr = fetch(field, photo)
    ids = np.where(field.ssd <= ssd_threshold, view.point_id, -1)
    return hdr, ids, inverse_ssd_weights(field.ssd)


def expand_cloud(points, ldr_colors, photo_hdr, *, method: str, views=None, transfer: str = "rgb", normals=None,
                 size: int = 1024, ssd_threshold: float = 1.0, robust: bool = True,
                 progress: Progress | None = None) -> ExpansionResult:
    """HDR radiance for every point of the cloud (the stages of the module docstring).

    ``points`` (N, 3) [m]; ``ldr_colors`` (N, 3) linear 0..1 floats or uint8 sRGB codes; ``photo_hdr``
    (H, W, 3) linear radiance, any units (may be None for the operator methods, then ``alpha`` is None);
    ``views``: None (3), a count or explicit positions (:func:`view_cameras`); ``transfer``: ``rgb`` or
    ``lum`` (:func:`~.transfer.apply_transfer`, also the Poisson mode); ``size``: view width = height [px];
    ``robust`` (PatchMatch only; not in the paper): values disagreeing with the rest of their clipped cluster
    (:func:`~.transfer.reject_cluster_outliers`) are dropped before the Poisson fill (``points_rejected``).

    ``report``: ``method``, ``transfer``, ``alpha``, ``views`` (list of {position, look_at}),
    ``points``, ``points_overexposed``, ``points_expanded`` (over-exposed points given a value by the
    transfer and kept), ``points_rejected`` (by ``robust``), ``points_filled`` (by Poisson),
    ``points_left_ldr``, ``unanchored_components``, ``clipped_negative``, ``radiance_max``, ``timings_ms``
    per stage.
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

    t = time.perf_counter()
    report_fn("exposure", 0, 1)
    match = None
    if photo_hdr is not None:
        match = match_exposure(photo_hdr, ldr)
    elif pmatch:
        raise HdrError(f"method {method}: needs the HDR photo")
    report_fn("exposure", 1, 1)
    timings["exposure"] = (time.perf_counter() - t) * 1e3

    cameras, rendered, view_hdr = [], [], []
    rejected = 0
    over = overexposed(ldr)
    if per_point:
        t = time.perf_counter()
        report_fn("transfer", 0, 1)
        hdr, valid = apply_transfer(ldr, expand_points(ldr, method[:-3]), np.ones(len(ldr), np.int64), 1.0,
                                    transfer)
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
        timings["views"] = (time.perf_counter() - t) * 1e3

        t = time.perf_counter()
        report_fn("transfer", 0, max(len(rendered), 1))
        ids, weights = [], []
        for i, v in enumerate(rendered):
            if pmatch:
                h, pid, w = pmatch_view(v, match, np.asarray(photo_hdr, np.float32), method[7:], ssd_threshold, i)
                ids.append(pid)
                weights.append(np.where(pid >= 0, w, 1.0))
                view_hdr.append(np.where((pid >= 0)[..., None], h * np.float32(match.alpha), 0.0))
            else:
                h = expand_with_operator(np.clip(v.color, 0.0, 1.0), method)
                ids.append(v.point_id)
                view_hdr.append(np.where(v.mask[..., None], h, 0.0))
            view_hdr[-1] = view_hdr[-1].astype(np.float32)
            report_fn("transfer", i + 1, len(rendered))
        # per-view values are in cloud units already (pmatch samples scaled by alpha above)
        samples, counts = project_views(ids, view_hdr, len(pts), weights if pmatch else None)
        hdr, valid = apply_transfer(ldr, samples, counts, 1.0, transfer)
        if pmatch and robust:
            valid, rejected = reject_cluster_outliers(hdr, valid, saturated_clusters(pts, ldr, normals=nrm))
        report_fn("transfer", max(len(rendered), 1), max(len(rendered), 1))
        timings["transfer"] = (time.perf_counter() - t) * 1e3

    t = time.perf_counter()
    report_fn("poisson", 0, 1)
    radiance, prep = poisson_fill(pts, hdr, ldr, valid, mode=transfer)
    report_fn("poisson", 1, 1)
    timings["poisson"] = (time.perf_counter() - t) * 1e3

    expanded = int((over & valid).sum())
    report = {
        "method": method, "transfer": transfer, "alpha": None if match is None else match.alpha,
        "exposure_distance": None if match is None else match.distance,
        "views": [{"position": p.tolist(), "look_at": q.tolist()} for p, q in cameras],
        "view_size": None if per_point else int(size),
        "points": int(len(pts)), "points_overexposed": int(over.sum()), "points_expanded": expanded,
        "points_rejected": rejected,
        "points_filled": prep.filled, "points_left_ldr": prep.left_ldr,
        "unanchored_components": prep.unanchored_components, "clipped_negative": prep.clipped_negative,
        "radiance_max": float(radiance.max()), "timings_ms": timings,
    }
    final_valid = valid.copy()
    final_valid[~valid] = True
    if prep.left_ldr:
        # the points Poisson could not reach keep their LDR colour: mark them not valid
        left = (~valid) & np.all(radiance == ldr, axis=1)
        final_valid[left] = False
    return ExpansionResult(radiance, final_valid, report, rendered, view_hdr)
