"""Fast paths side by side with their brute-force references for ``probeless bench pano``.

On one HDR frame: the diffuse map (GPU and matmul) against the paper's brute-force construction
at 64x32, and glossy ring sampling against the Monte Carlo lobe integral (see :mod:`probeless.bench.pano`).
"""

from __future__ import annotations

import numpy as np

from probeless.bench.pano_frames import SMALL, best_ms, ms

SIDE_BY_SIDE, ROUGHNESS = (64, 32), 0.1


def bruteforce_time(hdr: np.ndarray, n_texels: int, repeats: int = 3) -> tuple[np.ndarray, np.ndarray, dict]:
    """(texel indices, their brute-force values, timing) of :func:`diffuse_map_bruteforce` at 64x32 on
    ``n_texels`` random texels (seed 0). Its per-frame setup (pixel directions and solid angles of the
    full frame) and its texel loop are timed apart, each the least of ``repeats`` runs after a warm-up,
    and the setup is counted once in the all-texel estimate."""
    from probeless.pano.diffuse import bruteforce_inputs, bruteforce_texels

    w, h = SIDE_BY_SIDE
    idx = np.sort(np.random.default_rng(0).choice(w * h, n_texels, replace=False))
    inputs = bruteforce_inputs(hdr)  # warm-up
    inputs, t_setup = best_ms(lambda: bruteforce_inputs(hdr), repeats)
    brute, t_sub = best_ms(lambda: bruteforce_texels(inputs, SIDE_BY_SIDE, idx), repeats)
    per_texel = t_sub / n_texels
    return idx, brute, {"bruteforce_ms": t_setup + per_texel * w * h, "bruteforce_subset_ms": t_sub,
                        "bruteforce_setup_ms": t_setup, "bruteforce_ms_per_texel": per_texel,
                        "bruteforce_texels": int(n_texels), "all_texels": w * h,
                        "bruteforce_extrapolated": n_texels < w * h,
                        "bruteforce_extrapolation": "setup + subset texel loop / subset texels * all texels "
                                                    "(random texels, seed 0; each the least of "
                                                    f"{max(1, repeats)} runs)"}


def diffuse_side_by_side(hdr: np.ndarray, ctx, n_texels: int, repeats: int) -> dict:
    """Diffuse map 64x32 from the full frame: matmul and GPU vs the brute force (:func:`bruteforce_time`).

    ``diffuse_speedup`` is brute / matmul (both numpy on the CPU: the algorithmic gain alone);
    ``diffuse_gpu_speedup`` brute / the GPU pass; ``diffuse_max_rel_error`` the worse of the two.
    """
    from probeless.pano.diffuse import diffuse_map
    from probeless.pano.gpu_diffuse import GpuDiffuse

    gpu = GpuDiffuse(ctx, SIDE_BY_SIDE, SMALL)
    gpu.apply(hdr), diffuse_map(hdr, SIDE_BY_SIDE)  # warm-up: shader compile, weight matrix
    fast_gpu, t_gpu = best_ms(lambda: gpu.apply(hdr), repeats)
    fast_mm, t_mm = best_ms(lambda: diffuse_map(hdr, SIDE_BY_SIDE), repeats)
    gpu.release()
    idx, brute, timing = bruteforce_time(hdr, n_texels, max(3, repeats))

    def err(fast):
        ref = brute.astype(np.float64)
        rel = np.abs(fast.reshape(-1, 3)[idx] - ref) / np.maximum(ref, 1e-6 * ref.max())
        return float(rel.max()), float(rel.mean())

    (e_gpu, m_gpu), (e_mm, m_mm) = err(fast_gpu), err(fast_mm)
    t_brute = timing["bruteforce_ms"]
    return {"size": list(SIDE_BY_SIDE), "frame": [hdr.shape[1], hdr.shape[0]], "input_size": list(SMALL),
            "gpu_ms": t_gpu, "matmul_ms": t_mm, **timing,
            "diffuse_speedup": t_brute / t_mm, "diffuse_gpu_speedup": t_brute / t_gpu,
            "diffuse_max_rel_error": max(e_gpu, e_mm), "diffuse_matmul_max_rel_error": e_mm,
            "diffuse_matmul_mean_rel_error": m_mm, "diffuse_gpu_max_rel_error": e_gpu,
            "diffuse_gpu_mean_rel_error": m_gpu, "error_texels": "the brute-force subset's texels, every channel"}


def glossy_side_by_side(hdr: np.ndarray, n_dirs: int, mc_samples: int) -> dict:
    """Ring sampling vs Monte Carlo at roughness 0.1 on ``n_dirs`` random directions."""
    from probeless.pano import glossy
    from probeless.pano.glossy_eval import evaluate_one, random_directions

    levels, t_mips = ms(glossy.mip_levels, hdr)
    r = evaluate_one(hdr, levels, random_directions(n_dirs, 0), ROUGHNESS, mc_samples, 0, (0.0,))
    return {"roughness": ROUGHNESS, "dirs": int(n_dirs), "mc_samples": int(mc_samples), "ring_samples": 36,
            "mip_chain_ms": t_mips, "ring_ms_per_dir": r["ms_per_dir_ring"], "mc_ms_per_dir": r["ms_per_dir_mc"],
            "glossy_speedup": r["glossy_speedup"], "glossy_rel_error": r["ring"]["mean"],
            "glossy_max_rel_error": r["ring"]["max"], "mc_noise": r["mc_noise"]["mean"],
            "error": "|Y(ring) - Y(MC)| / mean Y(MC) per direction (mean, max); MC = mean of 2 seeds"}
