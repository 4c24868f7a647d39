"""Envmap scores that do not flatter (issue 17 §4): one entry point, :func:`score_envmap`, for the offline
(``probeless eval envmap --oracle``) and the graph-mode evaluations.

Units. ``est`` and ``truth_ldr`` are camera LDR: sRGB-encoded fisheye output 0..1 (uint8 codes / 255), i.e.
``linear_to_srgb(clip(radiance * exposure, 0, 1))``. ``truth_hdr`` is the rig's linear radiance (``gt/envmap``),
unclipped. ``est`` is decoded back to radiance as ``srgb_to_linear(est) / exposure``: its clipped texels stay
clipped, which is the point of the HDR scores (they show what an LDR map loses). A linear (HDR) map
(``Cubemap.linear``, ``linear=True``) is in the camera's *linear* units (radiance x exposure, 1 = LDR white,
unclipped): its radiance is ``est / exposure`` as it is, and the camera-LDR scores see it as the camera would,
``linear_to_srgb(clip(est, 0, 1))``; so one set of scores compares LDR and HDR maps.

Texel sets. ``observed`` (texels of ``est`` that show something a camera saw) gives ``coverage``; ``common``
(texels both compared methods observed; default ``observed``) is where the ``*_common`` scores, ``log_rmse_hdr``
and ``pu21_psnr`` are taken, so a method is not rewarded for painting texels nobody saw nor punished for the grey
it shows there. ``psnr_all``, ``rmse_sa`` and the SH scores take the whole sphere, unseen texels as they are.

PU21 (Mantiuk and Azimi, "PU21: A novel perceptually uniform encoding for adapting existing quality metrics for
HDR", Picture Coding Symposium 2021; reference code github.com/gfxdisp/pu21): the ``banding_glare`` variant the
authors recommend, ``V = p7 ((p1 + p2 Y^p4) / (1 + p3 Y^p4))^p5 - p6)`` for ``Y`` clamped to 0.005..10000 cd/m²,
applied to each linear RGB channel. Absolute units: the camera's clip level (``radiance * exposure = 1``) is
taken as :data:`PU21_WHITE_NITS` cd/m² (an SDR display's white); the PSNR's peak is ``V(10000)`` ≈ 595.39.
"""

from __future__ import annotations

import numpy as np

from probeless.color import linear_to_srgb, luminance, srgb_to_linear
from probeless.envmap import metrics as M
from probeless.envmap.sh import irradiance_from_sh, project_cubemap
from probeless.errors import ProbelessError
from probeless.geom.cube import cube_directions, cube_solid_angles

PU21_BANDING_GLARE = (0.353487901, 0.3734658629, 8.277049286e-05, 0.9062562627, 0.09150303166, 0.9099517204,
                      596.3148142)
PU21_L_MIN, PU21_L_MAX = 0.005, 10000.0  # cd/m², the encoding's range
PU21_WHITE_NITS = 100.0   # cd/m² given to the camera's clip level (radiance * exposure = 1)
LOG_FLOOR = 1e-4          # camera linear units: log10 floor (below 8-bit sRGB code 1 = 3e-4)
SH_BANDS = 3              # diffuse lighting: l <= 2 carries all but ~1 % of the clamped cosine
SH_NORMALS_FACE = 8       # the normals of sh_diffuse_error: cube texel directions of 8 x 8 faces, solid-angle weighted
SCORES = ("psnr_common", "ssim_common", "coverage", "common_coverage", "psnr_all", "rmse_sa", "log_rmse_hdr",
          "pu21_psnr", "sh_diffuse_error", "sh_diffuse_error_ldr")


def pu21_encode(nits: np.ndarray, params=PU21_BANDING_GLARE) -> np.ndarray:
    """PU21 code values of absolute linear values [cd/m²] (clamped to 0.005..10000), Mantiuk and Azimi 2021."""
    p1, p2, p3, p4, p5, p6, p7 = params
    y = np.clip(np.asarray(nits, np.float64), PU21_L_MIN, PU21_L_MAX) ** p4
    return p7 * (((p1 + p2 * y) / (1.0 + p3 * y)) ** p5 - p6)


def _faces(a: np.ndarray, what: str) -> np.ndarray:
    f = np.asarray(a)
    if f.ndim != 4 or f.shape[0] != 6 or f.shape[1] != f.shape[2] or f.shape[3] < 3:
        raise ProbelessError(f"score_envmap: {what} must be (6, S, S, 3) faces, got shape {f.shape}")
    return f[..., :3].astype(np.float64) / (255.0 if f.dtype == np.uint8 else 1.0)


def box_down(a: np.ndarray, size: int, what: str) -> np.ndarray:
    """(6, size, size, ...) block means of (6, S, S, ...) ``a``; S must be a multiple of ``size``."""
    s = a.shape[1]
    if s < size or s % size:
        raise ProbelessError(f"score_envmap: {what} faces are {s} texels wide, not a multiple of the truth's {size}")
    k = s // size
    return a.reshape(6, size, k, size, k, *a.shape[3:]).mean(axis=(2, 4))


def _mask(m, size: int, what: str) -> np.ndarray:
    if m is None:
        return np.ones((6, size, size), bool)
    b = np.asarray(m, bool)
    if b.ndim != 3 or b.shape[0] != 6 or b.shape[1] != b.shape[2]:
        raise ProbelessError(f"score_envmap: {what} must be a (6, S, S) mask, got shape {b.shape}")
    return b if b.shape[1] == size else box_down(b.astype(np.float64), size, what) >= 0.5


def _wmean(values: np.ndarray, w: np.ndarray) -> float:
    return float((values * w).sum() / w.sum()) if w.sum() > 0 else float("nan")


def ssim_masked(est: np.ndarray, truth: np.ndarray, mask: np.ndarray) -> float:
    """Mean of the per-face SSIM maps (:func:`probeless.envmap.metrics.ssim_map`) over the ``mask`` texels."""
    maps = np.stack([M.ssim_map(est[f], truth[f]) for f in range(6)])
    return float(maps[mask].mean()) if mask.any() else float("nan")


def sh_diffuse_error(est_radiance: np.ndarray, ref_radiance: np.ndarray) -> float:
    """Relative RMS error of the irradiance from 3-band SH of two linear maps, over the sphere of normals."""
    normals = cube_directions(SH_NORMALS_FACE).reshape(-1, 3)
    w = cube_solid_angles(SH_NORMALS_FACE).reshape(-1, 1)
    e, r = (irradiance_from_sh(project_cubemap(m, SH_BANDS), normals) for m in (est_radiance, ref_radiance))
    den = float((w * r * r).sum())
    if den <= 0:
        raise ProbelessError("score_envmap: the reference map has no light (zero irradiance)")
    return float(np.sqrt((w * (e - r) ** 2).sum() / den))


def _psnr(err2: np.ndarray, w: np.ndarray, peak: float = 1.0) -> float:
    mse = _wmean(err2, w)
    if not np.isfinite(mse):
        return float("nan")
    return float("inf") if mse == 0 else float(10.0 * np.log10(peak * peak / mse))


def score_envmap(est, truth_ldr, truth_hdr, *, exposure: float, observed=None, common=None,
                 linear: bool = False) -> dict[str, float]:
    """Scores of one estimated map against the truth (module doc for units and texel sets).

    Returns ``psnr_common`` [dB] and ``ssim_common`` (camera LDR, peak 1; the SSIM maps' mean over common
    texels), ``coverage`` / ``common_coverage`` (solid-angle fraction of ``observed`` / ``common``), ``psnr_all``
    [dB] (every texel equal, the whole sphere: the old ``envmap_psnr``), ``rmse_sa`` (solid-angle-weighted RMSE
    over the sphere, camera LDR), ``log_rmse_hdr`` (solid-angle-weighted RMSE of log10 luminance over common
    texels against ``truth_hdr``, both floored at :data:`LOG_FLOOR` / exposure), ``pu21_psnr`` [dB] (PU21
    units over common texels, peak V(10000)), ``sh_diffuse_error`` (:func:`sh_diffuse_error` of est's radiance
    vs ``truth_hdr``) and ``sh_diffuse_error_ldr`` (vs ``truth_ldr`` linearised: the fair one for LDR maps).
    ``exposure``: the fisheye's linear multiplier (camera linear = radiance x exposure), a number or per channel
    (3,) (exposure x white-balance gains). ``linear``: ``est`` is a linear HDR map in camera linear units (module
    doc). A score over an empty set of texels is NaN.
    """
    t_ldr, t_hdr = _faces(truth_ldr, "truth_ldr"), np.asarray(truth_hdr, np.float64)
    size = t_ldr.shape[1]
    if t_hdr.shape[:3] != t_ldr.shape[:3] or t_hdr.ndim != 4:
        raise ProbelessError(f"score_envmap: truth_hdr {t_hdr.shape} does not match truth_ldr {t_ldr.shape}")
    exposure = np.asarray(exposure, np.float64)
    if exposure.shape not in ((), (3,)) or not (np.isfinite(exposure).all() and (exposure > 0).all()):
        raise ProbelessError(f"score_envmap: exposure must be a positive number (or 3, per channel), got {exposure!r}")
    t_hdr = t_hdr[..., :3]
    e = _faces(est, "est")
    e = e if e.shape[1] == size else box_down(e, size, "est")
    if linear:
        if not np.isfinite(e).all():
            raise ProbelessError("score_envmap: the linear map has NaN or infinite texels")
        e_rad = np.maximum(e, 0.0) / exposure
        e = linear_to_srgb(np.clip(e, 0.0, 1.0))
    else:
        e = np.clip(e, 0.0, 1.0)
        e_rad = srgb_to_linear(e) / exposure
    obs = _mask(observed, size, "observed")
    com = obs if common is None else _mask(common, size, "common")
    omega = cube_solid_angles(size)
    err2 = ((e - t_ldr) ** 2).mean(axis=-1)
    floor = LOG_FLOOR / float(exposure.mean())
    log_err2 = (np.log10(np.maximum(luminance(e_rad), floor)) - np.log10(np.maximum(luminance(t_hdr), floor))) ** 2
    nits = PU21_WHITE_NITS * exposure
    pu_err2 = ((pu21_encode(e_rad * nits) - pu21_encode(t_hdr * nits)) ** 2).mean(axis=-1)
    return {
        "psnr_common": _psnr(err2, com.astype(np.float64)),
        "ssim_common": ssim_masked(e, t_ldr, com),
        "coverage": M.coverage(obs, omega),
        "common_coverage": M.coverage(com, omega),
        "psnr_all": _psnr(err2, np.ones_like(err2)),
        "rmse_sa": float(np.sqrt(_wmean(err2, omega))),
        "log_rmse_hdr": float(np.sqrt(_wmean(log_err2, omega * com))),
        "pu21_psnr": _psnr(pu_err2, omega * com, float(pu21_encode(PU21_L_MAX))),
        "sh_diffuse_error": sh_diffuse_error(e_rad, t_hdr),
        "sh_diffuse_error_ldr": sh_diffuse_error(e_rad, srgb_to_linear(np.clip(t_ldr, 0, 1)) / exposure),
    }
