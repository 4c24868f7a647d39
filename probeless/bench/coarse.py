"""``probeless bench coarse``: per-frame cost of the coarse room model's stages at a 2048x2048 atlas.

Scene: ``launch/scenes/partition_room.yaml`` (non-convex: the occlusion pass runs every frame).
The first ``--frames`` fisheye frames of the rig (15 Hz, consecutive, in the texturer's runtime
model) are rendered first, outside every timed region. Then, per frame, as ``run_coarse`` and the
nodes do it (Δ of frame k against the atlas after frame k-1):

* **read-back**: :meth:`AtlasTexturer.read_packed`, the RGBA8 atlas the texturer publishes;
* **brightness**, side by side on the same frame and atlas: vectorised :func:`estimate_delta` on
  all core texels and on a 65536-texel sample (the node's default), and the paper-style serial
  per-texel loop :func:`estimate_delta_serial` on ``--serial-texels`` K texels, extrapolated per
  texel to all core texels (a full serial run takes ~10 s per frame at 2048^2). The K texels are
  every n-th core texel (evenly strided), not the first K: those are one strip of wall just under
  the ceiling, whose share of observed texels (the texels the loop does real work for) is not the
  atlas's. The vectorised estimate on the same K texels checks that both compute the same Δ;
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
SERIAL_TEXELS, QUICK_SERIAL_TEXELS = 20000, 2000
SAMPLE_TEXELS = 65536
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


def strided_subset(index: np.ndarray, k: int) -> np.ndarray:
    """``k`` (or all, if fewer) flat texel indices spread evenly over ``index``: every n-th one."""
    step = max(1, len(index) // max(1, k))
    return index[::step][:k]


def brightness_frame(model, source, frame, all_s, sample_s, serial_s, *, full_serial: bool = False) -> dict:
    """Every brightness estimate of one frame against the current atlas, timed, plus the read-back;
    ``full_serial`` also times the serial loop over all texels (to check the extrapolation)."""
    from probeless.coarse.brightness import estimate_delta, estimate_delta_serial

    packed, t_read = _ms(model.gpu.read_packed)
    args = (packed[..., :3], packed[..., 3] > 0, model.texmap, frame.image, source.model, frame.world_from_fisheye,
            model.config.fov_deg, source.floorplan)
    (d_all, n_all), t_all = _ms(estimate_delta, *args, sample_idx=all_s)
    (d_smp, _), t_smp = _ms(estimate_delta, *args, sample_idx=sample_s)
    (d_ser, n_ser), t_ser = _ms(estimate_delta_serial, *args, sample_idx=serial_s)
    d_sub, n_sub = estimate_delta(*args, sample_idx=serial_s)
    return {"readback": t_read, "all": t_all, "sampled": t_smp, "serial_subset": t_ser,
            "serial_all": t_ser * len(all_s.index) / len(serial_s.index), "delta": d_smp, "texels_all": n_all,
            "sample_error": float(np.abs(d_smp.astype(np.float64) - d_all).max() * 255.0),
            "serial_diff": float(np.abs(d_ser.astype(np.float64) - d_sub).max() * 255.0),
            "serial_texels_equal": n_ser == n_sub,
            "serial_all_measured": _ms(estimate_delta_serial, *args, sample_idx=all_s)[1] if full_serial else None}


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
            last = k == len(rendered) - 1
            rec = brightness_frame(model, source, frame, *samples, full_serial=last) if k > 0 else None
            delta = rec["delta"] if rec else np.zeros(3, np.float32)
            _, t_step = _ms(model.step, frame.image, source.model, frame.world_from_fisheye, delta, frame.t_s)
            step_ms.append(t_step)
            per.append(rec)
            tick()
    return per, step_ms


def brightness_summary(b: list[dict], timings: dict, samples: tuple) -> dict:
    """Speedups, extrapolation check and estimate agreement of the measured frames' records ``b``."""
    all_s, sample_s, serial_s = samples

    def col(key: str) -> list:
        return [r[key] for r in b]

    serial_all = timings["brightness_serial_all_extrapolated"]["mean"]
    errors, last = col("sample_error"), b[-1]
    return {
        "all_texels": len(all_s.index), "sample_texels": len(sample_s.index), "serial_texels": len(serial_s.index),
        "serial_subset": "every n-th core texel (evenly strided), n = all_texels // serial_texels",
        "serial_extrapolated": True,
        "serial_extrapolation": "serial time on serial_texels texels * all_texels / serial_texels",
        "serial_ms_per_texel": timings["brightness_serial_subset"]["mean"] / len(serial_s.index),
        # the last frame's serial loop over all texels, measured, against its extrapolation and vectorised time
        "last_frame_serial_all_measured_ms": last["serial_all_measured"],
        "last_frame_serial_all_extrapolated_ms": last["serial_all"], "last_frame_vectorised_all_ms": last["all"],
        "last_frame_speedup_measured": last["serial_all_measured"] / last["all"],
        "texels_used_mean": float(np.mean(col("texels_all"))),
        "brightness_speedup": serial_all / timings["brightness_all"]["mean"],
        "brightness_sampled_speedup": serial_all / timings["brightness_sampled"]["mean"],
        "speedup_definition": "brightness_serial_all_extrapolated.mean / brightness_all.mean (sampled: "
                              "/ brightness_sampled.mean)",
        "serial_vs_vectorised_max_abs_diff": max(col("serial_diff")),
        "serial_vs_vectorised_texels_equal": all(col("serial_texels_equal")),
        "sampled_error_max": max(errors), "sampled_error_mean": float(np.mean(errors)),
        "units": "Δ differences in 0..255 camera units, max over channels and frames"}


def run_bench(*, atlas_size: int = 2048, frames: int = FRAMES, scene: str | Path = SCENE,
              serial_texels: int = SERIAL_TEXELS, sample_texels: int = SAMPLE_TEXELS,
              show_progress: bool = True) -> dict:
    """Render ``frames`` fisheye frames, then time every stage per frame (module docstring)."""
    from probeless.coarse.brightness import BrightnessSample, draw_sample
    from probeless.coarse.frames import scene_source
    from probeless.coarse.inpaint import inpaint_atlas
    from probeless.coarse.model import CoarseConfig, CoarseModel
    from probeless.errors import SchemaError

    if frames < WARMUP_FRAMES + 1 or serial_texels < 1 or sample_texels < 1 or atlas_size < 16:
        raise SchemaError(f"bench coarse: need --frames >= {WARMUP_FRAMES + 1}, --serial-texels >= 1, "
                          f"sample_texels >= 1 and --atlas-size >= 16, got {frames}, {serial_texels}, "
                          f"{sample_texels}, {atlas_size}")
    t_start = time.monotonic()
    source = scene_source(scene)
    rendered = render(source, min(frames, source.count), show_progress)
    render_s = time.monotonic() - t_start
    log(f"{len(rendered)} frames rendered in {render_s:.1f} s; building the {atlas_size}^2 atlas")
    config = CoarseConfig(atlas_size=atlas_size, fov_deg=source.texture_fov_deg, inpaint_scale=INPAINT_SCALE)
    model = CoarseModel(source.floorplan, source.ceiling_height, config, ctx=source.rig.renderer.ctx)
    all_s = draw_sample(model.texmap)
    sub = strided_subset(all_s.index, serial_texels)
    samples = (all_s, draw_sample(model.texmap, sample_texels, seed=0),
               BrightnessSample(sub, model.texmap.position.reshape(-1, 3)[sub],
                                model.texmap.normal.reshape(-1, 3)[sub], all_s.shape))
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
               **{f"brightness_{k}": stats([r[k] for r in b]) for k in ("all", "sampled", "serial_subset")},
               "brightness_serial_all_extrapolated": stats([r["serial_all"] for r in b]),
               "inpaint_amortised": stats(rest), "inpaint_full": stats(full),
               "readback_rgba8": stats([r["readback"] for r in b])}
    brightness = brightness_summary(b, timings, samples)
    goal = GOALS["brightness_speedup_min"]
    goals_met = {k: bool(brightness[k] >= goal) for k in ("brightness_speedup", "brightness_sampled_speedup")}
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
    print(f"  brightness: serial loop on {b['serial_texels']} strided texels ({b['serial_ms_per_texel'] * 1e3:.2f} "
          f"us/texel) extrapolated to {b['all_texels']}; speedup vectorised all texels {b['brightness_speedup']:.0f}x, "
          f"sampled ({b['sample_texels']}) {b['brightness_sampled_speedup']:.0f}x "
          f"(goal >= {r['goals']['brightness_speedup_min']:.0f}x)")
    print(f"  last frame: serial loop over all texels measured {b['last_frame_serial_all_measured_ms']:.0f} ms, "
          f"extrapolated {b['last_frame_serial_all_extrapolated_ms']:.0f} ms, vectorised "
          f"{b['last_frame_vectorised_all_ms']:.0f} ms -> {b['last_frame_speedup_measured']:.0f}x measured")
    print(f"  serial vs vectorised |ΔΔ| max {b['serial_vs_vectorised_max_abs_diff']} (same texels: "
          f"{b['serial_vs_vectorised_texels_equal']}); sampled vs all-texel error max {b['sampled_error_max']:.4f}, "
          f"mean {b['sampled_error_mean']:.4f} (0..255)")
    print(f"  inpainting: {r['inpaint']['incremental_runs']} incremental run(s), first "
          f"{r['inpaint']['first_run_ms']:.0f} ms; meets_goals={r['meets_goals']} {r['goals_met']}; "
          f"{r['duration_s']:.0f} s "
          f"(rendering {r['render_s']:.0f} s)")


def main(json_out: bool = False, quick: bool = False, *, atlas_size: int = 2048, frames: int | None = None,
         scene: str | Path | None = None, serial_texels: int | None = None, sample_texels: int = SAMPLE_TEXELS,
         show_progress: bool = True) -> int:
    """Run the benchmark; a table, or exactly one JSON object with ``json_out``. 0 always (figures, not a test).
    None for ``frames``, ``scene``, ``serial_texels``: the defaults (``quick``: fewer frames and serial texels)."""
    scene = scene or SCENE
    frames = frames or (QUICK_FRAMES if quick else FRAMES)
    serial_texels = serial_texels or (QUICK_SERIAL_TEXELS if quick else SERIAL_TEXELS)
    with stdout_to_stderr():
        result = run_bench(atlas_size=atlas_size, frames=frames, scene=scene, serial_texels=serial_texels,
                           sample_texels=sample_texels, show_progress=show_progress)
    emit(result, json_out, print_table)
    return 0


def add_arguments(ap: argparse.ArgumentParser) -> None:
    """The coarse benchmark's own options (besides ``--json`` / ``--quick``)."""
    ap.add_argument("--atlas-size", type=int, default=2048, help="atlas side [texels] (default 2048)")
    ap.add_argument("--frames", type=int, help=f"fisheye frames, the first a warm-up (default {FRAMES}, "
                                               f"--quick {QUICK_FRAMES})")
    ap.add_argument("--scene", help="scene file (default launch/scenes/partition_room.yaml)")
    ap.add_argument("--serial-texels", type=int, help=f"texels the serial brightness loop is timed on (default "
                                                      f"{SERIAL_TEXELS}, --quick {QUICK_SERIAL_TEXELS})")


def run(ns: argparse.Namespace) -> int:
    return main(ns.json, ns.quick, atlas_size=ns.atlas_size, frames=ns.frames, scene=ns.scene,
                serial_texels=ns.serial_texels)


if __name__ == "__main__":
    from probeless.bench.common import module_main

    raise SystemExit(module_main(__spec__.name))
