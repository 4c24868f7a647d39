"""End to end: a realsense-ros-style bag (colour, aligned depth, camera_info, tf_static) plus a fisheye topic
runs through `launch/probeless.yaml source:=rosbag` and augmented frames come out (one real launch)."""

from __future__ import annotations

import subprocess
import sys

import cv2
import numpy as np
import pytest

pytest.importorskip("rosbags")

from locations import REPO  # noqa: E402
from ros_bags import write_rig_bag  # noqa: E402

FRAMES = 4


@pytest.mark.graph
@pytest.mark.slow
def test_rosbag_source_runs_the_full_pipeline(tmp_path):
    wrote = write_rig_bag(tmp_path / "rs", "mcap", frames=FRAMES, fisheye=2, compressed=True)
    (tmp_path / "room.yaml").write_text("floorplan: [[-4, -4], [4, -4], [4, 4], [-4, 4]]\nceiling_height: 3.0\n")
    # a mirror sphere 1.1 m in front of the first 7-Scenes camera (camera-to-world pose of frame 0)
    pose = wrote["seven"][0]["pose"]
    centre = pose[:3, :3] @ np.array([0.0, 0.0, 1.1]) + pose[:3, 3]
    (tmp_path / "objects.yaml").write_text(
        f"objects:\n  - {{id: sphere, mesh: sphere, position: {centre.round(3).tolist()}, radius: 0.15}}\n")
    out = tmp_path / "pipe"
    proc = subprocess.run(
        [sys.executable, "-m", "probeless.cli", "launch", "launch/probeless.yaml", "source:=rosbag",
         f"bag:={tmp_path / 'rs'}", f"floorplan:={tmp_path / 'room.yaml'}", f"objects:={tmp_path / 'objects.yaml'}",
         "ros_map:=[/ground_truth/pose=rig/gt/rgbd_pose]", f"out_dir:={out}", "rate:=0", "atlas_size:=256"],
        cwd=REPO, capture_output=True, text=True, timeout=400)
    assert proc.returncode == 0, proc.stderr[-3000:]
    log = proc.stdout + proc.stderr
    assert "played" in log and "skipping /camera/status" in log   # the unnamed topic is listed as skipped
    cap = cv2.VideoCapture(str(out / "augmented.mp4"))
    frames = []
    while True:
        ok, img = cap.read()
        if not ok:
            break
        frames.append(img)
    assert len(frames) == FRAMES
    last = cv2.imread(str(out / "augmented_last.png"))[:, :, ::-1]
    source = wrote["seven"][-1]["rgb"]
    # the sphere covers the middle of the image: it changed there, and not at the border
    diff = np.abs(last.astype(int) - source.astype(int)).max(axis=2)
    assert (diff[200:280, 280:360] > 40).mean() > 0.5
    assert (diff[:40, :] > 40).mean() < 0.01
