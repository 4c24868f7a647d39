"""Fast paths side by side with the references a competent engineer would use, for ``probeless bench pano``.

* **Diffuse map 64x32**: the fast map (:func:`~probeless.pano.diffuse_fast.diffuse_map_fast`: Algorithm 1
  on a 256x128 area average by FFT along longitude, the 64 brightest texels from the full frame; the
  headline ``diffuse_speedup``), the numpy weight-matrix map (Algorithm 1 on 128x64,
  ``diffuse_matmul_speedup``) and the GPU pass against :func:`~probeless.pano.diffuse_eval.exact_diffuse`
  (the exact convolution of the full-resolution frame over every texel, by FFT along each output row,
  numpy float64): same frame in, same 64x32 map out, all timed warm (the least of ``repeats`` runs) and
  scored against it on every texel. The one-off costs are on the clock too: ``weights_build_ms`` (the
  matmul's weight matrix, built from scratch), ``fast_kernels_build_ms`` (the fast map's kernel spectra)
  and ``*_first_use_ms`` (the first map of a fresh process: weight / kernel build or shader compile
  included). The gate (``diffuse_gate_met``, on the headline method): max relative error <=
  ``DIFFUSE_GATE`` on the frame and on every HDR panorama of ``../shared/data/hdri`` (skipped, and said
  so, when that folder is absent); every method's worst error is reported beside it.
* **Glossy, equal cost** (roughness 0.1): ring sampling (36 trilinear lookups) against Monte Carlo
  and filtered importance sampling with the same 36 lookups, all scored against a converged Monte
  Carlo truth (:func:`probeless.pano.glossy_eval.evaluate_one`).
"""

from __future__ import annotations

import numpy as np

from probeless.bench.pano_frames import SMALL, best_ms, ms
from probeless.pano.diffuse_eval import GATE as DIFFUSE_GATE
from probeless.pano.diffuse_eval import SPEEDUP_REFERENCE as DIFFUSE_REFERENCE

SIDE_BY_SIDE, ROUGHNESS = (64, 32), 0.1


def first_use_ms(hdr: np.ndarray, ctx) -> dict:
    """One-off costs [ms]: the weight matrix built from scratch, the first matmul map (build included)
    and a fresh GPU pass's construction + first map (shader compile, textures)."""
    from probeless.pano.diffuse import diffuse_map, diffuse_weights
    from probeless.pano.diffuse_eval import matmul_in_size
    from probeless.pano.diffuse_fast import IN_SIZE, diffuse_map_fast, kernels
    from probeless.pano.gpu_diffuse import GpuDiffuse

    diffuse_weights.cache_clear()
    _, t_build = ms(diffuse_weights, SIDE_BY_SIDE, matmul_in_size(SIDE_BY_SIDE))
    diffuse_weights.cache_clear()
    _, t_mm_first = ms(diffuse_map, hdr, SIDE_BY_SIDE)
    kernels.cache_clear()
    _, t_kernels = ms(kernels, SIDE_BY_SIDE, IN_SIZE)
    kernels.cache_clear()
    _, t_fast_first = ms(diffuse_map_fast, hdr, SIDE_BY_SIDE)

    def gpu_first():
        gpu = GpuDiffuse(ctx, SIDE_BY_SIDE, SMALL)
        gpu.apply(hdr)
        return gpu

    gpu, t_gpu_first = ms(gpu_first)
    gpu.release()
    return {"weights_build_ms": t_build, "matmul_first_use_ms": t_mm_first, "gpu_first_use_ms": t_gpu_first,
            "fast_kernels_build_ms": t_kernels, "fast_first_use_ms": t_fast_first}


def diffuse_errors(hdr: np.ndarray, gpu, exact: np.ndarray | None = None) -> dict:
    """Max and mean relative error of the fast, matmul and GPU maps of ``hdr`` against the exact map (every
    texel)."""
    from probeless.pano.diffuse import diffuse_map
    from probeless.pano.diffuse_eval import exact_diffuse, rel_errors
    from probeless.pano.diffuse_fast import diffuse_map_fast

    exact = exact_diffuse(hdr, SIDE_BY_SIDE) if exact is None else exact
    return {"fast": rel_errors(diffuse_map_fast(hdr, SIDE_BY_SIDE), exact),
            "matmul": rel_errors(diffuse_map(hdr, SIDE_BY_SIDE), exact), "gpu": rel_errors(gpu.apply(hdr), exact)}


def hdr_panorama_errors(gpu, max_panoramas: int | None = None) -> dict:
    """``diffuse_errors`` on each HDR panorama of the shared data (all, or the first ``max_panoramas``)."""
    from probeless.pano.sources import HDRI_DIR, read_panorama

    paths = sorted(HDRI_DIR.glob("*.hdr")) if HDRI_DIR.is_dir() else []
    if not paths:
        return {"panoramas": {}, "skipped": f"no HDR panoramas in {HDRI_DIR}"}
    return {"panoramas": {p.name: diffuse_errors(read_panorama(str(p)), gpu) for p in paths[:max_panoramas]},
            "skipped": None}


def diffuse_side_by_side(hdr: np.ndarray, ctx, repeats: int, max_panoramas: int | None = None) -> dict:
    """Diffuse map 64x32 of the full frame: fast, matmul and GPU vs :data:`DIFFUSE_REFERENCE` (module doc)."""
    from probeless.pano.diffuse import diffuse_map
    from probeless.pano.diffuse_eval import exact_diffuse
    from probeless.pano.diffuse_fast import HOT_TEXELS, IN_SIZE, diffuse_map_fast
    from probeless.pano.gpu_diffuse import GpuDiffuse

    once = first_use_ms(hdr, ctx)
    gpu = GpuDiffuse(ctx, SIDE_BY_SIDE, SMALL)
    gpu.apply(hdr)  # warm
    exact, t_exact = best_ms(lambda: exact_diffuse(hdr, SIDE_BY_SIDE), repeats)
    fast, t_fast = best_ms(lambda: diffuse_map_fast(hdr, SIDE_BY_SIDE), repeats)
    fast_mm, t_mm = best_ms(lambda: diffuse_map(hdr, SIDE_BY_SIDE), repeats)
    fast_gpu, t_gpu = best_ms(lambda: gpu.apply(hdr), repeats)
    frame = diffuse_errors(hdr, gpu, exact)
    hdrs = hdr_panorama_errors(gpu, max_panoramas)
    gpu.release()
    worst = {m: max([frame[m]["max_rel_error"]] + [p[m]["max_rel_error"] for p in hdrs["panoramas"].values()])
             for m in frame}
    return {"size": list(SIDE_BY_SIDE), "frame": [hdr.shape[1], hdr.shape[0]], "input_size": list(SMALL),
            "texels": SIDE_BY_SIDE[0] * SIDE_BY_SIDE[1], "output_shapes": {
                "exact": list(exact.shape), "fast": list(fast.shape), "matmul": list(fast_mm.shape),
                "gpu": list(fast_gpu.shape)},
            "diffuse_reference": DIFFUSE_REFERENCE,
            "diffuse_method": f"diffuse_map_fast: Algorithm 1 on a {IN_SIZE[0]}x{IN_SIZE[1]} area average by FFT "
                              f"along longitude + the {HOT_TEXELS} brightest texels from the full frame",
            "exact_ms": t_exact, "fast_ms": t_fast, "matmul_ms": t_mm, "gpu_ms": t_gpu,
            **once, "timing": f"warm, the least of {max(1, repeats)} runs; first use: fresh weights / kernels / "
                              "GPU pass",
            "diffuse_speedup": t_exact / t_fast, "diffuse_matmul_speedup": t_exact / t_mm,
            "diffuse_gpu_speedup": t_exact / t_gpu,
            "diffuse_first_use_speedup": t_exact / once["fast_first_use_ms"],
            "diffuse_matmul_first_use_speedup": t_exact / once["matmul_first_use_ms"],
            "frame_errors": frame, "hdr_panoramas": hdrs["panoramas"], "hdr_panoramas_skipped": hdrs["skipped"],
            "diffuse_max_rel_error": worst["fast"], "max_rel_error_by_method": worst,
            "diffuse_gate": {"max_rel_error_max": DIFFUSE_GATE, "method": "fast"},
            "diffuse_gate_met": bool(worst["fast"] <= DIFFUSE_GATE),
            "error": "|fast - exact| / exact over every texel and channel (floor 1e-6 of the max), the video "
                     "frame and each HDR panorama"}


def glossy_side_by_side(hdr: np.ndarray, n_dirs: int, mc_samples: int) -> dict:
    """Ring sampling vs MC and FIS with the same lookups, at roughness 0.1 on ``n_dirs`` random directions."""
    from probeless.pano import glossy
    from probeless.pano.glossy_eval import evaluate_one, random_directions

    levels, t_mips = ms(glossy.mip_levels, hdr)
    r = evaluate_one(hdr, levels, random_directions(n_dirs, 0), ROUGHNESS, mc_samples, 0, (0.0,))
    return {"roughness": ROUGHNESS, "dirs": int(n_dirs), "truth_mc_samples": int(mc_samples),
            "lookups": r["lookups"], "mip_chain_ms": t_mips, "ring_ms_per_dir": r["ms_per_dir_ring"],
            "mc_equal_ms_per_dir": r["ms_per_dir_mc_equal"], "fis_equal_ms_per_dir": r["ms_per_dir_fis_equal"],
            "ring_rel_error": r["ring"], "mc_equal_rel_error": r["mc_equal"], "fis_equal_rel_error": r["fis_equal"],
            "truth_noise": r["mc_noise"], "glossy_rel_error": r["ring"]["mean"],
            "glossy_equal_cost_error_ratio": r["glossy_equal_cost_error_ratio"],
            "glossy_equal_cost_reference": r["glossy_equal_cost_reference"],
            "truth": f"mean of two {mc_samples}-sample importance-sampled Monte Carlo estimates (seeds 0, 1)",
            "error": "|Y(est) - Y(truth)| / mean Y(truth) per direction (mean, max)"}
