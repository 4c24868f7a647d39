"""``probeless eval coarse SCENE``: texture error of the coarse room model against the scene's true
surface colours, with and without the brightness compensation Δ (paper Figure 6).

The compute is :mod:`probeless.coarse.evaluate`. Old spelling: ``probeless coarse eval``.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from probeless.eval.harness import add_common_options, emit
from probeless.jsonio import json_safe
from probeless.progress import stdout_to_stderr


def add_arguments(e: argparse.ArgumentParser) -> None:
    """The options of ``probeless eval coarse``."""
    e.add_argument("scene", metavar="SCENE", help="scene file (.yaml)")
    add_common_options(e, figure=("--plot", "write error over time"))
    e.add_argument("--duration", type=float, metavar="S", help="render this much scene time [s]")
    e.add_argument("--atlas-size", type=int, default=512, help="atlas side [texels] (default 512)")
    e.add_argument("--every", type=int, default=3, help="evaluate every n-th frame (default 3)")
    e.add_argument("--stride", type=int, default=1, help="use every n-th fisheye frame (default 1)")
    e.add_argument("--after", type=float, metavar="S", help="also summarise the frames at or after this time "
                                                            "(e.g. a light switch) [s]")
    e.add_argument("--delta", action=argparse.BooleanOptionalAction, default=None,
                   help="only with (--delta) or without (--no-delta) brightness compensation; default both")


def run(ns: argparse.Namespace) -> int:
    """Evaluate with and/or without Δ, draw (``--plot``), print one line per summary or one JSON object."""
    from probeless.coarse.evaluate import evaluate_scene, plot_runs, summarize

    modes = (True, False) if ns.delta is None else (ns.delta,)
    with stdout_to_stderr():
        runs = [evaluate_scene(ns.scene, duration=ns.duration, use_delta=d, every=ns.every, stride=ns.stride,
                               show_progress=not ns.no_progress, config=None if ns.atlas_size == 512 else
                               _config(ns)) for d in modes]
    result: dict[str, Any] = {"scene": str(ns.scene), "atlas_size": ns.atlas_size, "units": "0..255 camera units"}
    for r in runs:
        key = "with_delta" if r.use_delta else "without_delta"
        result[key] = json_safe(summarize(r))  # non-finite -> None (printed as such in the text too)
        if ns.after is not None:
            result[f"{key}_after"] = json_safe(summarize(r, after_s=ns.after))
    if ns.figure:
        plot_runs(runs, ns.figure, Path(ns.scene).stem, ns.after)
    return emit(ns, result, format_summaries)


def format_summaries(result: dict) -> str:
    """One line ``key: name=value, ...`` per summary of the result."""
    lines = []
    for key, vals in result.items():
        if isinstance(vals, dict):
            lines.append(f"{key}: " + ", ".join(f"{k}={v:.2f}" if isinstance(v, float) else f"{k}={v}"
                                                for k, v in vals.items()))
    return "\n".join(lines)


def _config(ns: argparse.Namespace):
    from probeless.coarse.frames import FOV_MARGIN_DEG
    from probeless.coarse.model import CoarseConfig
    from probeless.scene.parse import load_scene

    return CoarseConfig(atlas_size=ns.atlas_size, fov_deg=load_scene(ns.scene).fisheye.fov_deg - FOV_MARGIN_DEG)
