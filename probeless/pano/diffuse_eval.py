"""Accuracy and cost of the fast diffuse maps against the exact convolution of the full-resolution frame.

For each HDR panorama and diffuse map size: the GPU maps (:class:`~probeless.pano.gpu_diffuse.GpuDiffuse`,
Algorithm 1 on a ``gpu_in_size`` area average with sub-texel weights, ``gpu``, and with radiance
moments, ``gpu_moments``), the numpy weight-matrix map (:func:`~probeless.pano.diffuse.diffuse_map`,
its default input size), the fast map (:func:`~probeless.pano.diffuse_fast.diffuse_map_fast`, ``fast``)
and the SH9 map against the exact per-texel convolution of the full frame,
every texel, with max and mean relative error. The exact maps come from :func:`exact_diffuse` (the
brute-force sum, evaluated by FFT; checked against :func:`~probeless.pano.diffuse.diffuse_map_bruteforce`
in the tests).

Speed-ups have one reference, :data:`SPEEDUP_REFERENCE`: that same exact convolution doing the same
work (the whole frame in, every texel of the same map out), timed warm like the fast paths (the least
of ``repeats`` runs); ``{method}_speedup`` = ``exact_s / {method}_s``. The matmul's one-off weight
build is timed from scratch once per size (``matmul_weights_s``) and counted in
``matmul_first_use_speedup``. The error gate of the same run: ``{method}_gate_met`` when the method's
worst max relative error over the panoramas is <= :data:`GATE`. GPU times are those of the GL renderer
named in the result (Mesa llvmpipe on a CPU-only machine: not a GPU's figures).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from probeless.pano.diffuse import IN_SIZES, MAX_WEIGHTS, diffuse_map, diffuse_weights, sh9_irradiance_map
from probeless.pano.diffuse_fast import diffuse_map_fast
from probeless.pano.equirect import check_equirect, pixel_directions, solid_angles
from probeless.pano.sources import default_panoramas, read_panorama
from probeless.progress import progress

SIZES = ((32, 16), (64, 32), (128, 64))
GPU_METHODS = {"gpu": "subtexel", "gpu_moments": "moments"}  # result key -> GpuDiffuse weights
METHODS = ("gpu", "gpu_moments", "matmul", "fast", "sh9")
TIMED = METHODS[:-1]  # the fast paths with a speed-up (SH9 is scored, not timed)
GATE = 0.01  # max relative error of a fast map against the exact one, every texel
SPEEDUP_REFERENCE = "exact_diffuse (FFT convolution of the full-resolution frame, numpy float64, every texel)"


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


def weights_build_s(size: tuple[int, int]) -> float:
    """Seconds to build the matmul's weight matrix for ``size`` from scratch (it stays cached after)."""
    diffuse_weights.cache_clear()
    return _best_time(lambda: diffuse_weights(tuple(size), matmul_in_size(size)), 1)[0]


def evaluate_size(hdr: np.ndarray, size: tuple[int, int], gpus: dict[str, Any], weights_s: float,
                  repeats: int = 2) -> dict[str, Any]:
    """Errors and timings at one diffuse map ``size`` of one frame; ``gpus``: method -> GpuDiffuse;
    ``weights_s``: the matmul's weight build (:func:`weights_build_s`). Every method and the exact
    reference take the same frame and give the same ``size`` map, timed warm, the least of ``repeats``."""
    t_exact, exact = _best_time(lambda: exact_diffuse(hdr, size), repeats)
    in_mm = matmul_in_size(size)
    diffuse_map(hdr, size, in_size=in_mm)  # warm: the weights are cached
    t_mm, mm = _best_time(lambda: diffuse_map(hdr, size, in_size=in_mm), repeats)
    diffuse_map_fast(hdr, size)  # warm: kernels cached
    t_fast, fast = _best_time(lambda: diffuse_map_fast(hdr, size), repeats)
    shapes = {"exact": list(exact.shape), "matmul": list(mm.shape), "fast": list(fast.shape)}
    row: dict[str, Any] = {"matmul": rel_errors(mm, exact), "sh9": rel_errors(sh9_irradiance_map(hdr, size), exact),
                           "matmul_in_size": list(in_mm), "matmul_s": t_mm, "matmul_weights_s": weights_s,
                           "matmul_speedup": t_exact / t_mm, "matmul_first_use_speedup": t_exact / (weights_s + t_mm),
                           "exact_s": t_exact, "texels": size[0] * size[1], "output_shapes": shapes,
                           "fast": rel_errors(fast, exact), "fast_s": t_fast, "fast_speedup": t_exact / t_fast}
    for method, gpu in gpus.items():
        gpu.apply(hdr)  # warm: first-use allocations
        t_gpu, fast = _best_time(lambda: gpu.apply(hdr), repeats)
        shapes[method] = list(fast.shape)
        row.update({method: rel_errors(fast, exact), f"{method}_s": t_gpu, f"{method}_speedup": t_exact / t_gpu,
                    f"{method}_in_size": list(gpu.in_size)})
    return row


def evaluate_diffuse(panoramas: Sequence[str | Path] | None = None, sizes: Sequence[tuple[int, int]] = SIZES,
                     gpu_in_size: tuple[int, int] = (128, 64), repeats: int = 2,
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
    weights = {tuple(s): weights_build_s(tuple(s)) for s in sizes}
    result: dict[str, Any] = {"reference": "exact per-texel convolution of the full-resolution frame, float64",
                              "speedup_reference": SPEEDUP_REFERENCE, "gate": {"max_rel_error_max": GATE},
                              "timing": f"warm, the least of {max(1, repeats)} runs; matmul_weights_s: one build "
                                        "from scratch per size", "renderer": ctx.info["GL_RENDERER"], "panoramas": {}}
    with progress(len(paths) * len(sizes), "diffuse maps vs exact", show_progress) as tick:
        for path in paths:
            hdr = read_panorama(str(path))
            rows = result["panoramas"][path.name] = {"resolution": [hdr.shape[1], hdr.shape[0]]}
            for size in sizes:
                rows[f"{size[0]}x{size[1]}"] = evaluate_size(hdr, tuple(size), gpus[tuple(size)],
                                                                weights[tuple(size)], repeats)
                tick()
    for per_size in gpus.values():
        for g in per_size.values():
            g.release()
    ctx.release()
    result["summary"] = summarize(result["panoramas"], sizes)
    return result


def summarize(per_pano: dict[str, dict], sizes: Sequence[tuple[int, int]]) -> dict[str, dict[str, Any]]:
    """Per size: worst max and average mean relative error over the panoramas, median timings and
    speed-ups, and ``{method}_gate_met`` (worst max relative error <= :data:`GATE`) for the timed methods."""
    out = {}
    for w, h in sizes:
        rows = [p[f"{w}x{h}"] for p in per_pano.values()]
        entry: dict[str, Any] = {}
        for method in METHODS:
            entry[f"{method}_max_rel_error"] = max(r[method]["max_rel_error"] for r in rows)
            entry[f"{method}_mean_rel_error"] = float(np.mean([r[method]["mean_rel_error"] for r in rows]))
        keys = [f"{m}_{k}" for m in TIMED for k in ("s", "speedup")]
        for key in keys + ["exact_s", "matmul_weights_s", "matmul_first_use_speedup"]:
            entry[key] = float(np.median([r[key] for r in rows]))
        for method in TIMED:
            entry[f"{method}_gate_met"] = bool(entry[f"{method}_max_rel_error"] <= GATE)
        out[f"{w}x{h}"] = entry
    return out
