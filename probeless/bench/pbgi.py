"""``probeless bench pbgi``: point-based GI of a virtual sphere (paper 001, §5 and §6.3): the BSH build and the
Classic / Mipmapped / Hybrid micro-buffer traversals, timed as the paper's Table 1 (BSH) and Table 3.

What is measured (one GL context; this machine runs Mesa llvmpipe on 2 shared CPU cores, not a GPU: ``device``
names the GL renderer, so the times are a CPU rasteriser's and only their ratios compare with the paper's):

* **BSH** (Table 1 analogue): :func:`~probeless.pbgi.bsh.build_bsh` with the paper's thresholds (tc 0.01,
  tn 0.98) on each scene's cloud and on 1 M points of :func:`~probeless.pbgi.bsh.synthetic_room` (best of
  ``--repeat`` builds; not with ``--quick``): seconds per stage, nodes before and after clustering. The first,
  small build that compiles (or loads) the numba kernels is timed apart (``numba_warmup_s``).
* **Table 3**: a sphere (r = 0.15 m, diffuse 0.8 grey) in each scene -- ``room``: the ``plain`` reference room
  (:func:`~probeless.pbgi.room.reference_room`, 1 cm cloud, the sphere at its object centre, seen from the room's
  ``front`` direction); ``fragment``: Open3D's scanned fragment (``SHARED_DATA/pointclouds/open3d_fragment.pcd``,
  colours sRGB), the sphere :data:`FRAGMENT_OFFSET` m from the cloud's centroid along the mean normal (towards
  where the scanner stood, in front of the scanned surfaces), seen from the side so that its lit half shows;
  image up is the scan's -y. Two views as the paper's: View1 a close-up whose silhouette spans twice the image
  (the object fills the viewport), View2 the whole object covering about a third of it. For each viewport and
  micro-buffer size, each variant's PBGI time (``ms``: ``MicroStats.seconds``, traversal and shading, GL
  finished; best of ``--repeat`` rounds, the variants interleaved in each round, after one untimed warm-up render
  per renderer; ``render_ms``: the whole render call with the G-buffer; ``cpu_ms``: that call's process CPU time
  over all llvmpipe threads, which other processes on the shared cores disturb less than wall time), the extra
  memory (``extra_mb``: peak bytes of the pair buffers, ``MicroStats.pair_bytes``; Classic has none) and the
  micro-buffer storage (``micro_mb``: every receiver's micro-buffer, 4 bytes a texel, (s x micro)² texels with
  ``--supersample`` s (default 1: the paper's micro-buffer), as one texture would hold them; the renderer fills
  them in batches of at most 64 MiB, ``micro_alloc_mb`` is the buffer it holds), in 10^6 bytes. A
  :class:`~probeless.errors.PbgiError` is recorded as ``null`` with its text (the paper's 'x').
* **Same work**: per configuration, the largest absolute difference and the relative RMS of the Mipmapped and
  Hybrid images against Classic's over the object's pixels. Gate: relative RMS <= :data:`EQUAL_REL_RMS` (the
  three compute the same cut, so the images should be identical); ``images_equal`` false fails the exit code.
* ``hybrid_speedup`` / ``mipmapped_speedup``: Classic time / that variant's time per configuration, with the
  largest and the median (``cpu``: the same of ``cpu_ms``). The reference is Classic micro-buffer PBGI
  (Ritschel et al. 2009) with the same shaders and cut (:data:`REFERENCE`).
* **Hybrid threshold** (not with ``--quick``): the Hybrid time for omega_tr = f x the micro-texel solid angle,
  f in :data:`SWEEP_FACTORS`, on room, View2, 256², 24² (the paper fixes f = 32 for its GPU): best of ``--repeat``
  rounds, each round Classic then every f, with each image checked against Classic's as above.

Time budget: ``--budget`` seconds for the whole run (default :data:`BUDGET_S`). Configurations run from the least
work (pixels x micro-texels) up; one whose predicted time (from the rate of the largest one run so far of the same
scene and view) would pass the budget is recorded as ``null``, ``"skipped: time budget ..."``. A configuration
whose first round takes over :data:`LONG_ROUND_S` s is timed once (its noise is small beside its length).
``--quick``: room, View2, 128², 16², one round, no 1 M-point build, no sweep (well under a minute).
``--figure PNG``: the Hybrid 256²/24² image of each scene and view and the times per variant as bars.
"""

from __future__ import annotations

import os
import time

from probeless.bench.common import emit, log, rounded
from probeless.bench.pbgi_report import missing_figure_images, print_table, write_figure
from probeless.bench.pbgi_scenes import (
    ALBEDO,
    BUDGET_S,
    EQUAL_REL_RMS,
    OBJECT_RADIUS,
    PAPER,
    REFERENCE,
    SCENES,
    SUPERSAMPLE,
    SYNTHETIC_POINTS,
    VIEW_MARGIN,
    Renderers,
    Scene,
    Settings,
    build_scene_bsh,
    fragment_scene,
    numba_warmup,
    room_scene,
    synthetic_row,
)
from probeless.bench.pbgi_table import Budget, speedup_summary, sweep, table3


def _ints(text: str) -> list[int]:
    """``--views`` / ``--viewports`` / ``--micro``: comma-separated positive integers."""
    import argparse

    try:
        out = [int(v) for v in str(text).split(",") if v.strip()]
    except ValueError:
        out = []
    if not out or min(out) < 1:
        raise argparse.ArgumentTypeError(f"expected comma-separated positive integers, got {text!r}")
    return out


def _scenes(text: str) -> list[str]:
    """``--scenes``: comma-separated names of :data:`SCENES`."""
    import argparse

    out = [v.strip() for v in str(text).split(",") if v.strip()]
    if not out or set(out) - set(SCENES):
        raise argparse.ArgumentTypeError(f"expected names among {', '.join(SCENES)}, got {text!r}")
    return out


def add_arguments(p) -> None:
    """``--scenes``, ``--views``, ``--viewports``, ``--micro``, ``--repeat``, ``--budget``, ``--figure``."""
    p.add_argument("--scenes", type=_scenes, default=None, help="room,fragment (default both; quick room)")
    p.add_argument("--views", type=_ints, default=None, help="1 (close-up), 2 (whole object) (default 1,2; quick 2)")
    p.add_argument("--viewports", type=_ints, default=None, help="image sides [px] (default 128,256,512; quick 128)")
    p.add_argument("--micro", type=_ints, default=None, help="micro-buffer sides (default 16,24,32; quick 16)")
    p.add_argument("--repeat", type=int, default=None, help="timed rounds, best kept (default 2; quick 1)")
    p.add_argument("--supersample", type=int, default=SUPERSAMPLE,
                   help=f"micro-buffer supersampling of the renderer (default {SUPERSAMPLE}: the paper's micro-buffer)")
    p.add_argument("--budget", type=float, default=BUDGET_S, help=f"seconds for the whole run (default {BUDGET_S:g})")
    p.add_argument("--figure", default=None, metavar="PNG", help="write the test images and the times as a PNG")


def settings(ns) -> Settings:
    """Options (lists, or comma-separated text as on the command line) with the (quick) defaults filled in;
    :class:`~probeless.errors.PbgiError` on an unknown view."""
    from probeless.errors import PbgiError

    quick = bool(ns.quick)

    def option(value, parse, default: str, quick_default: str):
        value = quick_default if value is None and quick else default if value is None else value
        return parse(value) if isinstance(value, str) else list(value)

    views = option(ns.views, _ints, "1,2", "2")
    if set(views) - set(VIEW_MARGIN):
        raise PbgiError(f"--views: expected 1 and/or 2, got {views}")
    return Settings(option(ns.scenes, _scenes, ",".join(SCENES), "room"), views,
                    option(ns.viewports, _ints, "128,256,512", "128"), option(ns.micro, _ints, "16,24,32", "16"),
                    max(1, ns.repeat or (1 if quick else 2)), int(getattr(ns, "supersample", None) or SUPERSAMPLE),
                    float(getattr(ns, "budget", None) or BUDGET_S), quick,
                    getattr(ns, "figure", None))


def load_scenes(st: Settings) -> dict:
    """{name: Scene or the reason it is skipped}, BSHs not built yet."""
    out = {}
    for name in st.scenes:
        log(f"loading {name}")
        out[name] = room_scene() if name == "room" else fragment_scene()
    return out


def bsh_table(st: Settings, scenes: dict) -> dict:
    """Numba warm-up, then each scene's BSH (kept for rendering) and the 1 M-point build (not quick)."""
    from probeless.pbgi.bsh import MAX_CLUSTER_RADIUS

    warm = numba_warmup()
    rows = []
    for name, scene in scenes.items():
        log(f"BSH of {name}")
        rows.append(build_scene_bsh(scene, st.repeat) if isinstance(scene, Scene) else {"cloud": name,
                                                                                        "skipped": scene})
    if not st.quick:
        log(f"BSH of {SYNTHETIC_POINTS} synthetic points")
        rows.append(synthetic_row(st.repeat))
    return {"numba_warmup_s": warm, "tc": 0.01, "tn": 0.98, "max_cluster_radius_m": MAX_CLUSTER_RADIUS, "rows": rows}


def scene_info(scenes: dict) -> dict:
    """Where the sphere is in each scene (or why the scene is skipped)."""
    return {name: ({"points": len(s.points), "sphere_centre": s.centre, "sphere_radius": OBJECT_RADIUS,
                    "camera_direction": s.direction, "up": s.up} if isinstance(s, Scene) else {"skipped": s})
            for name, s in scenes.items()}


def measure(st: Settings) -> dict:
    """The whole benchmark as one result object (see the module docstring)."""
    start = time.perf_counter()
    scenes = load_scenes(st)
    bsh = bsh_table(st, scenes)
    renderers = Renderers(st.supersample)
    try:
        sweep_result = None if st.quick else sweep(st, scenes, renderers)
        rows, images = table3(st, scenes, renderers, Budget(st.budget, start))
        if st.figure:
            missing_figure_images(st, scenes, renderers, images)
            write_figure(st.figure, images, rows)
        device = renderers.device
    finally:
        renderers.release()
    equal = all(r["equal"] for r in rows) and (sweep_result is None or sweep_result["equal"])
    speed = speedup_summary(rows)
    return {"benchmark": "pbgi", "reference": REFERENCE, "paper": PAPER, "device": device,
            "cpu_cores": os.cpu_count(), "quick": st.quick,
            "settings": {"scenes": st.scenes, "views": st.views, "viewports": st.viewports, "micro": st.micros,
                         "repeat": st.repeat, "supersample": st.supersample, "budget_s": st.budget,
                         "view_margin": VIEW_MARGIN, "albedo": ALBEDO, "gate_rel_rms": EQUAL_REL_RMS},
            "scenes": scene_info(scenes), "bsh": bsh, "table3": rows,
            "images_equal": bool(equal), "hybrid_speedup": speed["hybrid"], "mipmapped_speedup": speed["mipmapped"],
            "configs_run": sum(not r.get("skipped") for r in rows), "configs_skipped": sum(
                bool(r.get("skipped")) for r in rows),
            "hybrid_threshold_sweep": sweep_result, "figure": st.figure, "duration_s": time.perf_counter() - start}


# -- output ----------------------------------------------------------------------------------------------------------


def run(ns) -> int:
    """Run the benchmark; exit 1 when the variants' images differ (the figures are printed first)."""
    result = rounded(measure(settings(ns)), 6)
    emit(result, ns.json, print_table)
    return 0 if result["images_equal"] else 1


def main(json_out: bool = False, quick: bool = False) -> int:
    """``run`` with the defaults (the benchmark interface of :mod:`probeless.bench`)."""
    import argparse

    return run(argparse.Namespace(json=json_out, quick=quick, scenes=None, views=None, viewports=None, micro=None,
                                  repeat=None, supersample=SUPERSAMPLE, budget=BUDGET_S, figure=None))


if __name__ == "__main__":
    from probeless.bench.common import module_main

    raise SystemExit(module_main(__name__))
