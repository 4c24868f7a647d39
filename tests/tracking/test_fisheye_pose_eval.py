"""Fisheye pose accuracy evaluation: analytic motion, noise propagation, the shipped scenes, recordings, the CLI."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest
from locations import REPO
from scipy.spatial.transform import Rotation

from probeless.bag.writer import BagWriter
from probeless.errors import BagError, DatasetError
from probeless.eval import add_evaluation
from probeless.geom.rotation import transform_from_rpy
from probeless.messages.geometry import PoseStamped
from probeless.messages.header import Header
from probeless.scene.parse import load_scene
from probeless.scene.rig import FISHEYE_FRAME, RGBD_FRAME, Rig, frame_schedule
from probeless.tracking import fisheye_eval as fe
from probeless.wire import encode

ROOT = REPO
SCENES = sorted((ROOT / "launch" / "scenes").glob("*.yaml"))
F = transform_from_rpy([0.0, -0.06, -0.02], [-90.0, 0.0, 0.0])  # fisheye_from_rgbd
AXIS = np.array([0.3, 1.0, -0.4]) / np.linalg.norm([0.3, 1.0, -0.4])
OMEGA, V = np.radians(60.0), np.array([0.3, 0.1, -0.05])


def cv_pose(t: float) -> np.ndarray:
    """world_from_rgbd at constant linear and angular velocity."""
    T = np.eye(4)
    T[:3, :3] = (Rotation.from_rotvec(AXIS * OMEGA * t).as_matrix()
                 @ Rotation.from_euler("x", -100, degrees=True).as_matrix())
    T[:3, 3] = [1.0, 2.0, 1.4] + V * t
    return T


def analytic_inputs(offset_s: float, pose=cv_pose, n_fisheye: int = 45) -> fe.Inputs:
    rgbd_t = np.arange(2 * n_fisheye + 2) / 30
    fish_t = offset_s + np.arange(n_fisheye) / 15
    ns = lambda t: np.round(t * 1e9).astype(np.int64)  # noqa: E731
    return fe.Inputs("analytic", fe.make_track(ns(rgbd_t), [pose(t) for t in rgbd_t], "rgbd"),
                     fe.make_track(ns(fish_t), [pose(t) @ np.linalg.inv(F) for t in fish_t], "fisheye"), F)


def test_constant_velocity_interpolation_exact_nearest_and_latest_lag_by_omega_dt():
    errors = fe.evaluate(analytic_inputs(0.020))
    for mode in ("interpolated", "extrapolated"):
        assert errors[mode].rot_deg.max() < 1e-6 and errors[mode].trans_mm.max() < 1e-6
    c = np.linalg.inv(F)[:3, 3]  # the fisheye origin in the RGB-D frame
    for mode, dt in (("nearest", 1 / 30 - 0.020), ("latest", -0.020)):  # the pose used is dt after the frame
        assert np.allclose(errors[mode].rot_deg, np.degrees(OMEGA * abs(dt)), atol=1e-9)
        t = errors[mode].stamps_ns / 1e9
        origin = lambda s: [1.0, 2.0, 1.4] + V * s + cv_pose(s)[:3, :3] @ c  # noqa: E731
        expected = [np.linalg.norm(origin(s + dt) - origin(s)) * 1000 for s in t]
        assert np.allclose(errors[mode].trans_mm, expected, atol=1e-9)
    assert errors["extrapolated"].skipped == 1 and errors["interpolated"].skipped == 0


@pytest.mark.slow
def test_noise_propagation_matches_the_interpolation_weights():
    static = analytic_inputs(0.013, pose=lambda t: cv_pose(0.0), n_fisheye=1500)
    noisy = fe.Inputs("noisy", fe.with_noise(static.rgbd, 0.0, 1.0, seed=4), static.fisheye, F)
    errors = fe.evaluate(noisy)
    rms = {m: np.sqrt(np.mean(e.trans_mm ** 2)) for m, e in errors.items()}
    s = 0.013 * 30  # fraction of the RGB-D period past the previous pose
    # position noise of a weighted sum of independent poses: sigma * sqrt(3 * sum(w^2)) (3 axes, 1 mm each)
    for mode, weights in (("latest", [1.0]), ("interpolated", [1 - s, s]), ("extrapolated", [-s, 1 + s])):
        assert rms[mode] == pytest.approx(np.sqrt(3 * np.sum(np.square(weights))), rel=0.06)


@pytest.mark.slow
@pytest.mark.parametrize("scene", SCENES, ids=lambda p: p.stem)
def test_shipped_scene_interpolation_beats_nearest_pose(scene):
    summary = fe.summarize(fe.evaluate(fe.scene_inputs(scene)))
    near = summary["nearest"]
    for mode, factor in (("interpolated", 0.1), ("extrapolated", 0.2)):
        for key in ("rot_deg", "trans_mm"):
            for stat in ("median", "p95"):
                assert summary[mode][key][stat] < factor * near[key][stat], (mode, key, stat)
    assert near["trans_mm"]["median"] > 1.0  # the 13 ms offset matters: millimetres off without interpolation


def test_scene_truth_is_the_rigs():
    scene = load_scene(SCENES[0])
    rig = Rig(scene, renderer=object(), envmaps=False)  # poses only: nothing is rendered
    inputs = fe.scene_inputs(SCENES[0])
    events = frame_schedule(scene)
    for kind, track, pose in ((RGBD_FRAME, inputs.rgbd, rig.rgbd_pose),
                              (FISHEYE_FRAME, inputs.fisheye, rig.fisheye_pose)):
        picked = [e for e in events if e.kind == kind]
        assert track.stamps_ns.tolist() == [e.stamp_ns for e in picked]
        assert np.allclose(track.poses, [pose(e.t) for e in picked], atol=1e-12)


def write_rig_bag(path: Path, scene_path: Path, rig_id: str = "rig", with_scene: bool = True) -> None:
    scene = load_scene(scene_path)
    rig = Rig(scene, renderer=object(), envmaps=False)
    meta = {"probeless.scene": {"name": scene.name, "yaml": scene_path.read_text()}} if with_scene else {}
    with BagWriter(path, metadata=meta) as writer:
        for seq, e in enumerate(frame_schedule(scene)):
            rgbd = e.kind == RGBD_FRAME
            output = "gt/rgbd_pose" if rgbd else "gt/fisheye_pose"
            msg = PoseStamped(Header(e.stamp_ns, "world"), e.kind,
                              rig.rgbd_pose(e.t) if rgbd else rig.fisheye_pose(e.t))
            writer.write_frames(encode(f"{rig_id}/{output}", msg, rig_id, e.stamp_ns, seq=seq), log_time_ns=e.stamp_ns)


def run_cli(argv: list[str]) -> int:
    parser = argparse.ArgumentParser()
    add_evaluation(parser.add_subparsers(dest="command").add_parser("eval").add_subparsers(dest="eval_command"),
                   "fisheye-pose")
    ns = parser.parse_args(["eval", "fisheye-pose", *argv])
    return ns.func(ns)


@pytest.mark.slow
def test_recording_gives_the_scene_figures_and_the_cli_writes_json_and_plot(tmp_path, capsys):
    scene = SCENES[-1]
    bag = tmp_path / "rig.mcap"
    write_rig_bag(bag, scene)
    from_scene = fe.summarize(fe.evaluate(fe.scene_inputs(scene)))
    assert run_cli([str(bag), "--json", "--plot", str(tmp_path / "errors.png")]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["name"] == "rig.mcap:rig" and out["fisheye_frames"] == from_scene["nearest"]["n"]
    for mode, s in from_scene.items():
        assert out["modes"][mode]["n"] == s["n"]
        for key in ("rot_deg", "trans_mm"):
            assert out["modes"][mode][key]["median"] == pytest.approx(s[key]["median"], rel=1e-9, abs=1e-12)
    png = (tmp_path / "errors.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 20_000
    assert run_cli([str(scene)]) == 0
    assert "interpolated" in capsys.readouterr().out


def test_input_errors_name_the_problem(tmp_path):
    with pytest.raises(DatasetError, match="expected a scene file"):
        run_cli([str(tmp_path / "poses.txt")])
    bag = tmp_path / "bare.mcap"
    write_rig_bag(bag, SCENES[0], with_scene=False)
    with pytest.raises(BagError, match="--fisheye-from-rgbd"):
        fe.bag_inputs(bag)
    assert run_cli([str(bag), "--fisheye-from-rgbd", "0", "-0.06", "-0.02", "-90", "0", "0"]) == 0
    with pytest.raises(BagError, match="0 rig"):
        fe.bag_inputs(_empty_bag(tmp_path))
    with pytest.raises(BagError, match="no topic 'rig/slam/pose'"):
        fe.bag_inputs(bag, pose_topic="rig/slam/pose", fisheye_from_rgbd=F)


def _empty_bag(tmp_path: Path) -> Path:
    path = tmp_path / "other.mcap"
    with BagWriter(path) as writer:
        msg = PoseStamped(Header(0, "world"), "x", np.eye(4))
        writer.write_frames(encode("cam/pose", msg, "cam", 0, seq=0), log_time_ns=0)
    return path
