"""Accuracy and cost of the fast diffuse maps against the exact convolution of the full-resolution frame.

For each HDR panorama and diffuse map size: the GPU maps (:class:`~probeless.pano.gpu_diffuse.GpuDiffuse`,
Algorithm 1 on a ``gpu_in_size`` area average with sub-texel weights, ``gpu``, and with radiance
moments, ``gpu_moments``), the numpy weight-matrix map (:func:`~probeless.pano.diffuse.diffuse_map`,
its default input size) and the SH9 map against the exact per-texel convolution of the full frame,
every texel, with max and mean relative error. The exact maps come from :func:`exact_diffuse` (the
brute-force sum, evaluated by FFT; checked against :func:`~probeless.pano.diffuse.diffuse_map_bruteforce`
in the tests); the paper's one-texel-at-a-time construction is timed on ``probe_texels`` texels and
scaled up to the whole map, its per-frame setup counted once (``paper_bruteforce_s``). GPU times are
those of the GL renderer named in the result (Mesa llvmpipe on a CPU-only machine: not a GPU's figures).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from probeless.pano.diffuse import (
    IN_SIZES,
    MAX_WEIGHTS,
    bruteforce_inputs,
    bruteforce_texels,
    diffuse_map,
    sh9_irradiance_map,
)
from probeless.pano.equirect import check_equirect, pixel_directions, solid_angles
from probeless.pano.sources import default_panoramas, read_panorama
from probeless.progress import progress

SIZES = ((32, 16), (64, 32), (128, 64))
GPU_METHODS = {"gpu": "subtexel", "gpu_moments": "moments"}  # result key -> GpuDiffuse weights
METHODS = ("gpu", "gpu_moments", "matmul", "sh9")


def exact_diffuse(hdr: np.ndarray, out_size: tuple[int, int], batch: int = 16) -> np.ndarray:
    """(H_out, W_out, C) float64 ``sum_w L(w) max(0, n . w) dOmega / sum_w max(0, n . w) dOmega`` over
    every pixel of ``hdr``: the brute-force sum, evaluated exactly but fast.

    The weights of output column ``j`` are those of column 0 shifted by ``j W / W_out`` pixels, so
    when that is whole each output row is one circular cross-correlation along the columns (FFT);
    otherwise ``batch`` output texels per matrix product.
    """
    img = check_equirect(hdr, "exact_diffuse").astype(np.float64)
    h, w, c = img.shape
    ow, oh = out_size
    dirs = pixel_directions(w, h)
    omega = solid_angles(w, h)
    normals = pixel_directions(ow, oh)
    if w % ow:
        return _exact_batched(img, dirs, omega, normals, batch)
    spectrum = np.fft.rfft(img, axis=1)  # (H, W/2 + 1, C)
    out = np.empty((oh, ow, c))
    for t in range(oh):
        w0 = omega * np.maximum(dirs @ normals[t, 0], 0.0)
        corr = np.fft.irfft(np.einsum("hk,hkc->kc", np.conj(np.fft.rfft(w0, axis=1)), spectrum), n=w, axis=0)
        out[t] = corr[::w // ow] / w0.sum()
    return out


def _exact_batched(img, dirs, omega, normals, batch):
    flat, d, om = img.reshape(-1, img.shape[2]), dirs.reshape(-1, 3), omega.reshape(-1)
    n = normals.reshape(-1, 3)
    out = np.empty((len(n), img.shape[2]))
    for i in range(0, len(n), batch):
        wgt = np.maximum(n[i:i + batch] @ d.T, 0.0) * om
        out[i:i + batch] = (wgt @ flat) / wgt.sum(axis=1, keepdims=True)
    return out.reshape(*normals.shape[:2], img.shape[2])


def rel_errors(fast: np.ndarray, exact: np.ndarray) -> dict[str, float]:
    """Max and mean of ``|fast - exact| / exact`` over texels and channels (floor: 1e-6 of the max)."""
    den = np.maximum(exact, 1e-6 * float(exact.max()))
    rel = np.abs(np.asarray(fast, np.float64) - exact) / den
    return {"max_rel_error": float(rel.max()), "mean_rel_error": float(rel.mean())}


def _best_time(fn: Callable[[], Any], repeat: int = 3) -> tuple[float, Any]:
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def matmul_in_size(out_size: tuple[int, int]) -> tuple[int, int]:
    """The input size :func:`diffuse_map` picks by default for ``out_size``."""
    n = out_size[0] * out_size[1]
    return next((s for s in IN_SIZES if s[0] * s[1] * n <= MAX_WEIGHTS), IN_SIZES[-1])


def evaluate_size(hdr: np.ndarray, size: tuple[int, int], gpus: dict[str, Any], probe_texels: int = 8
                  ) -> dict[str, Any]:
    """Errors and timings at one diffuse map ``size`` of one frame; ``gpus``: method -> GpuDiffuse."""
    t_exact, exact = _best_time(lambda: exact_diffuse(hdr, size), 1)
    in_mm = matmul_in_size(size)
    t_weights, _ = _best_time(lambda: diffuse_map(hdr, size, in_size=in_mm), 1)  # builds the cached weights
    t_mm, mm = _best_time(lambda: diffuse_map(hdr, size, in_size=in_mm))
    idx = np.random.default_rng(0).choice(size[0] * size[1], probe_texels, replace=False)
    t_setup, inputs = _best_time(lambda: bruteforce_inputs(hdr), 2)  # the per-frame setup, counted once
    t_probe, _ = _best_time(lambda: bruteforce_texels(inputs, size, idx), 2)
    t_paper = t_setup + t_probe / probe_texels * size[0] * size[1]
    row: dict[str, Any] = {"matmul": rel_errors(mm, exact), "sh9": rel_errors(sh9_irradiance_map(hdr, size), exact),
                           "matmul_in_size": list(in_mm), "matmul_s": t_mm, "matmul_weights_s": t_weights,
                           "matmul_speedup": t_paper / t_mm, "exact_s": t_exact, "paper_bruteforce_s": t_paper,
                           "paper_bruteforce_probe_texels": probe_texels}
    for method, gpu in gpus.items():
        gpu.apply(hdr)  # warm: first-use allocations
        t_gpu, fast = _best_time(lambda: gpu.apply(hdr), 2)
        row.update({method: rel_errors(fast, exact), f"{method}_s": t_gpu, f"{method}_speedup": t_paper / t_gpu,
                    f"{method}_in_size": list(gpu.in_size)})
    return row


def evaluate_diffuse(panoramas: Sequence[str | Path] | None = None, sizes: Sequence[tuple[int, int]] = SIZES,
                     gpu_in_size: tuple[int, int] = (128, 64), probe_texels: int = 8,
                     show_progress: bool = True) -> dict[str, Any]:
    """Per panorama and size: errors of the GPU map (``gpu``: sub-texel weights as matmul;
    ``gpu_moments``: radiance moments), matmul and SH9 against the exact full-resolution map, and
    timings (see the module docstring); ``summary`` has the worst max and the mean mean error."""
    from probeless.gl.context import create_context
    from probeless.pano.gpu_diffuse import GpuDiffuse

    paths = [Path(p) for p in (panoramas or default_panoramas())]
    ctx = create_context()
    gpus = {tuple(s): {m: GpuDiffuse(ctx, tuple(s), gpu_in_size, weights=wt) for m, wt in GPU_METHODS.items()}
            for s in sizes}
    result: dict[str, Any] = {"reference": "exact per-texel convolution of the full-resolution frame, float64",
                              "renderer": ctx.info["GL_RENDERER"], "panoramas": {}}
    with progress(len(paths) * len(sizes), "diffuse maps vs exact", show_progress) as tick:
        for path in paths:
            hdr = read_panorama(str(path))
            rows = result["panoramas"][path.name] = {"resolution": [hdr.shape[1], hdr.shape[0]]}
            for size in sizes:
                rows[f"{size[0]}x{size[1]}"] = evaluate_size(hdr, tuple(size), gpus[tuple(size)], probe_texels)
                tick()
    for per_size in gpus.values():
        for g in per_size.values():
            g.release()
    ctx.release()
    result["summary"] = summarize(result["panoramas"], sizes)
    return result


def summarize(per_pano: dict[str, dict], sizes: Sequence[tuple[int, int]]) -> dict[str, dict[str, float]]:
    """Per size: worst max and average mean relative error over the panoramas, median timings."""
    out = {}
    for w, h in sizes:
        rows = [p[f"{w}x{h}"] for p in per_pano.values()]
        entry = {}
        for method in METHODS:
            entry[f"{method}_max_rel_error"] = max(r[method]["max_rel_error"] for r in rows)
            entry[f"{method}_mean_rel_error"] = float(np.mean([r[method]["mean_rel_error"] for r in rows]))
        for key in [f"{m}_{k}" for m in METHODS[:-1] for k in ("s", "speedup")] + ["exact_s", "paper_bruteforce_s"]:
            entry[key] = float(np.median([r[key] for r in rows]))
        out[f"{w}x{h}"] = entry
    return out
