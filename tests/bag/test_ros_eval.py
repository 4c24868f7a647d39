"""`probeless eval slam` on 7-Scenes frames read from a ROS bag (imported) gives the dataset player's ATE."""

from __future__ import annotations

import json

import pytest

pytest.importorskip("rosbags")

from ros_bags import SEVEN, write_rig_bag  # noqa: E402

from probeless.bag.ros_import import import_bag  # noqa: E402
from probeless.cli import main  # noqa: E402

FRAMES = 4


def _ate(capsys, dataset) -> dict:
    assert main(["eval", "slam", str(dataset), "--max-frames", str(FRAMES), "--json", "--no-progress"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["frames"]["with_ground_truth"] == FRAMES
    return report["ate"]


@pytest.mark.slow
def test_eval_slam_from_a_ros_bag_matches_the_dataset_player(tmp_path, capsys):
    write_rig_bag(tmp_path / "in.bag", "ros1", frames=FRAMES, fisheye=1, compressed=True)
    import_bag(tmp_path / "in.bag", tmp_path / "run.mcap", preset="realsense",
               maps=["/ground_truth/pose=rig/gt/rgbd_pose"])
    from_bag, from_dataset = _ate(capsys, tmp_path / "run.mcap"), _ate(capsys, SEVEN)
    assert from_bag["n"] == from_dataset["n"] == FRAMES
    assert abs(from_bag["rmse"] - from_dataset["rmse"]) < 1e-4   # 0.1 mm
