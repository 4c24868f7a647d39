"""The evaluation of one SLAM run against ground truth: a JSON-ready dict, and its text form.

Figures as the TUM RGB-D benchmark computes them (:mod:`probeless.tracking.metrics`): ATE after a
rigid alignment of the estimated to the true positions, RPE over one frame and over a fixed time.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from probeless.errors import DatasetError
from probeless.tracking.metrics import ate_errors, rpe, summary


def mean_costs(costs_ms: dict[str, list[float]]) -> dict[str, dict]:
    """Per SLAM stage: mean, median and max duration [ms] and how many frames ran it."""
    return {k: {"mean": float(np.mean(v)), "median": float(np.median(v)), "max": float(np.max(v)), "frames": len(v)}
            for k, v in costs_ms.items() if v}


def slam_report(run, dataset: str, params, rpe_delta_s: float = 1.0) -> dict:
    """dataset, frames (processed, tracked, dropped = no estimate, with_ground_truth, states), failures,
    ate (m), rpe per_frame / per_second (m, deg), costs_ms per stage, slam_ms_per_frame, params.

    DatasetError when fewer than 3 frames have both an estimate and ground truth.
    """
    n_gt = sum(g is not None for g in run.gt)
    both = sum(p is not None and g is not None for p, g in zip(run.poses, run.gt))
    if both < 3:
        raise DatasetError(f"{dataset}: {both} frame(s) have both an estimate and ground truth "
                           f"({n_gt} of {run.frames} have ground truth); ATE needs at least 3")
    return {
        "dataset": str(dataset),
        "frames": {"processed": run.frames, "tracked": sum(p is not None for p in run.poses),
                   "dropped": sum(p is None for p in run.poses), "with_ground_truth": n_gt,
                   "states": {s: run.states.count(s) for s in sorted(set(run.states))}},
        "failures": run.failures,
        "ate": summary(ate_errors(run.poses, run.gt)["errors"]),
        "rpe": {"per_frame": rpe(run.poses, run.gt, run.stamps_ns, delta_frames=1),
                "per_second": rpe(run.poses, run.gt, run.stamps_ns, delta_s=rpe_delta_s)},
        "costs_ms": mean_costs(run.costs_ms),
        "slam_ms_per_frame": 1e3 * run.wall_s / max(run.frames, 1),
        "params": dataclasses.asdict(params),
    }


def mm(v: float | None) -> str:
    """Metres as a millimetre string ("n/a" for None)."""
    return "n/a" if v is None else f"{v * 1e3:.1f} mm"


def _deg(r: dict) -> str:
    return "n/a" if r["rot_rmse_deg"] is None else f"{r['rot_rmse_deg']:.2f} deg"


def format_report(r: dict) -> str:
    """A few human-readable lines of :func:`slam_report`'s dict (plus written files, if any)."""
    f, a, rf, rs = r["frames"], r["ate"], r["rpe"]["per_frame"], r["rpe"]["per_second"]
    costs = ", ".join(f"{k} {v['mean']:.1f} ms" for k, v in r["costs_ms"].items())
    lines = [
        (f"{r['dataset']}: {f['processed']} frames processed, {f['dropped']} dropped, "
         f"{r['failures']} tracking failure(s)"),
        (f"ATE RMSE {mm(a['rmse'])} (mean {mm(a['mean'])}, median {mm(a['median'])}, max {mm(a['max'])}; "
         f"{a['n']} frames with ground truth)"),
        (f"RPE per frame: {mm(rf['trans_rmse'])}, {_deg(rf)} RMSE ({rf['n']} pairs); "
         f"per {rs['delta']['s']:g} s: {mm(rs['trans_rmse'])}, {_deg(rs)} ({rs['n']} pairs)"),
        f"mean cost per frame: {costs}; SLAM total {r['slam_ms_per_frame']:.1f} ms",
        (f"depth_max {r['params']['depth_max']:g} m, voxel {r['params']['voxel_size'] * 1e3:g} mm, "
         f"scale {r['params']['scale']:g}"),
    ]
    if "depth_consistency" in r:
        from probeless.tracking.depth_consistency import format_consistency

        lines += format_consistency(r["depth_consistency"])
    lines += [f"{key} written to {r[key]}" for key in ("trajectory", "groundtruth", "plot") if key in r]
    if "trajectory" in r:
        lines.append(f"check with TUM's tools: evaluate_ate.py {r['groundtruth']} {r['trajectory']}")
    return "\n".join(lines)
