"""Transfer of expanded HDR values from views of the cloud back onto its points (paper 001, §4.1).

A view is a rendering of the LDR cloud (linear 0..1) with, per pixel, the id of the point it shows
(-1 = background). Its HDR version comes from an inverse tone mapping operator
(:func:`expand_with_operator`), from the photo through PatchMatch, or from a network; its pixels are
averaged per point (:func:`project_views`), then only the over-exposed points (LDR luminance above
``t_l = 0.9``) take them (:func:`apply_transfer`). ``expand_points`` is the paper's LANDIS-PC /
BANTERLE-PC baseline: the operator applied to the points' colours directly.

Units: the cloud's linear LDR values. PatchMatch samples are radiance of the photo ``I_HDR``; the
cloud's colours are ``~ clamp(alpha * I_HDR)`` (:mod:`.exposure`), so they are brought to the cloud's
units by multiplying by ``alpha``; operator outputs are already in the cloud's units (``alpha = 1``).
"""

from __future__ import annotations

import numpy as np

from probeless.errors import HdrError
from probeless.hdr.exposure import luminance
from probeless.pano import itmo

OPERATORS = ("landis", "banterle")
"""Operators of §6.2 (LANDIS [Lan02], BANTERLE [BLDC06]), both defined on linear values."""

OVEREXPOSED = 0.9
"""The paper's luminance threshold ``t_l`` (§4.1)."""


def _points(a, what: str) -> np.ndarray:
    a = np.asarray(a, dtype=np.float32)
    if a.ndim != 2 or a.shape[1] != 3:
        raise HdrError(f"{what}: expected an (N, 3) array, got shape {a.shape}")
    if not np.isfinite(a).all():
        raise HdrError(f"{what}: has {int((~np.isfinite(a)).sum())} NaN or infinite values")
    return a


def overexposed(ldr_rgb_linear: np.ndarray, threshold: float = OVEREXPOSED) -> np.ndarray:
    """bool (...,): CIE Y of the linear LDR colours (..., 3) strictly above ``threshold``."""
    return luminance(ldr_rgb_linear) > np.float32(threshold)


def _operator(operator: str) -> str:
    if operator not in OPERATORS:
        raise HdrError(f"unknown expansion operator {operator!r}; choices: {', '.join(OPERATORS)}")
    return operator


def expand_with_operator(view_ldr: np.ndarray, operator: str, *, max_lum: float, **params) -> np.ndarray:
    """(H, W, 3) float32 HDR of a linear 0..1 rendering of the cloud by ``landis`` or ``banterle``.

    The operators of :mod:`probeless.pano.itmo` applied to linear values (a view is linear already, so no gamma
    is decoded here), with LDR white (1) mapped to ``max_lum`` [cloud units]: the peak comes from the data (the
    photo's brightest luminance in cloud units, :func:`probeless.hdr.expand.operator_peak`) or from the user,
    never from a constant. Banterle's ``l_white`` is ``max_lum`` too. ``params`` go to the operator.
    """
    v = np.asarray(view_ldr, dtype=np.float32)
    if v.ndim != 3 or v.shape[2] != 3:
        raise HdrError(f"view_ldr: expected an (H, W, 3) image, got shape {v.shape}")
    if not np.isfinite(v).all() or v.min(initial=0.0) < 0 or v.max(initial=0.0) > 1.0 + 1e-6:
        raise HdrError("view_ldr: values must be finite linear LDR values in 0..1")
    if _operator(operator) == "banterle":
        params.setdefault("l_white", max_lum)
    return itmo.apply_itmo(operator, v, max_lum=float(max_lum), **params)


KNN = 32
"""Neighbours of the point-cloud expand map (BANTERLE-PC)."""


def knn_expand_map(points: np.ndarray, mask: np.ndarray, k: int = KNN, at: np.ndarray | None = None) -> np.ndarray:
    """(N,) float32 expand map of BANTERLE-PC: the mean of ``mask`` over each point's ``k`` nearest neighbours (the
    point included; ``scipy.spatial.cKDTree``), normalised to max 1: the image operator's blur of the clipped mask,
    taken over the cloud's kNN graph instead of an image grid. ``at`` (bool (N,)): compute it only there (0
    elsewhere), e.g. at the over-exposed points, the only ones the transfer changes."""
    from scipy.spatial import cKDTree

    p = np.asarray(points, np.float64)
    m = np.asarray(mask, np.float32)
    e = np.zeros(len(p), np.float32)
    rows = np.flatnonzero(np.ones(len(p), bool) if at is None else at)
    if len(rows) == 0 or not m.any():
        return e
    kk = min(int(k), len(p))
    _, nb = cKDTree(p).query(p[rows], k=kk, workers=-1)
    nb = nb.reshape(len(rows), kk)
    e[rows] = m[nb].mean(axis=1)
    return e / max(float(e.max()), 1e-12)


def expand_points(ldr_points: np.ndarray, operator: str, *, max_lum: float, points: np.ndarray | None = None,
                  k: int = KNN) -> np.ndarray:
    """(N, 3) float32: LANDIS-PC / BANTERLE-PC, the operator applied to each point's colour.

    Landis is per value, so this is the image operator exactly. Banterle's expand map blurs the over-exposed mask:
    here over the kNN graph of ``points`` (:func:`knn_expand_map`, required for ``banterle``), not along the point
    order. ``max_lum`` as in :func:`expand_with_operator`.
    """
    p = _points(ldr_points, "ldr_points")
    if p.shape[0] == 0:
        return p.copy()
    if _operator(operator) == "landis":
        return itmo.landis_itmo(p, max_lum=float(max_lum))
    if points is None:
        raise HdrError("expand_points: banterle needs the points' positions for its kNN expand map")
    pos = _points(points, "points")
    if len(pos) != len(p):
        raise HdrError(f"expand_points: {len(pos)} positions for {len(p)} colours")
    ld = luminance(p)
    mask = ld > np.float32(OVEREXPOSED)
    e = knn_expand_map(pos, mask, k, at=mask)
    lw = ld * (1.0 - e) + itmo.inverse_reinhard(ld, float(max_lum), float(max_lum)) * e
    ratio = np.divide(lw, ld, out=np.zeros_like(ld), where=ld > 0)
    return (p * ratio[:, None]).astype(np.float32)


def inverse_ssd_weights(ssd: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    """float32 ``1 / (ssd + eps)``: PatchMatch quality as a weight, lower SSD = more weight."""
    s = np.asarray(ssd, dtype=np.float32)
    if not np.isfinite(s).all() or (s < 0).any():
        raise HdrError("ssd: expected finite values >= 0")
    return (1.0 / (s + np.float32(eps))).astype(np.float32)


def project_views(point_ids_per_view, values_per_view, n_points: int, weights_per_view=None):
    """Per-point average of the views' samples: ``(mean (N, C) float32, count (N,) int64)``.

    ``point_ids_per_view``: one int array per view (any shape S, e.g. (H, W)), the id of the point each
    pixel shows, -1 for background; ``values_per_view``: matching (S..., C) arrays (HDR RGB: C = 3);
    ``weights_per_view``: None for the plain mean (ITMO, networks) or matching (S...) weights > 0 (e.g.
    :func:`inverse_ssd_weights` for PatchMatch). Every pixel is one sample, so a point splatted on
    several pixels of a view counts several times. ``count``: samples per point; points without one
    get mean 0. Sums are accumulated in float64.
    """
    ids_list, vals_list = list(point_ids_per_view), list(values_per_view)
    if len(ids_list) != len(vals_list):
        raise HdrError(f"project_views: {len(ids_list)} id maps but {len(vals_list)} value maps")
    w_list = [None] * len(ids_list) if weights_per_view is None else list(weights_per_view)
    if len(w_list) != len(ids_list):
        raise HdrError(f"project_views: {len(ids_list)} id maps but {len(w_list)} weight maps")
    n = int(n_points)
    channels = None
    sums = wsum = count = None
    for i, (ids, vals, w) in enumerate(zip(ids_list, vals_list, w_list)):
        ids = np.asarray(ids)
        vals = np.asarray(vals, dtype=np.float64)
        if not np.issubdtype(ids.dtype, np.integer):
            raise HdrError(f"point_ids_per_view[{i}]: expected integer ids, got dtype {ids.dtype}")
        if vals.shape[:-1] != ids.shape or vals.ndim != ids.ndim + 1:
            raise HdrError(f"values_per_view[{i}]: shape {vals.shape} does not match ids {ids.shape} + (C,)")
        if channels is None:
            channels = vals.shape[-1]
            sums, wsum, count = np.zeros((n, channels)), np.zeros(n), np.zeros(n, np.int64)
        elif vals.shape[-1] != channels:
            raise HdrError(f"values_per_view[{i}]: {vals.shape[-1]} channels, view 0 has {channels}")
        ids = ids.ravel()
        vals = vals.reshape(-1, channels)
        if ids.size and (ids.max() >= n or ids.min() < -1):
            raise HdrError(f"point_ids_per_view[{i}]: ids must be in -1..{n - 1}, got {ids.min()}..{ids.max()}")
        keep = ids >= 0
        if not np.isfinite(vals[keep]).all():
            raise HdrError(f"values_per_view[{i}]: NaN or infinite values on point pixels")
        if w is None:
            wk = np.ones(int(keep.sum()))
        else:
            w = np.asarray(w, dtype=np.float64)
            if w.shape != (ids.size,) and w.shape != np.asarray(ids_list[i]).shape:
                raise HdrError(f"weights_per_view[{i}]: shape {w.shape} does not match ids")
            wk = w.ravel()[keep]
            if not np.isfinite(wk).all() or (wk <= 0).any():
                raise HdrError(f"weights_per_view[{i}]: weights must be finite and > 0 on point pixels")
        pid = ids[keep]
        count += np.bincount(pid, minlength=n)
        wsum += np.bincount(pid, weights=wk, minlength=n)
        for c in range(channels):
            sums[:, c] += np.bincount(pid, weights=wk * vals[keep, c], minlength=n)
    if channels is None:
        return np.zeros((n, 3), np.float32), np.zeros(n, np.int64)
    mean = np.divide(sums, wsum[:, None], out=np.zeros_like(sums), where=wsum[:, None] > 0)
    return mean.astype(np.float32), count


def apply_transfer(ldr_points: np.ndarray, hdr_samples: np.ndarray, counts: np.ndarray, alpha: float = 1.0,
                   mode: str = "rgb", threshold: float = OVEREXPOSED):
    """HDR colours of the cloud: ``(hdr_points (N, 3) float32, valid_mask (N,) bool)``.

    ``ldr_points``: (N, 3) linear LDR colours; ``hdr_samples``, ``counts``: :func:`project_views`'s
    output; ``alpha``: the factor to the cloud's units (the exposure of
    :func:`~probeless.hdr.exposure.match_exposure` for samples of the photo, 1 for operator outputs),
    which aligns the photo's black with the cloud's and makes the transfer continuous at the threshold.
    Points with LDR luminance <= ``threshold`` keep their LDR colour (valid). Over-exposed points
    with samples take ``s = alpha * sample``: ``rgb`` takes its colour, ``lum`` keeps the LDR
    chromaticity at the sample's luminance (``ldr * Y(s) / Y(ldr)``) (paper's Figure 2). Over-exposed
    points without samples (count 0; set it to 0 too for samples rejected by the PatchMatch SSD
    threshold ``t_h``) keep their LDR colour and are not valid: :mod:`.poisson` fills them.
    """
    ldr = _points(ldr_points, "ldr_points")
    s = np.asarray(hdr_samples, dtype=np.float32)
    c = np.asarray(counts)
    if s.shape != ldr.shape:
        raise HdrError(f"hdr_samples: shape {s.shape} does not match ldr_points {ldr.shape}")
    if c.shape != (ldr.shape[0],):
        raise HdrError(f"counts: expected shape ({ldr.shape[0]},), got {c.shape}")
    if not (np.isfinite(alpha) and alpha > 0):
        raise HdrError(f"alpha: expected a positive exposure, got {alpha}")
    if not 0.0 <= threshold < 1.0:
        raise HdrError(f"threshold: expected a luminance in [0, 1), got {threshold}")
    if mode not in ("rgb", "lum"):
        raise HdrError(f"mode: expected 'rgb' or 'lum', got {mode!r}")
    over = overexposed(ldr, threshold)
    take = over & (c > 0)
    if not np.isfinite(s[take]).all() or (s[take] < 0).any():
        raise HdrError("hdr_samples: NaN, infinite or negative values on over-exposed points")
    out = ldr.copy()
    sample = s[take] * np.float32(alpha)
    if mode == "rgb":
        out[take] = sample
    else:
        out[take] = ldr[take] * (luminance(sample) / luminance(ldr[take]))[:, None]
    return out, ~over | take


def reject_cluster_outliers(hdr_points: np.ndarray, valid: np.ndarray, clusters, factor: float = 2.0,
                            mads: float = 3.0, trusted: np.ndarray | None = None) -> tuple[np.ndarray, int]:
    """``(valid without the outliers, number rejected)``: robust agreement inside each clipped cluster.

    A connected cluster of over-exposed points (``clusters``: :class:`~.views.SaturatedCluster` list) is
    most often one surface or one emitter, yet PatchMatch matches its flat interior to any clipped patch of
    the photo with SSD 0 (a wall lit by a lamp may fetch the lamp). Per cluster, among its valid points,
    those whose log luminance is further than ``max(log factor, mads * 1.4826 * MAD)`` from the cluster's
    median are outliers: they lose their value, and the Poisson fill gives them one from their neighbours.
    Clusters with fewer than 3 valid points are left alone. ``trusted`` (N,) bool: values known to be right (the
    photo's own pixels, through its pose): never rejected, and where a cluster has at least 3 of them its median is
    theirs.
    """
    h = _points(hdr_points, "hdr_points")
    v = np.asarray(valid, bool).copy()
    if v.shape != (h.shape[0],):
        raise HdrError(f"valid: expected shape ({h.shape[0]},), got {v.shape}")
    if not (np.isfinite(factor) and factor > 1 and np.isfinite(mads) and mads > 0):
        raise HdrError(f"factor must be > 1 and mads > 0, got {factor!r}, {mads!r}")
    rejected = 0
    for cl in clusters:
        idx = cl.indices[v[cl.indices]]
        if len(idx) < 3:
            continue
        y = np.log(np.maximum(luminance(h[idx]).astype(np.float64), 1e-12))
        ref = y
        safe = np.zeros(len(idx), bool) if trusted is None else np.asarray(trusted, bool)[idx]
        if safe.sum() >= 3:
            ref = y[safe]
        med = np.median(ref)
        mad = np.median(np.abs(ref - med))
        out = (np.abs(y - med) > max(np.log(factor), mads * 1.4826 * mad)) & ~safe
        v[idx[out]] = False
        rejected += int(out.sum())
    return v, rejected

