"""``probeless eval fisheye-pose SCENE_OR_BAG``: how well RGB-D poses give the fisheye pose at its stamps.

Compares interpolation, extrapolation from the two most recent poses (the live case), the nearest
pose and the most recent pose against the true fisheye pose (see :mod:`probeless.tracking.fisheye_eval`;
the ``--plot`` figure is :func:`probeless.tracking.plots.plot_fisheye_errors`).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from probeless.errors import DatasetError
from probeless.eval.harness import add_common_options, emit

if TYPE_CHECKING:
    from probeless.tracking import fisheye_eval as fe


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``probeless eval fisheye-pose``."""
    p.add_argument("source", metavar="SCENE_OR_BAG", help="scene file (.yaml) or recording (.mcap) with "
                                                          "<id>/gt/rgbd_pose and <id>/gt/fisheye_pose")
    add_common_options(p, figure=("--plot", "write error vs time and histograms"),
                       progress_help="accepted for uniformity (this evaluation shows no progress bar)")
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


def load_inputs(ns: argparse.Namespace) -> fe.Inputs:
    """The evaluation inputs the command line names, noise added."""
    from probeless.geom.rotation import transform_from_rpy
    from probeless.tracking import fisheye_eval as fe

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
        raise DatasetError(f"noise must be >= 0, got --noise-rot-deg {ns.noise_rot_deg} "
                           f"--noise-trans-mm {ns.noise_trans_mm}")
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


def run(ns: argparse.Namespace) -> int:
    """Evaluate, draw (``--plot``), print the table or one JSON object. Returns the exit status."""
    from probeless.tracking import fisheye_eval as fe

    inputs = load_inputs(ns)
    errors = fe.evaluate(inputs)
    summary = fe.summarize(errors)
    if ns.figure:
        from probeless.tracking.plots import plot_fisheye_errors

        plot_fisheye_errors(inputs.name, errors, ns.figure)
    result = {"source": str(ns.source), "name": inputs.name, "fisheye_frames": len(inputs.fisheye.stamps_ns),
              "rgbd_poses": len(inputs.rgbd.stamps_ns), "modes": summary}
    return emit(ns, result, lambda r: format_table(r["name"], r["modes"])
                + (f"\nwrote {ns.figure}" if ns.figure else ""))
