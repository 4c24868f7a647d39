"""``probeless eval fisheye-pose SCENE_OR_BAG``: how well RGB-D poses give the fisheye pose at its stamps.

Compares interpolation, extrapolation from the two most recent poses (the live case), the nearest
pose and the most recent pose against the true fisheye pose (see :mod:`probeless.tracking.fisheye_eval`).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

from probeless.errors import DatasetError
from probeless.tracking import fisheye_eval as fe


def add_fisheye_eval(eval_subparsers: Any) -> argparse.ArgumentParser:
    """Add ``fisheye-pose`` to the subparsers of the ``probeless eval`` command group."""
    p = eval_subparsers.add_parser("fisheye-pose", help="fisheye pose from interpolated RGB-D poses vs the true one")
    p.add_argument("source", metavar="SCENE_OR_BAG", help="scene file (.yaml) or recording (.mcap) with "
                                                          "<id>/gt/rgbd_pose and <id>/gt/fisheye_pose")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--plot", metavar="OUT.png", help="write error vs time and histograms")
    p.add_argument("--duration", type=float, metavar="S", help="scene: evaluate this much scene time [s]")
    p.add_argument("--rig-id", help="recording: node id of the rig (default: the only one)")
    p.add_argument("--pose-topic", metavar="TOPIC", help="recording: RGB-D poses to use instead of "
                                                         "<id>/gt/rgbd_pose (same world frame)")
    p.add_argument("--fisheye-from-rgbd", type=float, nargs=6, metavar=("TX", "TY", "TZ", "R", "P", "Y"),
                   help="extrinsics [m, deg] (default: the scene's, or the recording's scene metadata)")
    p.add_argument("--noise-rot-deg", type=float, default=0.0, help="Gaussian noise on the RGB-D rotations, "
                                                                    "sigma per axis [deg]")
    p.add_argument("--noise-trans-mm", type=float, default=0.0, help="Gaussian noise on the RGB-D positions, "
                                                                     "sigma per axis [mm]")
    p.add_argument("--seed", type=int, default=0, help="noise seed")
    p.set_defaults(func=cmd_fisheye_pose)
    return p


def load_inputs(ns: argparse.Namespace) -> fe.Inputs:
    """The evaluation inputs the command line names, noise added."""
    from probeless.tracking.interp import transform_from_rpy

    src = Path(ns.source)
    extrinsics = None if ns.fisheye_from_rgbd is None else transform_from_rpy(ns.fisheye_from_rgbd[:3],
                                                                              ns.fisheye_from_rgbd[3:])
    if src.suffix in (".yaml", ".yml"):
        inputs = fe.scene_inputs(src, ns.duration)
        if extrinsics is not None:  # the truth stays the scene's rig: this measures a wrong calibration
            inputs = fe.Inputs(inputs.name, inputs.rgbd, inputs.fisheye, extrinsics)
    elif src.suffix == ".mcap":
        inputs = fe.bag_inputs(src, ns.rig_id, ns.pose_topic, extrinsics)
    else:
        raise DatasetError(f"{src}: expected a scene file (.yaml) or a recording (.mcap)")
    if ns.noise_rot_deg < 0 or ns.noise_trans_mm < 0:
        raise DatasetError(f"noise must be >= 0, got --noise-rot-deg {ns.noise_rot_deg} --noise-trans-mm {ns.noise_trans_mm}")
    if ns.noise_rot_deg or ns.noise_trans_mm:
        inputs = fe.Inputs(inputs.name, fe.with_noise(inputs.rgbd, ns.noise_rot_deg, ns.noise_trans_mm, ns.seed),
                           inputs.fisheye, inputs.fisheye_from_rgbd)
    return inputs


def format_table(name: str, summary: dict[str, dict]) -> str:
    """Human-readable table: one row per mode."""
    fmt = lambda v: "-" if v is None else f"{v:.4f}"  # noqa: E731
    lines = [f"fisheye pose errors: {name}",
             f"{'mode':<13} {'n':>4} {'skip':>4}   {'rot med / p95 / max [deg]':<28} {'trans med / p95 / max [mm]'}"]
    for mode, s in summary.items():
        r, t = s["rot_deg"], s["trans_mm"]
        lines.append(f"{mode:<13} {s['n']:>4} {s['skipped']:>4}   "
                     f"{fmt(r['median']):>8} {fmt(r['p95']):>8} {fmt(r['max']):>8}    "
                     f"{fmt(t['median']):>8} {fmt(t['p95']):>8} {fmt(t['max']):>8}")
    return "\n".join(lines)


def plot(name: str, errors: dict[str, fe.ModeErrors], out: str | Path) -> None:
    """PNG: rotation and translation error vs time (top) and their histograms (bottom), log scales."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    floor = {"rot_deg": 1e-6, "trans_mm": 1e-5}  # exact poses would vanish from a log axis
    fig, axes = plt.subplots(2, 2, figsize=(12, 7))
    for col, (key, label) in enumerate((("rot_deg", "rotation error [deg]"), ("trans_mm", "translation error [mm]"))):
        values = {m: np.maximum(getattr(e, key), floor[key]) for m, e in errors.items()}
        both = np.concatenate([v for v in values.values() if len(v)] or [np.array([floor[key], 1.0])])
        bins = np.geomspace(both.min(), max(both.max(), both.min() * 10), 40)
        for mode, e in errors.items():
            style = "--" if mode == "nearest" else "-"  # nearest and latest coincide when the offset is < half a period
            axes[0, col].plot(e.stamps_ns / 1e9, values[mode], style, marker=".", ms=3, lw=0.8, label=mode)
            axes[1, col].hist(values[mode], bins=bins, histtype="step", linestyle=style, label=mode)
        axes[0, col].set(yscale="log", xlabel="fisheye stamp [s]", ylabel=label)
        axes[1, col].set(xscale="log", xlabel=label, ylabel="frames")
        axes[0, col].legend(fontsize=8)
        axes[0, col].grid(True, which="both", alpha=0.3)
    fig.suptitle(f"fisheye pose from RGB-D poses: {name}")
    fig.tight_layout()
    fig.savefig(out, dpi=100)
    plt.close(fig)


def cmd_fisheye_pose(ns: argparse.Namespace) -> int:
    inputs = load_inputs(ns)
    errors = fe.evaluate(inputs)
    summary = fe.summarize(errors)
    if ns.plot:
        plot(inputs.name, errors, ns.plot)
    if ns.json:
        print(json.dumps({"source": str(ns.source), "name": inputs.name, "fisheye_frames": len(inputs.fisheye.stamps_ns),
                          "rgbd_poses": len(inputs.rgbd.stamps_ns), "modes": summary}, indent=2))
    else:
        print(format_table(inputs.name, summary))
        if ns.plot:
            print(f"wrote {ns.plot}")
    return 0
