"""``probeless eval slam DATASET``: run the dense SLAM over a dataset, scene or recording and score it.

The figures are :func:`probeless.tracking.slam_report.slam_report`'s. With ``--trajectory-out`` the
estimate and the ground truth are written in TUM format, so that TUM's ``evaluate_ate.py
GROUNDTRUTH ESTIMATE`` and evo's ``evo_ape tum GROUNDTRUTH ESTIMATE --align`` reproduce the ATE
printed here (asserted to < 1 µm in tests/eval/test_eval_slam_evo.py); ``--plot`` (or ``--figure``) draws the
trajectories and the error over time.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from probeless.eval.harness import add_common_options, emit
from probeless.progress import stdout_to_stderr

# SlamParams fields settable from the command line (importing SlamParams here would slow every
# ``probeless`` command down by ~0.5 s; tests check that these fields exist with these types).
SLAM_FLAGS: dict[str, type] = {
    "voxel_size": float, "depth_max": float, "depth_min": float, "depth_diff": float,
    "trunc_voxel_multiplier": float, "integrate_every": int, "raycast_every": int, "scale": float,
    "min_fitness": float, "iterations": tuple, "raycast_shift": bool, "grid_rotation_deg": list,
    "integrate_nearest_pixel": bool, "depth_weighting": bool, "depth_sigma": list, "refine_iterations": int,
    "refine_step": int,
}
FLAG_HELP = {"depth_max": "[m]; default: the source's accurate depth range where it has one (a scene file: its "
                          "rig's depth_max_m), else SlamParams' 3 m",
             "depth_weighting": "refine each pose with points weighted by their depth noise (default: on, off for a "
                                "source with constant noise such as a scene file's rig)",
             "depth_sigma": "A B Z0: depth noise sigma(z) = A + B (z - Z0)^2 [m] (default: Kinect v1, "
                            "Nguyen et al. 2012)"}


def _gap(text: str) -> int:
    """A frame gap >= 1 (argparse type)."""
    try:
        gap = int(text)
    except ValueError:
        gap = 0
    if gap < 1:
        raise argparse.ArgumentTypeError(f"a gap is a whole number of frames >= 1, got {text!r}")
    return gap


def add_arguments(c: argparse.ArgumentParser) -> None:
    """The options of ``probeless eval slam``."""
    c.add_argument("dataset", metavar="DATASET", help="RGB-D dataset folder, scene file (.yaml) or recording (.mcap)")
    add_common_options(c, json_help="print one JSON object on stdout",
                       figure=("--plot", "write estimated vs true trajectory and the error over time"),
                       progress_help="no progress bar on stderr")
    c.add_argument("--trajectory-out", metavar="TRAJ.txt", help="write the estimate in TUM format, and the ground "
                                                               "truth beside it (TRAJ.groundtruth.txt)")
    c.add_argument("--groundtruth-out", metavar="GT.txt", help="where to write the ground truth (TUM format)")
    c.add_argument("--start", type=int, default=0, help="first frame")
    c.add_argument("--max-frames", type=int, default=0, help="frames to run; 0 = all")
    c.add_argument("--stride", type=int, default=1, help="use every n-th frame")
    c.add_argument("--rpe-delta-s", type=float, default=1.0, help="interval of the drift RPE [s] (default 1)")
    c.add_argument("--depth-consistency", metavar="GAP", type=_gap, nargs="+",
                   help="also score estimate and ground truth by how well they explain the depth images: median "
                        "projective depth residual of frame pairs GAP frames apart (needs no ground truth)")
    g = c.add_argument_group("SLAM parameters (default: probeless.tracking.dense.SlamParams)")
    for name, kind in SLAM_FLAGS.items():
        flag, dest = "--" + name.replace("_", "-"), "slam_" + name
        if kind is bool:
            g.add_argument(flag, dest=dest, default=None, action=argparse.BooleanOptionalAction,
                           help=FLAG_HELP.get(name))
        else:
            g.add_argument(flag, dest=dest, default=None, metavar=name.upper(), help=FLAG_HELP.get(name),
                           **({"nargs": "+", "type": int} if kind is tuple else
                              {"nargs": 3, "type": float} if kind is list else {"type": kind}))


def slam_params(ns: argparse.Namespace):
    """SlamParams with the fields given on the command line replaced."""
    from probeless.tracking.dense import SlamParams

    given = {k: getattr(ns, "slam_" + k) for k in SLAM_FLAGS if getattr(ns, "slam_" + k, None) is not None}
    if "iterations" in given:
        given["iterations"] = tuple(given["iterations"])
    for key in ("grid_rotation_deg", "depth_sigma"):
        if key in given:
            given[key] = tuple(given[key])
    return SlamParams(**given)


def write_outputs(slam_run, r: dict, ns: argparse.Namespace) -> None:
    """Trajectory files and plot the command line asked for; their paths go into the report ``r``."""
    from probeless.tracking.metrics import align_points, ate_errors
    from probeless.tracking.slam_report import mm

    if ns.trajectory_out or ns.groundtruth_out:
        from probeless.tracking.tum import write_tum

        if ns.trajectory_out:
            r["trajectory"] = str(write_tum(ns.trajectory_out, slam_run.stamps_ns, slam_run.poses))
        gt_path = ns.groundtruth_out or str(Path(ns.trajectory_out).with_suffix(".groundtruth.txt"))
        r["groundtruth"] = str(write_tum(gt_path, slam_run.stamps_ns, slam_run.gt))
    if ns.figure:
        from probeless.tracking.plots import plot_trajectory

        ate = ate_errors(slam_run.poses, slam_run.gt)
        t_s = (slam_run.stamps_ns - slam_run.stamps_ns[0]) / 1e9
        tracked = np.array([p is not None for p in slam_run.poses])
        est_all = align_points(np.array([p[:3, 3] for p in slam_run.poses if p is not None]), ate)
        title = f"{Path(r['dataset']).name}: ATE RMSE {mm(r['ate']['rmse'])} over {r['ate']['n']} frames"
        r["plot"] = str(plot_trajectory(ns.figure, t_s=t_s[tracked], est_aligned=est_all, gt_t_s=t_s[ate["indices"]],
                                        gt=ate["gt"], gt_est=ate["est_aligned"], errors=ate["errors"], title=title))


def run(ns: argparse.Namespace) -> int:
    """Run, score, write; prints the report (one JSON object with --json). Returns the exit status."""
    from probeless.tracking.offline import run_slam
    from probeless.tracking.slam_report import format_report, slam_report

    params = slam_params(ns)
    t0 = time.perf_counter()
    with stdout_to_stderr():
        # a source that describes its depth (the synthetic rig) sets depth_max and the weighting, unless flags do
        slam_run = run_slam(ns.dataset, params, start=ns.start, max_frames=ns.max_frames, stride=ns.stride,
                       progress=not ns.no_progress, source_depth_model=True,
                       explicit=[k for k in SLAM_FLAGS if getattr(ns, "slam_" + k, None) is not None])
        r = slam_report(slam_run, ns.dataset, slam_run.params or params, ns.rpe_delta_s)
        if ns.depth_consistency:
            from probeless.tracking.depth_consistency import consistency_report

            r["depth_consistency"] = consistency_report(slam_run, ns.dataset, ns.depth_consistency, start=ns.start,
                                                        max_frames=ns.max_frames, stride=ns.stride)
        r["wall_s"] = time.perf_counter() - t0
        write_outputs(slam_run, r, ns)
    return emit(ns, r, format_report)
