"""``probeless coarse preview|eval``: pictures and accuracy of the coarse room model."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

from probeless.progress import stdout_to_stderr


def add_coarse_parser(sub: Any) -> None:
    """Add the ``coarse`` command group to the top-level subparsers."""
    coarse = sub.add_parser("coarse", help="coarse room model: preview pictures, accuracy on synthetic scenes")
    cmds = coarse.add_subparsers(dest="coarse_cmd", required=True)
    p = cmds.add_parser("preview", help="texture the room from a scene or recording and write PNGs")
    p.add_argument("source", metavar="BAG_OR_SCENE", help="scene file (.yaml) or rig recording (.mcap) with "
                                                          "fisheye, fisheye/camera_info, gt/fisheye_pose, floorplan")
    p.add_argument("-o", "--out", required=True, metavar="DIR", help="output folder for the PNGs")
    p.add_argument("--duration", type=float, metavar="S", help="scene: render this much scene time [s]")
    p.add_argument("--atlas-size", type=int, default=1024, help="atlas side [texels] (default 1024)")
    p.add_argument("--snapshots", type=int, default=4, help="atlas snapshots in filling.png (default 4)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_preview)
    e = cmds.add_parser("eval", help="texture error against the scene's true surface colours, with and without Δ")
    e.add_argument("scene", metavar="SCENE", help="scene file (.yaml)")
    e.add_argument("--duration", type=float, metavar="S", help="render this much scene time [s]")
    e.add_argument("--atlas-size", type=int, default=512, help="atlas side [texels] (default 512)")
    e.add_argument("--every", type=int, default=3, help="evaluate every n-th frame (default 3)")
    e.add_argument("--stride", type=int, default=1, help="use every n-th fisheye frame (default 1)")
    e.add_argument("--after", type=float, metavar="S", help="also summarise the frames at or after this time "
                                                            "(e.g. a light switch) [s]")
    e.add_argument("--delta", action=argparse.BooleanOptionalAction, default=None,
                   help="only with (--delta) or without (--no-delta) brightness compensation; default both")
    e.add_argument("--plot", metavar="OUT.png", help="write error over time")
    e.add_argument("--json", action="store_true", help="print one JSON object")
    e.add_argument("--no-progress", action="store_true", help="no progress bar")
    e.set_defaults(func=cmd_eval)


def cmd_preview(ns: argparse.Namespace) -> int:
    from probeless.coarse.preview import preview

    written = preview(ns.source, ns.out, duration=ns.duration, atlas_size=ns.atlas_size, snapshots=ns.snapshots,
                      show_progress=not ns.no_progress)
    for path in written:
        print(path)
    return 0


def _clean(d: dict) -> dict:
    return {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in d.items()}


def cmd_eval(ns: argparse.Namespace) -> int:
    from probeless.coarse.evaluate import evaluate_scene, plot_runs, summarize

    modes = (True, False) if ns.delta is None else (ns.delta,)
    with stdout_to_stderr():
        runs = [evaluate_scene(ns.scene, duration=ns.duration, use_delta=d, every=ns.every, stride=ns.stride,
                               show_progress=not ns.no_progress, config=None if ns.atlas_size == 512 else
                               _config(ns)) for d in modes]
    result: dict[str, Any] = {"scene": str(ns.scene), "atlas_size": ns.atlas_size, "units": "0..255 camera units"}
    for run in runs:
        key = "with_delta" if run.use_delta else "without_delta"
        result[key] = _clean(summarize(run))
        if ns.after is not None:
            result[f"{key}_after"] = _clean(summarize(run, after_s=ns.after))
    if ns.plot:
        plot_runs(runs, ns.plot, Path(ns.scene).stem, ns.after)
    if ns.json:
        print(json.dumps(result))
        return 0
    for key, vals in result.items():
        if isinstance(vals, dict):
            print(f"{key}: " + ", ".join(f"{k}={v:.2f}" if isinstance(v, float) else f"{k}={v}"
                                         for k, v in vals.items()))
    return 0


def _config(ns: argparse.Namespace):
    from probeless.coarse.frames import FOV_MARGIN_DEG
    from probeless.coarse.model import CoarseConfig
    from probeless.scene.parse import load_scene

    return CoarseConfig(atlas_size=ns.atlas_size, fov_deg=load_scene(ns.scene).fisheye.fov_deg - FOV_MARGIN_DEG)
