"""``probeless bench pano``: per-frame cost of the 360° video IBL pipeline (paper 002) and its fast paths
side by side with the brute-force references, in one run.

Input: the first frames of the shipped video (``../shared/data/video360/*.webm``, decoded before
anything is timed); if it is missing, a synthetic sky frame (said so in ``source``). Per frame, the
first one a warm-up left out of every statistic (shader compiles, weight caches):

* **ITMO**: the GPU paper operator as the ``itmo`` node runs it (upload, expand, read back the full
  frame as float16 and a 128x64 area average); every numpy operator on the same frame;
* **diffuse map 32x16** from the 128x64 frame: GPU (Algorithm 1) and the numpy weight matrix;
* **compositing** with the five default objects of ``pano_compositor``: environment + background
  upload, then :func:`probeless.pano.composite.render_view` (background view, object render,
  compositing) at 1280x720 mono and at 2 x 1182x1464 stereo. Output rates: ``*_fps`` = 1000 / the
  view's mean time (the display loop, the frame already uploaded), ``*_new_frame_fps`` with the upload,
  ``pipeline_mono_fps`` with GPU ITMO + GPU diffuse map + upload + mono view per frame.

Side by side on the first HDR frame (paper ITMO, numpy, full 1280x640), each against the reference a
competent engineer would use, doing the same work, with its quality gate checked in the same run
(:mod:`probeless.bench.pano_side`):

* diffuse map 64x32: the fast map (``diffuse_map_fast``: Algorithm 1 on a 256x128 area average by FFT
  along longitude, the brightest texels from the full frame), matmul and GPU from the full frame vs
  ``exact_diffuse`` (the exact FFT convolution of the full frame, all texels): ``diffuse_speedup`` =
  exact / fast (``diffuse_method`` names it), ``diffuse_matmul_speedup`` = exact / matmul,
  ``diffuse_gpu_speedup`` = exact / GPU pass (on llvmpipe that "GPU" is the CPU too), all warm; the
  weight / kernel builds and first-use times reported beside them; the gate ``diffuse_gate_met``: the
  fast map's max relative error <= 1 % on the frame and on the shared HDR panoramas;
* glossy at equal cost (roughness 0.1, 36 lookups each): ring sampling vs Monte Carlo and filtered
  importance sampling with the same lookup count, all against a converged Monte Carlo truth:
  ``glossy_equal_cost_error_ratio`` = the better equal-cost error / the ring's error.

The measurements are :mod:`probeless.bench.pano_frames` (per frame) and
:mod:`probeless.bench.pano_side` (side by side). Timings on a 2-core machine with Mesa llvmpipe (the
"GPU" passes run on the CPU) are far from a real GPU's. ``--json`` prints exactly one JSON object on
stdout; progress goes to stderr.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np

from probeless.bench.common import emit, log
from probeless.bench.pano_frames import (  # noqa: F401
    FOV_DEG,
    MONO,
    NUMPY_ITMOS,
    VIDEO,
    load_frames,
    make_renderer,
    stats,
    time_compositing,
    time_lighting,
)
from probeless.bench.pano_side import diffuse_side_by_side, glossy_side_by_side

FULL = {"frames": 12, "stereo_frames": 4, "hdr_panoramas": None, "glossy_dirs": 256, "mc_samples": 4096,
        "repeats": 5}
QUICK = {"frames": 3, "stereo_frames": 2, "hdr_panoramas": 2, "glossy_dirs": 48, "mc_samples": 1024, "repeats": 1}
GOALS = {"diffuse_speedup_min": 50.0, "diffuse_max_rel_error_max": 0.01}


def run_bench(quick: bool = False, show_progress: bool = True, video: Path = VIDEO) -> dict:
    """Every measurement of the module docstring; ``quick`` uses fewer frames, texels and samples."""
    from probeless.gl.context import create_context
    from probeless.pano.itmo import paper_itmo
    from probeless.progress import progress

    cfg, t_start = QUICK if quick else FULL, time.monotonic()
    frames, source = load_frames(cfg["frames"], video)
    if source.startswith("synthetic"):
        log(f"{video} is missing: timing a synthetic frame instead")
    ctx = create_context()
    renderer, n_objects = make_renderer(ctx)
    steps = 2 * len(frames) + 2
    with progress(steps, "bench pano", enabled=show_progress) as tick:
        light, hdrs, diffs = time_lighting(frames, ctx, tick)
        comp = time_compositing(renderer, frames, hdrs, diffs, min(cfg["stereo_frames"], len(frames)), tick)
        full = paper_itmo(frames[0].astype(np.float32) / np.float32(255.0))
        diffuse = diffuse_side_by_side(full, ctx, cfg["repeats"], cfg["hdr_panoramas"])
        tick()
        gloss = glossy_side_by_side(full, cfg["glossy_dirs"], cfg["mc_samples"])
        tick()
    renderer.release()
    timings = {k: stats(v) for k, v in {**light, **comp}.items()}
    return summarize(timings, diffuse, gloss, {
        "source": source, "frames": len(frames), "warmup_frames": 1, "objects": n_objects,
        "renderer": ctx.info["GL_RENDERER"], "quick": quick, "config": cfg, "mono_size": list(MONO),
        "stereo_eye_size": [1182, 1464], "fov_deg": FOV_DEG, "cpu_count": os.cpu_count(),
        "duration_s": time.monotonic() - t_start})


def summarize(timings: dict, diffuse: dict, gloss: dict, meta: dict) -> dict:
    """The result object: timings, rates, side-by-side figures, goals."""
    mean = {k: v["mean"] for k, v in timings.items()}
    rate = lambda ms: 1000.0 / ms if ms and np.isfinite(ms) and ms > 0 else float("nan")  # noqa: E731
    rates = {"mono_fps": rate(mean["mono_view"]), "stereo_fps": rate(mean.get("stereo_view", float("nan"))),
             "mono_new_frame_fps": rate(mean["mono_view"] + mean["upload"]),
             "stereo_new_frame_fps": rate(mean.get("stereo_view", float("nan")) + mean["upload"]),
             "pipeline_mono_fps": rate(mean["itmo_gpu_paper"] + mean["diffuse_gpu_32x16"] + mean["upload"]
                                       + mean["mono_view"])}
    goals_met = {"diffuse_speedup": bool(diffuse["diffuse_speedup"] >= GOALS["diffuse_speedup_min"]),
                 "diffuse_max_rel_error": bool(diffuse["diffuse_max_rel_error"] <= GOALS["diffuse_max_rel_error_max"])}
    return {**meta, "timings_ms": timings, "rates": rates, "diffuse": diffuse, "glossy": gloss,
            "diffuse_speedup": diffuse["diffuse_speedup"], "diffuse_gpu_speedup": diffuse["diffuse_gpu_speedup"],
            "diffuse_matmul_speedup": diffuse["diffuse_matmul_speedup"], "diffuse_method": diffuse["diffuse_method"],
            "diffuse_reference": diffuse["diffuse_reference"],
            "diffuse_max_rel_error": diffuse["diffuse_max_rel_error"],
            "diffuse_gate_met": diffuse["diffuse_gate_met"], "weights_build_ms": diffuse["weights_build_ms"],
            "glossy_equal_cost_error_ratio": gloss["glossy_equal_cost_error_ratio"],
            "glossy_equal_cost_reference": gloss["glossy_equal_cost_reference"],
            "glossy_rel_error": gloss["glossy_rel_error"],
            "goals": GOALS, "goals_met": goals_met, "meets_goals": all(goals_met.values())}


def print_table(r: dict) -> None:
    """The figures as a readable table on stdout."""
    print(f"probeless bench pano: {r['source']}; {r['objects']} objects; renderer {r['renderer']}")
    print(f"  {'stage [ms per frame]':30s} {'mean':>9s} {'p50':>9s} {'p95':>9s} {'n':>4s}")
    for name, s in r["timings_ms"].items():
        print(f"  {name:30s} {s['mean']:9.2f} {s['p50']:9.2f} {s['p95']:9.2f} {s['n']:4d}")
    print("  rates [frames/s]: " + ", ".join(f"{k} {v:.1f}" for k, v in r["rates"].items()))
    d, g = r["diffuse"], r["glossy"]
    print(f"  diffuse map {d['size'][0]}x{d['size'][1]} from the {d['frame'][0]}x{d['frame'][1]} frame vs "
          f"{d['diffuse_reference']}: exact {d['exact_ms']:.0f} ms, fast {d['fast_ms']:.1f} ms, matmul "
          f"{d['matmul_ms']:.1f} ms, GPU {d['gpu_ms']:.1f} ms (warm); builds: kernels {d['fast_kernels_build_ms']:.0f}"
          f" ms, weights {d['weights_build_ms']:.0f} ms; first use fast {d['fast_first_use_ms']:.0f} ms, matmul "
          f"{d['matmul_first_use_ms']:.0f} ms, GPU {d['gpu_first_use_ms']:.0f} ms")
    print(f"    diffuse_speedup {d['diffuse_speedup']:.1f}x ({d['diffuse_method']}; matmul "
          f"{d['diffuse_matmul_speedup']:.1f}x, GPU pass {d['diffuse_gpu_speedup']:.2f}x), goal "
          f">= {r['goals']['diffuse_speedup_min']:.0f}; max rel error {d['diffuse_max_rel_error']:.2e} over the frame"
          f" and {len(d['hdr_panoramas'])} HDR panoramas (gate <= {d['diffuse_gate']['max_rel_error_max']}: "
          f"{'met' if d['diffuse_gate_met'] else 'MISSED'})")
    print(f"  glossy r={g['roughness']}, {g['lookups']} lookups each: error mean ring "
          f"{g['ring_rel_error']['mean']:.2%}, "
          f"MC {g['mc_equal_rel_error']['mean']:.2%}, FIS {g['fis_equal_rel_error']['mean']:.2%} (truth noise "
          f"{g['truth_noise']['mean']:.2%}) -> glossy_equal_cost_error_ratio {g['glossy_equal_cost_error_ratio']:.2f}")
    print(f"  meets_goals={r['meets_goals']} {r['goals_met']}; {r['duration_s']:.0f} s")


def main(json_out: bool = False, quick: bool = False, *, show_progress: bool = True, video: Path = VIDEO) -> int:
    """Run the benchmark; a table, or exactly one JSON object with ``json_out``. 0 always (figures, not a test)."""
    from probeless.progress import stdout_to_stderr

    with stdout_to_stderr():
        result = run_bench(quick, show_progress, Path(video))
    emit(result, json_out, print_table)
    return 0


if __name__ == "__main__":
    from probeless.bench.common import module_main

    raise SystemExit(module_main(__spec__.name))
