"""``probeless bench coarse``: per-frame cost of the coarse room model's stages at a 2048x2048 atlas.

Scene: ``launch/scenes/partition_room.yaml`` (non-convex: the occlusion pass runs every frame).
The first ``--frames`` fisheye frames of the rig (15 Hz, consecutive, in the texturer's runtime
model) are rendered first, outside every timed region. Then, per frame, as ``run_coarse`` and the
nodes do it (Δ of frame k against the atlas after frame k-1):

* **read-back**: :meth:`AtlasTexturer.read_packed`, the RGBA8 atlas the texturer publishes;
* **brightness**, side by side on the same frame and atlas, against one reference, the same estimate
  as a compiled serial loop over all core texels (:func:`probeless.bench.coarse_numba.estimate_delta_numba`,
  numba ``@njit``; ``brightness_reference`` names it):

  - ``brightness_speedup`` (the headline) = reference / **what the node runs**: :func:`node_estimate`, the
    ``brightness_estimator`` node's own call of :func:`estimate_delta` with its default params
    (:data:`NODE_PARAMS`: 65536 texels drawn with seed 0, its dark / saturated thresholds and occlusion
    offset, the rgba8 atlas's alpha as the observed mask). Its quality gate, in the same run: the sample's
    Δ differs from the all-texel Δ by at most ``SAMPLE_GATE_CODES`` (the node's deadband, 0.5 codes: below
    it a Δ counts as no change) in every channel and frame (``sampled_error_*``, 0..255 units);
  - ``brightness_full_speedup`` = reference / the vectorised estimate over all core texels, with the gate
    that both give the same Δ from the same texel count (``agreement_gate_met``);
  - ``sampled_speedup_vs_all`` = all-texel vectorised / sampled time;
* **occlusion mask** and **texture update** on the GPU (``CoarseModel.step``'s own timings, each
  ending with ``ctx.finish()``); inpainting runs inside ``step`` with the default
  :class:`IncrementalInpainter` gating, and step time minus those two passes is its amortised cost;
* after the frames, :func:`inpaint_atlas` at scale 0.25 on the final atlas (``INPAINT_REPS`` runs).

Frame 0 is a warm-up (first use of the GL programs, the first inpainting, no previous atlas for Δ)
and is left out of every per-frame statistic. Timings on a shared 2-core machine with Mesa
llvmpipe (the GPU passes run on the CPU) are noisy and far from a real GPU's.

``--json`` prints exactly one JSON object on stdout; progress goes to stderr.
"""

from __future__ import annotations

import argparse
import itertools
import os
import time
from pathlib import Path

import numpy as np

from probeless.bench.common import emit, log, rounded
from probeless.paths import REPO_ROOT
from probeless.progress import progress, stdout_to_stderr

SCENE = REPO_ROOT / "launch" / "scenes" / "partition_room.yaml"
GOALS = {"brightness_speedup_min": 100.0}
FRAMES, QUICK_FRAMES = 45, 6
# brightness_estimator's defaults (nodes/coarse/brightness.py Params; a test holds them equal)
NODE_PARAMS = {"samples": 65536, "seed": 0, "dark": 0.01, "saturated": 0.98, "occlusion_offset_texels": 1.5}
SAMPLE_TEXELS = NODE_PARAMS["samples"]
SAMPLE_GATE_CODES = 0.5  # max |Δ sampled - Δ all texels| [0..255 units]: the node's deadband (DEADBAND * 255)
BRIGHTNESS_REFERENCE = "estimate_delta_numba: the same estimate as a compiled serial loop (numba @njit), same texels"
AGREEMENT_GATE = 1e-3  # max |Δ numba - Δ vectorised| [0..255 units]: float32 vs float64 sums
INPAINT_SCALE = 0.25
INPAINT_REPS = 3
WARMUP_FRAMES = 1


def stats(values: list[float]) -> dict:
    """mean, p50, p95 and count of per-frame timings [ms]."""
    a = np.asarray(values, np.float64)
    if a.size == 0:
        return {"mean": float("nan"), "p50": float("nan"), "p95": float("nan"), "n": 0}
    return {"mean": float(a.mean()), "p50": float(np.median(a)), "p95": float(np.percentile(a, 95)), "n": int(a.size)}


def _ms(fn, *args, **kwargs):
    t0 = time.perf_counter()
    out = fn(*args, **kwargs)
    return out, (time.perf_counter() - t0) * 1e3


def node_estimate(packed: np.ndarray, texmap, image: np.ndarray, camera, world_from_fisheye: np.ndarray,
                  fov_deg: float, layout, sample) -> tuple[np.ndarray, int]:
    """(Δ, texels used) exactly as the ``brightness_estimator`` node computes it from its rgba8 ``atlas``
    (``BrightnessEstimator._resolve`` with :data:`NODE_PARAMS`), over ``sample``."""
    from probeless.coarse.brightness import estimate_delta

    p = NODE_PARAMS
    return estimate_delta(packed[..., :3], packed[..., 3], texmap, image, camera, world_from_fisheye, fov_deg,
                          layout.floorplan, sample_idx=sample, dark=p["dark"], saturated=p["saturated"],
                          offset_m=p["occlusion_offset_texels"] / layout.texels_per_m)


def brightness_frame(model, source, frame, all_s, sample_s) -> dict:
    """Every brightness estimate of one frame against the current atlas, timed, plus the read-back."""
    from probeless.bench.coarse_numba import estimate_delta_numba

    packed, t_read = _ms(model.gpu.read_packed)
    geo = (model.texmap, frame.image, source.model, frame.world_from_fisheye, model.config.fov_deg, model.layout)
    p = NODE_PARAMS
    settings = {"dark": p["dark"], "saturated": p["saturated"],
                "offset_m": p["occlusion_offset_texels"] / model.layout.texels_per_m}
    (d_all, n_all), t_all = _ms(node_estimate, packed, *geo, all_s)
    (d_smp, _), t_smp = _ms(node_estimate, packed, *geo, sample_s)
    args = (packed[..., :3], packed[..., 3], model.texmap, frame.image, source.model, frame.world_from_fisheye,
            model.config.fov_deg, model.layout.floorplan)
    (d_nb, n_nb), t_nb = _ms(estimate_delta_numba, *args, sample_idx=all_s, **settings)
    return {"readback": t_read, "all": t_all, "sampled": t_smp, "numba_all": t_nb, "delta": d_smp,
            "texels_all": n_all, "sample_error": float(np.abs(d_smp.astype(np.float64) - d_all).max() * 255.0),
            "numba_diff": float(np.abs(d_nb.astype(np.float64) - d_all).max() * 255.0),
            "numba_texels_equal": n_nb == n_all}


def render(source, n: int, show_progress: bool) -> list:
    """The first ``n`` frames of ``source``, rendered before anything is timed."""
    rendered = []
    with progress(n, "rendering fisheye frames", enabled=show_progress) as tick:
        for frame in itertools.islice(source.frames, n):
            rendered.append(frame)
            tick()
    return rendered


def measure(model, source, rendered: list, samples: tuple, show_progress: bool) -> tuple[list, list[float]]:
    """(brightness records per frame, None for frame 0; ``model.step`` times [ms]) over ``rendered``."""
    per, step_ms = [], []
    lay = model.layout
    with progress(len(rendered), f"coarse model, {lay.width}x{lay.height} atlas", enabled=show_progress) as tick:
        for k, frame in enumerate(rendered):
            rec = brightness_frame(model, source, frame, *samples)  # frame 0: compiles the reference, not used
            rec = rec if k > 0 else None
            delta = rec["delta"] if rec else np.zeros(3, np.float32)
            _, t_step = _ms(model.step, frame.image, source.model, frame.world_from_fisheye, delta, frame.t_s)
            step_ms.append(t_step)
            per.append(rec)
            tick()
    return per, step_ms


def brightness_summary(b: list[dict], timings: dict, samples: tuple) -> dict:
    """Ratios against the named reference, estimate agreement and sampling error (the two gates) of ``b``."""
    all_s, sample_s = samples

    def col(key: str) -> list:
        return [r[key] for r in b]

    errors, t = col("sample_error"), {k: timings[f"brightness_{k}"]["mean"] for k in ("all", "sampled", "numba_all")}
    agree = max(col("numba_diff"))
    return {
        "all_texels": len(all_s.index), "sample_texels": len(sample_s.index),
        "brightness_reference": BRIGHTNESS_REFERENCE, "reference_texels": len(all_s.index),
        "brightness_speedup": t["numba_all"] / t["sampled"],
        "speedup_definition": "brightness_numba_all.mean / brightness_sampled.mean: the reference over all core "
                              "texels against what the brightness_estimator node runs (node_estimate: "
                              f"{len(sample_s.index)} sampled texels, the node's params), same frames",
        "node_params": dict(NODE_PARAMS),
        "sample_gate": {"sampled_error_max_max": SAMPLE_GATE_CODES,
                        "why": "the node's deadband: a Δ below it in every channel counts as no change"},
        "sample_gate_met": bool(max(errors) <= SAMPLE_GATE_CODES),
        "brightness_full_speedup": t["numba_all"] / t["all"],
        "full_speedup_definition": "brightness_numba_all.mean / brightness_all.mean (same texels, same frames)",
        "numba_vs_vectorised_max_abs_diff": agree,
        "numba_vs_vectorised_texels_equal": all(col("numba_texels_equal")),
        "agreement_gate": {"max_abs_diff_max": AGREEMENT_GATE, "texels_equal": True},
        "agreement_gate_met": bool(agree <= AGREEMENT_GATE and all(col("numba_texels_equal"))),
        "sampled_reference": "estimate_delta over all core texels (vectorised), same frame",
        "sampled_speedup_vs_all": t["all"] / t["sampled"],
        "sampled_speedup_vs_numba_all": t["numba_all"] / t["sampled"],
        "sampled_error_max": max(errors), "sampled_error_mean": float(np.mean(errors)),
        "texels_used_mean": float(np.mean(col("texels_all"))),
        "units": "Δ differences in 0..255 camera units, max over channels and frames"}


def run_bench(*, atlas_size: int = 2048, frames: int = FRAMES, scene: str | Path = SCENE,
              sample_texels: int = SAMPLE_TEXELS, show_progress: bool = True) -> dict:
    """Render ``frames`` fisheye frames, then time every stage per frame (module docstring)."""
    from probeless.coarse.brightness import draw_sample
    from probeless.coarse.frames import scene_source
    from probeless.coarse.inpaint import inpaint_atlas
    from probeless.coarse.model import CoarseConfig, CoarseModel
    from probeless.errors import SchemaError

    if frames < WARMUP_FRAMES + 1 or sample_texels < 1 or atlas_size < 16:
        raise SchemaError(f"bench coarse: need --frames >= {WARMUP_FRAMES + 1}, sample_texels >= 1 and "
                          f"--atlas-size >= 16, got {frames}, {sample_texels}, {atlas_size}")
    t_start = time.monotonic()
    source = scene_source(scene)
    rendered = render(source, min(frames, source.count), show_progress)
    render_s = time.monotonic() - t_start
    log(f"{len(rendered)} frames rendered in {render_s:.1f} s; building the {atlas_size}^2 atlas")
    config = CoarseConfig(atlas_size=atlas_size, fov_deg=source.texture_fov_deg, inpaint_scale=INPAINT_SCALE)
    model = CoarseModel(source.floorplan, source.ceiling_height, config, ctx=source.rig.renderer.ctx)
    all_s = draw_sample(model.texmap)
    samples = (all_s, draw_sample(model.texmap, sample_texels, seed=NODE_PARAMS["seed"]))
    per, step_ms = measure(model, source, rendered, samples, show_progress)
    rgb, seen = model.gpu.read_atlas()
    observed = seen >= 0
    full = []
    for _ in range(INPAINT_REPS):
        (_, inpainted), t = _ms(inpaint_atlas, rgb, observed, model.layout, model.texmap, scale=INPAINT_SCALE)
        full.append(t)
    model.release()

    w, tm, b = WARMUP_FRAMES, model.timings_ms, per[WARMUP_FRAMES:]
    rest = [s - o - t for s, o, t in zip(step_ms[w:], tm["occlusion"][w:], tm["texture"][w:])]
    timings = {"occlusion": stats(tm["occlusion"][w:]), "texture_update": stats(tm["texture"][w:]),
               **{f"brightness_{k}": stats([r[k] for r in b]) for k in ("all", "sampled", "numba_all")},
               "inpaint_amortised": stats(rest), "inpaint_full": stats(full),
               "readback_rgba8": stats([r["readback"] for r in b])}
    brightness = brightness_summary(b, timings, samples)
    goal = GOALS["brightness_speedup_min"]
    goals_met = {"brightness_speedup": bool(brightness["brightness_speedup"] >= goal),
                 "sample_gate": brightness["sample_gate_met"], "agreement_gate": brightness["agreement_gate_met"]}
    lay = model.layout
    result = {
        "scene": str(scene), "frames": len(rendered), "warmup_frames": w,
        "fisheye": [source.model.width, source.model.height],
        "atlas": {"width": lay.width, "height": lay.height, "texels_per_m": lay.texels_per_m,
                  "core_texels": len(all_s.index), "observed_at_end": int(observed.sum()),
                  "inpainted_at_end": int(inpainted.sum())},
        "timings_ms": timings, "brightness": brightness,
        "inpaint": {"scale": INPAINT_SCALE, "full_runs": INPAINT_REPS, "incremental_runs": model.inpainter.runs,
                    "first_run_ms": tm["inpaint"][0] if tm["inpaint"] else float("nan"),
                    # each incremental run as CoarseModel times it: float atlas read-back, inpaint, write-back
                    "incremental_run_ms": list(tm["inpaint"]),
                    "min_new_texels": config.inpaint_min_new_texels, "inpaint_every": config.inpaint_every,
                    "amortised": "CoarseModel.step time - occlusion - texture update: gating check, atlas "
                                 "read-back, inpainting and write-back when due, per frame"},
        "goals": GOALS, "goals_met": goals_met, "meets_goals": all(goals_met.values()),
        "render_s": render_s, "duration_s": time.monotonic() - t_start, "cpu_count": os.cpu_count()}
    return rounded(result)


def print_table(r: dict) -> None:
    """The figures as a readable table on stdout."""
    a, b = r["atlas"], r["brightness"]
    print(f"probeless bench coarse: {Path(r['scene']).name}, {a['width']}x{a['height']} atlas "
          f"({a['texels_per_m']:.0f} texels/m, {a['core_texels']} core texels), {r['frames']} frames "
          f"({r['warmup_frames']} warm-up), fisheye {r['fisheye'][0]}x{r['fisheye'][1]}")
    print(f"  {'stage [ms per frame]':36s} {'mean':>9s} {'p50':>9s} {'p95':>9s} {'n':>4s}")
    for name, s in r["timings_ms"].items():
        cells = " ".join(f"{s[k]:9.2f}" if s[k] is not None else f"{'-':>9s}" for k in ("mean", "p50", "p95"))
        print(f"  {name:36s} {cells} {s['n']:4d}")
    t = r["timings_ms"]
    print(f"  brightness as the node runs it ({b['sample_texels']} sampled texels) "
          f"{t['brightness_sampled']['mean']:.1f} ms vs the compiled serial loop (numba) over all {b['all_texels']} "
          f"core texels {t['brightness_numba_all']['mean']:.1f} ms -> brightness_speedup "
          f"{b['brightness_speedup']:.2f}x (goal >= {r['goals']['brightness_speedup_min']:.0f}x); sample error max "
          f"{b['sampled_error_max']:.4f}, mean {b['sampled_error_mean']:.4f} codes (gate <= "
          f"{b['sample_gate']['sampled_error_max_max']}: {b['sample_gate_met']})")
    print(f"  all core texels vectorised {t['brightness_all']['mean']:.1f} ms -> brightness_full_speedup "
          f"{b['brightness_full_speedup']:.2f}x; agreement |ΔΔ| max {b['numba_vs_vectorised_max_abs_diff']:.2e} "
          f"(gate met: {b['agreement_gate_met']}); sampled {b['sampled_speedup_vs_all']:.1f}x faster than all")
    print(f"  inpainting: {r['inpaint']['incremental_runs']} incremental run(s), first "
          f"{r['inpaint']['first_run_ms']:.0f} ms; meets_goals={r['meets_goals']} {r['goals_met']}; "
          f"{r['duration_s']:.0f} s "
          f"(rendering {r['render_s']:.0f} s)")


def main(json_out: bool = False, quick: bool = False, *, atlas_size: int = 2048, frames: int | None = None,
         scene: str | Path | None = None, sample_texels: int = SAMPLE_TEXELS, show_progress: bool = True) -> int:
    """Run the benchmark; a table, or exactly one JSON object with ``json_out``. 0 always (figures, not a test).
    None for ``frames``, ``scene``: the defaults (``quick``: fewer frames)."""
    scene = scene or SCENE
    frames = frames or (QUICK_FRAMES if quick else FRAMES)
    with stdout_to_stderr():
        result = run_bench(atlas_size=atlas_size, frames=frames, scene=scene, sample_texels=sample_texels,
                           show_progress=show_progress)
    emit(result, json_out, print_table)
    return 0


def add_arguments(ap: argparse.ArgumentParser) -> None:
    """The coarse benchmark's own options (besides ``--json`` / ``--quick``)."""
    ap.add_argument("--atlas-size", type=int, default=2048, help="atlas side [texels] (default 2048)")
    ap.add_argument("--frames", type=int, help=f"fisheye frames, the first a warm-up (default {FRAMES}, "
                                               f"--quick {QUICK_FRAMES})")
    ap.add_argument("--scene", help="scene file (default launch/scenes/partition_room.yaml)")


def run(ns: argparse.Namespace) -> int:
    return main(ns.json, ns.quick, atlas_size=ns.atlas_size, frames=ns.frames, scene=ns.scene)


if __name__ == "__main__":
    from probeless.bench.common import module_main

    raise SystemExit(module_main(__spec__.name))
