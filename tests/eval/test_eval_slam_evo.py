"""``probeless eval slam``'s ATE against evo, the community's trajectory tool (issue 17 §6 "Trajectories"):
what ``evo_ape tum GROUNDTRUTH ESTIMATE --align`` computes (associate within 10 ms, SE(3) Umeyama
alignment, RMSE of the translation errors), through evo's own API on the files ``eval slam`` writes.
Agreement within 0.1 mm is the goal; the figures agree to far less (the files keep nanometres)."""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest
from locations import REPO, SHARED_DATA
from scipy.spatial.transform import Rotation

from probeless.eval import add_eval_parser
from probeless.tracking.metrics import associate, ate
from probeless.tracking.tum import write_tum

evo_file = pytest.importorskip("evo.tools.file_interface", reason="evo is a dev dependency: pip install -e .[dev]")
from evo.core import metrics, sync  # noqa: E402

TOLERANCE_M = 1e-4  # the goal: 0.1 mm


def evo_ape_rmse(gt_path, est_path, align: bool = True) -> tuple[float, int]:
    """(ATE RMSE [m], pairs) as ``evo_ape tum GT EST [--align]`` computes it."""
    ref = evo_file.read_tum_trajectory_file(str(gt_path))
    est = evo_file.read_tum_trajectory_file(str(est_path))
    ref, est = sync.associate_trajectories(ref, est, max_diff=0.01)
    if align:
        est.align(ref, correct_scale=False)
    ape = metrics.APE(metrics.PoseRelation.translation_part)
    ape.process_data((ref, est))
    return float(ape.get_statistic(metrics.StatisticsType.rmse)), est.num_poses


def random_trajectory(rng, n: int) -> list[np.ndarray]:
    """A smooth random walk of poses (world_from_camera)."""
    pos = np.cumsum(rng.normal(0, 0.01, (n, 3)), axis=0)
    rot = Rotation.from_rotvec(np.cumsum(rng.normal(0, 0.01, (n, 3)), axis=0))
    out = [np.eye(4) for _ in range(n)]
    for T, R, p in zip(out, rot.as_matrix(), pos):
        T[:3, :3], T[:3, 3] = R, p
    return out


def test_ate_matches_evo_on_offset_noisy_trajectories_with_gaps(tmp_path):
    """Estimate in another frame (1 m, 40 deg away), noisy, stamped up to 4 ms off the truth, frames missing on
    both sides: our association and alignment give evo's RMSE, and the test tells aligned from unaligned."""
    rng = np.random.default_rng(7)
    n = 120
    gt = random_trajectory(rng, n)
    gt_ns = np.arange(n, dtype=np.int64) * 33_333_333 + 1_700_000_000_000_000_000
    off = np.eye(4)
    off[:3, :3], off[:3, 3] = Rotation.from_euler("xyz", [40, -10, 25], degrees=True).as_matrix(), [1.0, -0.5, 0.2]
    est = []
    for T in gt:
        E = off @ T
        E[:3, 3] += rng.normal(0, 0.005, 3)
        est.append(E)
    est_ns = gt_ns + rng.integers(-4_000_000, 4_000_000, n)
    keep_est, keep_gt = rng.random(n) > 0.1, rng.random(n) > 0.1
    est_ns, est = est_ns[keep_est], [e for e, k in zip(est, keep_est) if k]
    gt_ns, gt = gt_ns[keep_gt], [g for g, k in zip(gt, keep_gt) if k]
    gt_file, est_file = write_tum(tmp_path / "gt.txt", gt_ns, gt), write_tum(tmp_path / "est.txt", est_ns, est)

    stamps, e, g = associate(est_ns, est, gt_ns, gt, max_dt_s=0.01)
    ours = ate(e, g)
    theirs, pairs = evo_ape_rmse(gt_file, est_file)
    assert ours["n"] == pairs > 80
    assert abs(ours["rmse"] - theirs) <= TOLERANCE_M and abs(ours["rmse"] - theirs) < 1e-8
    assert 0.005 < ours["rmse"] < 0.015  # the noise (8.7 mm RMS in 3D), not the 1 m offset
    assert evo_ape_rmse(gt_file, est_file, align=False)[0] > 0.5  # unaligned, evo sees the offset


def run_eval_slam(argv: list[str], capfd) -> dict:
    root = argparse.ArgumentParser(prog="probeless")
    add_eval_parser(root.add_subparsers(dest="command", required=True))
    ns = root.parse_args(["eval", "slam", *argv, "--json", "--no-progress"])
    assert ns.func(ns) == 0
    return json.loads(capfd.readouterr().out)


DATASETS = {
    "7-scenes (real Kinect)": [str(SHARED_DATA / "rgbd" / "sevenscenes_kinect_0000-0399"), "--max-frames", "10",
                               "--stride", "3", "--scale", "0.5"],
    "icl (5 ground-truth frames)": [str(SHARED_DATA / "rgbd" / "icl_livingroom1_micro"), "--max-frames", "5",
                                    "--scale", "0.5"],
    "convex_room (our render)": [str(REPO / "launch" / "scenes" / "convex_room.yaml"), "--max-frames", "12",
                                 "--stride", "2", "--scale", "0.5"],
}


@pytest.mark.slow
@pytest.mark.parametrize("name", [pytest.param(k, marks=[pytest.mark.gl] if "render" in k else []) for k in DATASETS])
def test_eval_slam_ate_agrees_with_evo_ape(name, tmp_path, capfd):
    traj = tmp_path / "traj.txt"
    r = run_eval_slam([*DATASETS[name], "--trajectory-out", str(traj)], capfd)
    theirs, pairs = evo_ape_rmse(r["groundtruth"], r["trajectory"])
    assert pairs == r["ate"]["n"] >= 3
    assert abs(r["ate"]["rmse"] - theirs) <= TOLERANCE_M
    assert abs(r["ate"]["rmse"] - theirs) < 1e-6  # what is actually seen: the files round to nanometres
