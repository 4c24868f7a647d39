"""``probeless eval slam`` end to end, TUM trajectory files, plots: checked against independent readings
of the files."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest
from locations import REPO, SHARED_DATA
from references import horn_quaternion
from scipy.spatial.transform import Rotation

from probeless.errors import DatasetError
from probeless.eval import add_eval_parser
from probeless.scene.parse import load_scene
from probeless.tracking.tum import read_tum, write_tum

DATA = SHARED_DATA / "rgbd"
SEVEN = DATA / "sevenscenes_kinect_0000-0399"
SCENE = REPO / "launch" / "scenes" / "convex_room.yaml"


def run_cli(argv: list[str]) -> int:
    root = argparse.ArgumentParser(prog="probeless")
    add_eval_parser(root.add_subparsers(dest="command", required=True))
    ns = root.parse_args(argv)
    return ns.func(ns)


def load_tum_columns(path: Path) -> np.ndarray:
    """The 8 numeric columns of a TUM file, read without the project's reader."""
    rows = [line.split() for line in path.read_text().splitlines() if line.strip() and not line.startswith("#")]
    assert all(len(r) == 8 for r in rows), "every TUM line has 8 columns"
    return np.array(rows, dtype=np.float64)


def ate_from_files(gt_file: Path, est_file: Path) -> tuple[float, int]:
    """What TUM's evaluate_ate.py does: match stamps within 20 ms, Horn alignment, RMSE of position errors."""
    gt, est = load_tum_columns(gt_file), load_tum_columns(est_file)
    pairs = [(i, int(np.argmin(np.abs(gt[:, 0] - s)))) for i, s in enumerate(est[:, 0])]
    pairs = [(i, j) for i, j in pairs if abs(gt[j, 0] - est[i, 0]) < 0.02]
    e, g = est[[i for i, _ in pairs], 1:4], gt[[j for _, j in pairs], 1:4]
    R, t = horn_quaternion(e, g)
    return float(np.sqrt(np.mean(np.sum((e @ R.T + t - g) ** 2, axis=1)))), len(pairs)


def test_tum_round_trip_and_columns(tmp_path):
    rng = np.random.default_rng(0)
    rots = Rotation.random(5, random_state=1)
    poses = [np.eye(4) for _ in range(5)]
    for T, R, p in zip(poses, rots.as_matrix(), rng.normal(0, 2, (5, 3))):
        T[:3, :3], T[:3, 3] = R, p
    stamps = np.array([0, 33_333_333, 66_666_667, 1_700_000_000_123_456_789, 1_700_000_000_200_000_000])
    poses[2] = None  # an untracked frame is not written
    path = write_tum(tmp_path / "t.txt", stamps, poses)
    cols = load_tum_columns(path)
    assert len(cols) == 4
    kept = [0, 1, 3, 4]
    np.testing.assert_allclose(cols[:, 0], stamps[kept] / 1e9, rtol=0, atol=1e-6)
    np.testing.assert_allclose(cols[:, 1:4], [poses[k][:3, 3] for k in kept], atol=1e-8)
    q_ref = rots[kept].as_quat()  # scipy: x, y, z, w like TUM
    same_sign = np.sign(np.sum(q_ref * cols[:, 4:], axis=1))[:, None]
    np.testing.assert_allclose(cols[:, 4:], q_ref * same_sign, atol=1e-8)
    back_ns, back = read_tum(path)
    assert list(back_ns) == list(stamps[kept])
    np.testing.assert_allclose(back, [poses[k] for k in kept], atol=1e-8)


@pytest.mark.slow
def test_eval_slam_on_20_real_kinect_frames(tmp_path, capfd):
    traj, png = tmp_path / "traj.txt", tmp_path / "plot.png"
    code = run_cli(["eval", "slam", str(SEVEN), "--max-frames", "20", "--json", "--no-progress",
                    "--trajectory-out", str(traj), "--plot", str(png), "--voxel-size", "0.01",
                    "--iterations", "6", "3", "1"])
    assert code == 0
    report = json.loads(capfd.readouterr().out)  # exactly one JSON object on stdout, native warnings elsewhere
    assert report["frames"]["processed"] == 20 and report["frames"]["with_ground_truth"] == 20
    assert report["params"]["voxel_size"] == 0.01 and report["params"]["iterations"] == [6, 3, 1]
    assert set(report["costs_ms"]) >= {"track", "integrate"}
    # The printed ATE is what the TUM procedure gives on the files written.
    gt_file = Path(report["groundtruth"])
    ate_files, n = ate_from_files(gt_file, traj)
    assert n == report["ate"]["n"] == 20 - report["frames"]["dropped"]
    assert report["ate"]["rmse"] == pytest.approx(ate_files, abs=1e-6)
    assert report["ate"]["rmse"] < 0.02
    # The written ground truth is the dataset's reference poses (camera-to-world per frame file).
    ref = np.array([np.loadtxt(SEVEN / f"frame-{k:06d}.pose.txt")[:3, 3] for k in range(20)])
    np.testing.assert_allclose(load_tum_columns(gt_file)[:, 1:4], ref, atol=1e-6)
    assert png.stat().st_size > 10_000 and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.gl
@pytest.mark.graph
@pytest.mark.slow
def test_eval_slam_on_a_synthetic_scene(capfd):
    code = run_cli(["eval", "slam", str(SCENE), "--max-frames", "8", "--stride", "4", "--no-progress", "--json"])
    assert code == 0
    report = json.loads(capfd.readouterr().out)
    assert report["frames"]["processed"] == 8 and report["frames"]["with_ground_truth"] == 8
    assert report["failures"] == 0
    assert report["ate"]["n"] == 8 and report["ate"]["rmse"] < 0.02
    assert report["rpe"]["per_frame"]["n"] == 7
    # the rig's depth is good to its range, so that is the depth_max used (no --depth-max given)
    assert report["params"]["depth_max"] == load_scene(SCENE).rgbd.depth_max_m != 3.0


@pytest.mark.slow
def test_eval_slam_depth_consistency_scores_estimate_and_reference(capfd):
    code = run_cli(["eval", "slam", str(SEVEN), "--max-frames", "6", "--no-progress", "--json",
                    "--depth-consistency", "1", "5"])
    assert code == 0
    dc = json.loads(capfd.readouterr().out)["depth_consistency"]
    assert sorted(dc) == ["1", "5"]
    assert dc["1"]["estimate"]["pairs"] == 5 and dc["5"]["ground_truth"]["pairs"] == 1
    for gap in dc.values():
        for c in gap.values():  # Kinect depth: a few mm apart, most pixels consistent
            assert 0.0005 < c["median_m"] < 0.02 and c["inlier_fraction"] > 0.8
    assert run_cli(["eval", "slam", str(SEVEN), "--max-frames", "3", "--no-progress", "--depth-consistency", "2"]) == 0
    assert "depth residual, frames 2 apart (median): estimate" in capfd.readouterr().out


@pytest.mark.slow
def test_eval_slam_human_report(capfd):
    assert run_cli(["eval", "slam", str(SEVEN), "--max-frames", "4", "--no-progress"]) == 0
    out = capfd.readouterr().out
    assert "4 frames processed" in out and "ATE RMSE" in out and "RPE per frame" in out


@pytest.mark.slow
def test_eval_slam_refuses_a_slice_without_ground_truth():
    # icl_livingroom1_micro has official ground truth for frames 0-4, 50, 100, 150, 200 only.
    with pytest.raises(DatasetError, match="0 frame\\(s\\) have both an estimate and ground truth"):
        run_cli(["eval", "slam", str(DATA / "icl_livingroom1_micro"), "--start", "5", "--max-frames", "3",
                 "--no-progress"])


def test_slam_flags_name_real_slam_params_fields():
    import dataclasses

    from probeless.eval.slam import SLAM_FLAGS, slam_params
    from probeless.tracking.dense import SlamParams

    defaults = {f.name: f.default for f in dataclasses.fields(SlamParams)}
    for name, kind in SLAM_FLAGS.items():
        assert name in defaults, f"--{name} is not a SlamParams field"
        want = tuple if kind is list else kind  # list: a fixed-length float tuple given as 3 numbers
        assert type(defaults[name]) is want, f"--{name}: SlamParams default is {defaults[name]!r}"
    root = argparse.ArgumentParser()
    add_eval_parser(root.add_subparsers(dest="command"))
    ns = root.parse_args(["eval", "slam", "x", "--voxel-size", "0.02", "--iterations", "4", "2",
                          "--no-raycast-shift", "--integrate-every", "3", "--grid-rotation-deg", "1", "2.5", "3"])
    p = slam_params(ns)
    assert (p.voxel_size, p.iterations, p.raycast_shift, p.integrate_every) == (0.02, (4, 2), False, 3)
    assert p.grid_rotation_deg == (1.0, 2.5, 3.0)
    assert p.depth_max == defaults["depth_max"]  # unset flags keep the default
    ns = root.parse_args(["eval", "slam", "x", "--no-depth-weighting", "--depth-sigma", "0.002", "0.001", "0.5"])
    p = slam_params(ns)
    assert not p.depth_weighting and p.depth_sigma == (0.002, 0.001, 0.5)
