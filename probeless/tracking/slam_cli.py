"""``probeless slam run DATASET -o traj.txt``: dense SLAM over a dataset folder, scene file or recording.

Writes the tracked poses as a TUM trajectory (score it with TUM's ``evaluate_ate.py`` or
``probeless eval slam``) and prints frames, failures and the mean cost of each SLAM stage.
"""

from __future__ import annotations

import argparse
import json
from typing import Any


def add_slam_parser(sub: Any) -> Any:
    """Add the ``slam`` command group with ``run``; returns its subparsers."""
    p = sub.add_parser("slam", help="dense RGB-D SLAM (Open3D tensor pipeline, CPU)")
    cmds = p.add_subparsers(dest="slam_command", required=True)
    c = cmds.add_parser("run", help="track a dataset, scene or recording and write its TUM trajectory")
    c.add_argument("dataset", metavar="DATASET", help="RGB-D dataset folder, scene file (.yaml) or recording (.mcap)")
    c.add_argument("-o", "--output", required=True, metavar="TRAJ.txt", help="TUM trajectory to write")
    c.add_argument("--start", type=int, default=0, help="first frame")
    c.add_argument("--max-frames", type=int, default=0, help="frames to run; 0 = all")
    c.add_argument("--stride", type=int, default=1, help="use every n-th frame")
    c.add_argument("--initial-pose", choices=("gt", "identity"), default="gt",
                   help="pose of the first frame: its ground truth (identity without one) or identity")
    c.add_argument("--voxel-size", type=float, help="TSDF voxel edge [m] (default 0.01)")
    c.add_argument("--scale", type=float, help="resolution fraction 1/n: 1, 0.5, 0.25 (default 1)")
    c.add_argument("--integrate-every", type=int, help="integrate every k-th tracked frame (default 1)")
    c.add_argument("--raycast-every", type=int, help="raycast every k-th tracked frame (default 1)")
    c.add_argument("--depth-max", type=float, help="depth used [m]; default: a scene file's rig range, else 3")
    c.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    c.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    c.set_defaults(func=cmd_slam_run)
    return cmds


def params_from(ns: argparse.Namespace):
    """SlamParams with the options given on the command line replaced."""
    from probeless.tracking.dense import SlamParams

    keys = ("voxel_size", "scale", "integrate_every", "raycast_every", "depth_max")
    return SlamParams(**{k: getattr(ns, k) for k in keys if getattr(ns, k) is not None})


def cmd_slam_run(ns: argparse.Namespace) -> int:
    """Run, write the trajectory, print the summary. Returns the exit status."""
    from probeless.progress import stdout_to_stderr
    from probeless.tracking.offline import run_slam
    from probeless.tracking.tum import write_tum

    params = params_from(ns)
    with stdout_to_stderr():  # Open3D prints on stdout
        run = run_slam(ns.dataset, params, start=ns.start, max_frames=ns.max_frames, stride=ns.stride,
                       progress=not ns.no_progress, initial_pose="gt" if ns.initial_pose == "gt" else None,
                       source_depth_model=True, explicit=[k for k in ("depth_max",) if ns.depth_max is not None])
    path = write_tum(ns.output, run.stamps_ns, run.poses)
    states = {s: run.states.count(s) for s in sorted(set(run.states))}
    costs = run.mean_costs_ms()
    report = {"dataset": ns.dataset, "trajectory": str(path), "frames": run.frames, "failures": run.failures,
              "states": states, "mean_costs_ms": costs, "slam_ms_per_frame": 1e3 * run.wall_s / max(run.frames, 1)}
    if ns.json:
        print(json.dumps(report))
        return 0
    print(f"{ns.dataset}: {run.frames} frames, {run.failures} failure(s) "
          f"({', '.join(f'{k} {v}' for k, v in states.items())})")
    print("mean cost per frame: " + ", ".join(f"{k} {v:.1f} ms" for k, v in costs.items())
          + f"; total {report['slam_ms_per_frame']:.1f} ms")
    print(f"trajectory written to {path}")
    return 0
