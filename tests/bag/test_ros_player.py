"""The rosbag_player node's stream: a main bag merged with a fisheye from a second bag or a video, clock offset
applied, floorplan first and the initial pose with the first colour frame (no processes: the node's own
stream, as its read-ahead thread consumes it)."""

from __future__ import annotations

from types import SimpleNamespace

import cv2
import numpy as np
import pytest

pytest.importorskip("rosbags")

from locations import SHARED_DATA  # noqa: E402
from ros_bags import write_rig_bag  # noqa: E402

from probeless.bag.ros_source import RosBag  # noqa: E402
from probeless.nodes.bag.rosbag_player import RosbagPlayer, load_floorplan  # noqa: E402

OCAM = SHARED_DATA / "fisheye" / "ocamcalib"


def _player(tmp_path, **params) -> RosbagPlayer:
    p = RosbagPlayer.__new__(RosbagPlayer)   # the stream only: no runtime context
    defaults = dict(fisheye_offset_s=0.0, topics=())
    p.params = SimpleNamespace(**{**defaults, **params})
    p.bag = RosBag(params["path"], "realsense", ["/ground_truth/pose=rig/gt/rgbd_pose"], only=None)
    p.fisheye_bag = p.video = p.floorplan = p.pose0 = None
    return p


def test_fisheye_from_a_second_bag_with_a_clock_offset(tmp_path):
    write_rig_bag(tmp_path / "rs", "mcap", frames=2, fisheye=1)
    wrote = write_rig_bag(tmp_path / "fish.bag", "ros1", frames=1, fisheye=2)
    p = _player(tmp_path, path=tmp_path / "rs")
    p.fisheye_bag = RosBag(tmp_path / "fish.bag", "usb_cam", (), only=["rig/fisheye", "rig/fisheye/camera_info"],
                           time_offset_ns=5_000_000)
    items = list(p._items(p.bag.start_ns, None))
    times = [i.log_time_ns for i in items]
    assert times == sorted(times)
    fish = [i.msg.header.stamp_ns for i in items if i.topic == "rig/fisheye"]
    # the second bag's two frames, shifted by 5 ms, replace the main bag's own fisheye
    assert fish == [f["stamp"] + 5_000_000 for f in wrote["fisheye"]]


def test_video_fisheye_floorplan_and_initial_pose(tmp_path):
    write_rig_bag(tmp_path / "rs", "mcap", frames=2, fisheye=1)
    img = cv2.imread(str(OCAM / "test_fisheye.jpg"))
    vw = cv2.VideoWriter(str(tmp_path / "f.avi"), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, img.shape[1::-1])
    for _ in range(3):
        vw.write(img)
    vw.release()
    (tmp_path / "room.yaml").write_text("room:\n  floorplan: [[0, 0], [5, 0], [5, 4], [0, 4]]\n  ceiling_height: 2.6\n")
    p = _player(tmp_path, path=tmp_path / "rs", fisheye_video=str(tmp_path / "f.avi"),
                fisheye_calibration=str(OCAM / "calib_results_fisheye.txt"), fisheye_offset_s=0.01)
    p.video = p._open_video()
    p.floorplan = load_floorplan(str(tmp_path / "room.yaml"))
    p.pose0 = np.eye(4)
    items = list(p._items(p.bag.start_ns, None))
    assert items[0].topic == "rig/floorplan" and np.array_equal(items[0].msg.vertices, [[0, 0], [5, 0], [5, 4], [0, 4]])
    video = [i for i in items if i.topic == "rig/fisheye"]
    assert all(i.msg.data.shape[:2] == img.shape[:2] for i in video)   # the video replaces the bag's fisheye
    assert [i.msg.header.stamp_ns - p.bag.start_ns for i in video] == [10_000_000, 110_000_000, 210_000_000]
    infos = [i.msg for i in items if i.topic == "rig/fisheye/camera_info"]
    assert len(infos) == 3 and all(m.model == "ocam" for m in infos)
    info = infos[0]
    assert (info.width, info.height) == (img.shape[1], img.shape[0])
    first_rgb = next(k for k, i in enumerate(items) if i.topic == "rig/rgb")
    # the bag's ground truth comes through; the initial pose is published just before the first colour frame
    before = items[first_rgb - 1]
    assert before.topic == "rig/gt/rgbd_pose" and np.array_equal(before.msg.target_from_source, np.eye(4))
