"""Accuracy and speed of glossy ring sampling against a Monte Carlo Phong-lobe integral (paper 002, Fig. 6).

Error metric (luminance, the paper's Eq. 1 weights ``Y = 0.3 R + 0.59 G + 0.11 B``): for each of
``n_dirs`` random reflection directions ``i``, ``e_i = |Y(est_i) - Y(ref_i)| / mean_j Y(ref_j)``,
i.e. the error relative to the panorama's mean glossy radiance at that roughness (a per-direction
relative error would blow up in dark directions). Reported: mean and max of ``e_i``. The
reference ``ref`` is the mean of two Monte Carlo estimates with independent seeds (``seed`` and
``seed + 1``); its own noise is ``|Y(mc_a) - Y(mc_b)| / 2`` in the same units (the standard error of
the mean of two), the floor below which an error cannot be resolved. Times are per direction,
mip chain excluded (the paper builds it for the diffuse map anyway).

Equal cost: the ring pattern makes 36 trilinear lookups per direction. Its competitors at the same
number of lookups, against the same converged reference: ``mc_equal`` (the reference's own
importance-sampled Monte Carlo with 36 bilinear lookups of level 0) and ``fis_equal`` (filtered
importance sampling, Křivánek & Colbert 2008: the same 36 lobe samples, each a trilinear lookup at
``lod = max(0, log2(Ω_s / Ω_p) / 2 + 1)``, Ω_s = 1 / (K pdf) the sample's share of the lobe, Ω_p the
level-0 texel's solid angle). ``glossy_equal_cost_error_ratio`` = error of the better of the two /
error of the ring (> 1: the ring is more accurate at equal cost).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from probeless.pano import glossy
from probeless.pano.equirect import direction_to_pixel, row_solid_angles
from probeless.pano.glossy_figure import LUMA, ROUGHNESS, glossy_figure
from probeless.pano.glossy_report import format_table
from probeless.pano.rings import lobe_half_angle, mass_to_angle, phong_exponent, ring_pattern
from probeless.pano.sources import default_panoramas, read_panorama
from probeless.progress import progress

__all__ = ["evaluate_glossy", "format_table", "glossy_figure", "rel_errors"]  # command line: probeless.eval.glossy
DEFAULT_GLOB = "../shared/data/hdri/*.hdr"  # what :func:`default_panoramas` reads, for help texts


def random_directions(n: int, seed: int = 0) -> np.ndarray:
    """(n, 3) unit directions uniform on the sphere."""
    d = np.random.default_rng(seed).normal(size=(int(n), 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def rel_errors(est: np.ndarray, ref: np.ndarray, scale: float = 1.0) -> dict[str, float]:
    """Mean and max of ``scale |Y(est) - Y(ref)| / mean Y(ref)`` over directions (module doc)."""
    yr = np.asarray(ref, np.float64) @ LUMA
    e = scale * np.abs(np.asarray(est, np.float64) @ LUMA - yr) / max(float(yr.mean()), 1e-30)
    return {"mean": float(e.mean()), "max": float(e.max())}


def glossy_fis(levels: list[np.ndarray], dirs: np.ndarray, roughness: float, n_samples: int,
               rng=None) -> np.ndarray:
    """(N, C) float32 filtered importance sampling of the Phong lobe (module doc): ``n_samples`` lobe
    samples on glossy_mc's shifted rank-1 lattice, each a trilinear lookup at its pdf's mip level."""
    n, r, s = phong_exponent(roughness), np.asarray(dirs, np.float64), int(n_samples)
    if s < 1:
        raise ValueError(f"glossy_fis: n_samples must be >= 1, got {n_samples}")
    shift = np.random.default_rng(rng).random((len(r), 2))
    i = np.arange(s)
    u = np.mod((i + 0.5) / s + shift[:, :1], 1.0)
    v = np.mod(i * (np.sqrt(5.0) - 1.0) / 2.0 + shift[:, 1:], 1.0)
    theta = mass_to_angle(1.0 - u, n)
    d = glossy._around(r, theta, 2.0 * np.pi * v)  # (N, K, 3), the lattice glossy_mc uses
    pdf = (n + 1.0) / (2.0 * np.pi) * np.cos(theta) ** n
    h, w = levels[0].shape[:2]
    row = np.clip(direction_to_pixel(d, w, h)[1].astype(np.int64), 0, h - 1)
    omega_p = row_solid_angles(w, h)[row]
    lod = np.maximum(0.0, 0.5 * np.log2(1.0 / (s * np.maximum(pdf, 1e-30)) / omega_p) + 1.0)
    return sample_equirect_mean(levels, d, lod)


def sample_equirect_mean(levels: list[np.ndarray], d: np.ndarray, lod: np.ndarray) -> np.ndarray:
    """(N, C) float32 mean over K of trilinear lookups of ``d`` (N, K, 3) at ``lod`` (N, K)."""
    return glossy.sample_equirect(levels, d, lod).astype(np.float64).mean(axis=1).astype(np.float32)


def equal_cost(img, levels, dirs, roughness: float, ref: np.ndarray, ring_err: dict, seed: int) -> dict[str, Any]:
    """Errors of MC and FIS at the ring's lookup count against ``ref``, their times, and the error ratio."""
    k = int(ring_pattern(roughness, img.shape[0]).weights.size)
    mc, t_mc = _timed(lambda: glossy.glossy_mc(img, dirs, roughness, k, rng=seed + 2), 3)
    fis, t_fis = _timed(lambda: glossy_fis(levels, dirs, roughness, k, rng=seed + 2), 3)
    e_mc, e_fis = rel_errors(mc, ref), rel_errors(fis, ref)
    best = min(e_mc["mean"], e_fis["mean"])
    return {"lookups": k, "mc_equal": e_mc, "fis_equal": e_fis,
            "ms_per_dir_mc_equal": 1e3 * t_mc / len(dirs), "ms_per_dir_fis_equal": 1e3 * t_fis / len(dirs),
            "glossy_equal_cost_error_ratio": best / max(ring_err["mean"], 1e-30),
            "glossy_equal_cost_reference": f"the better of Monte Carlo and filtered importance sampling with {k} "
                                           "lookups (the ring's count), same directions, same converged truth"}


def _timed(fn, repeat: int = 1):
    best, out = float("inf"), None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return out, best


def evaluate_one(img: np.ndarray, levels: list[np.ndarray], dirs: np.ndarray, roughness: float, mc_samples: int,
                 seed: int, lod_biases: tuple[float, ...]) -> dict[str, Any]:
    """One panorama at one roughness: errors of ring sampling (per lod bias) and mirror, MC noise, times."""
    mc_a, t_mc = _timed(lambda: glossy.glossy_mc(img, dirs, roughness, mc_samples, rng=seed))
    mc_b = glossy.glossy_mc(img, dirs, roughness, mc_samples, rng=seed + 1)
    ref = 0.5 * (mc_a.astype(np.float64) + mc_b)
    n = phong_exponent(roughness)
    out: dict[str, Any] = {"exponent": n, "lobe_half_angle_deg": float(np.degrees(lobe_half_angle(n))),
                           "mc_noise": rel_errors(mc_a, mc_b, scale=0.5)}
    times = []
    for bias in lod_biases:
        run = lambda: glossy.glossy_ring(levels, dirs, roughness, ring_pattern(roughness, img.shape[0],  # noqa: E731
                                                                                lod_bias=bias))
        est, t = _timed(run, repeat=3)
        out["ring" if bias == 0.0 else f"ring_lod_bias_{bias:g}"] = rel_errors(est, ref)
        times.append(t)
    t_ring = min(times)  # every bias costs the same: 36 lookups and the pattern
    out["mirror"] = rel_errors(glossy.mirror(levels, dirs), ref)
    out["ms_per_dir_ring"] = 1e3 * t_ring / len(dirs)
    out["ms_per_dir_mc_truth"] = 1e3 * t_mc / len(dirs)
    out.update(equal_cost(img, levels, dirs, roughness, ref, out["ring"], seed))
    return out


def evaluate_glossy(panoramas: list[str] | None = None, roughness=ROUGHNESS, n_dirs: int = 128,
                    mc_samples: int = 8192, seed: int = 0, lod_biases: tuple[float, ...] = (0.0, -0.5, -1.0),
                    show_progress: bool = True) -> dict[str, Any]:
    """Ring sampling vs Monte Carlo for every panorama and roughness (metric: module doc).

    Returns ``{"settings": ..., "panoramas": {name: {str(roughness): evaluate_one(...)}},
    "summary": {str(roughness): mean over panoramas of the mean errors, max of the max errors}}``.
    """
    paths = default_panoramas() if not panoramas else list(panoramas)
    rough = [float(r) for r in roughness]
    for r in rough:
        phong_exponent(r)
    dirs = random_directions(n_dirs, seed)
    lod_biases = (0.0,) + tuple(float(b) for b in lod_biases if b != 0.0)  # "ring" is always the paper's rule
    res: dict[str, Any] = {"settings": {"n_dirs": int(n_dirs), "mc_samples": int(mc_samples), "seed": int(seed),
                                        "ring_samples": int(ring_pattern(0.1, 8).weights.size),
                                        "lod_biases": list(lod_biases),
                                        "metric": "|Y(est) - Y(ref)| / mean Y(ref) per direction, "
                                                  "Y = 0.3 R + 0.59 G + 0.11 B"}, "panoramas": {}}
    with progress(len(paths) * len(rough), "glossy vs MC", enabled=show_progress) as tick:
        for path in paths:
            img = read_panorama(path, linear=True)
            levels = glossy.mip_levels(img)
            rows = res["panoramas"][Path(path).name] = {}
            for r in rough:
                rows[f"{r:g}"] = evaluate_one(img, levels, dirs, r, mc_samples, seed, tuple(lod_biases))
                tick()
    res["summary"] = _summary(res["panoramas"], rough)
    return res


def _summary(per_pano: dict[str, Any], rough: list[float]) -> dict[str, Any]:
    out = {}
    for r in rough:
        rows = [p[f"{r:g}"] for p in per_pano.values()]
        keys = [k for k, v in rows[0].items() if isinstance(v, dict)]
        out[f"{r:g}"] = {k: {"mean": float(np.mean([x[k]["mean"] for x in rows])),
                             "max": float(np.max([x[k]["max"] for x in rows]))} for k in keys}
        out[f"{r:g}"]["glossy_equal_cost_error_ratio"] = float(np.median(
            [x["glossy_equal_cost_error_ratio"] for x in rows]))
    return out
