"""Fault injection: bad sensor data. Frames of the wrong size or encoding mid-stream, NaN and all-zero
depth, a video file that is cut short or unreadable, and a camera that stalls.

Each fault must be reported naming the node, and the node either resumes or ends with one clear
error line: never a traceback, never a hang (every launch runs under a timeout).
"""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
from faults_common import launch_graph, write_graph

from probeless.errors import DeviceError

W, H = 320, 240
FAULTS = {"wrong_size": 10, "wrong_encoding": 14, "nan_depth": 18, "zero_depth": 22}
PERIOD_NS = 33_333_000


@pytest.mark.graph
@pytest.mark.slow
def test_slam_reports_each_bad_frame_and_keeps_tracking(tmp_path):
    faults = ", ".join(f"{k}: [{v}]" for k, v in FAULTS.items())
    g = write_graph(tmp_path, f"""
nodes:
  - id: cam
    node: injectors:BadCamera
    inputs: {{tick: timer/hz/15}}
    outputs: [rgb, depth, camera_info]
    params: {{count: 30, width: {W}, height: {H}, period_ms: 33.333, {faults}}}
  - id: slam
    node: dense_slam
    inputs:
      rgb: {{source: cam/rgb, policy: block, queue_size: 4}}
      depth: {{source: cam/depth, policy: block, queue_size: 4}}
      camera_info: {{source: cam/camera_info, policy: block, queue_size: 4}}
    outputs: [pose, tracking]
    params: {{model_output: none, depth_weighting: false}}
  - id: log
    node: injectors:StampLog
    inputs:
      tracking: {{source: slam/tracking, policy: block, queue_size: 8}}
      pose: {{source: slam/pose, policy: block, queue_size: 8}}
    params: {{out: {tmp_path}/log.json}}
""")
    code, log = launch_graph(g, timeout_s=240)
    assert code == 0, log
    assert "Traceback" not in log
    states = {s[0]: s for s in json.loads((tmp_path / "log.json").read_text())["tracking"]}
    assert len(states) == 30  # every frame got a state: none crashed the node or vanished
    why = {k: states[v * PERIOD_NS] for k, v in FAULTS.items()}
    assert all(s[1] == "invalid_input" for s in why.values()), why
    assert "(120, 160" in why["wrong_size"][2] and "float32" in why["wrong_encoding"][2]
    assert "valid depth" in why["nan_depth"][2] and "valid depth" in why["zero_depth"][2]
    # reported with the node id, once per run of failures
    assert log.count("[slam] WARNING slam: frame ") == len(FAULTS)
    # tracking resumes after every fault
    for k in FAULTS.values():
        assert states[(k + 1) * PERIOD_NS][1] == "ok", states[(k + 1) * PERIOD_NS]
    assert sum(s[1] == "ok" for s in states.values()) == 30 - len(FAULTS)


@pytest.mark.graph
def test_undistort_ends_with_one_clear_error_on_a_frame_of_the_wrong_size(tmp_path):
    g = write_graph(tmp_path, f"""
nodes:
  - id: cam
    node: injectors:BadCamera
    inputs: {{tick: timer/hz/50}}
    outputs: [camera_info, fisheye]
    params: {{count: 20, width: {W}, height: {H}, wrong_size: [6]}}
  - id: undistort
    node: fisheye_undistort
    inputs:
      image: {{source: cam/fisheye, policy: block, queue_size: 4}}
      camera_info: {{source: cam/camera_info, policy: block, queue_size: 4}}
    outputs: [image, camera_info]
    params: {{target: omnidir, width: 64, height: 64, fov_deg: 120.0}}
  - id: log
    node: injectors:StampLog
    inputs: {{image: {{source: undistort/image, policy: block, queue_size: 8}}}}
    params: {{out: {tmp_path}/log.json}}
""")
    code, log = launch_graph(g, timeout_s=120)
    assert code == 1, log
    assert "Traceback" not in log
    assert (f"[undistort] ERROR undistort: node 'undistort': CalibrationError: image {W // 2}x{H // 2} does not match "
            f"camera_info {W}x{H}") in log
    assert "graph stopped: node(s) failed: undistort" in log
    got = json.loads((tmp_path / "log.json").read_text())["image"]
    assert [g[0] for g in got] == [k * PERIOD_NS for k in range(6)]  # the frames before the bad one went through


def _write_video(path: Path, fourcc: str, n: int = 30) -> list[np.ndarray]:
    """n 64x48 frames (brightness 8k, a white bar at column 2k), written with cv2.VideoWriter; returns them."""
    frames = []
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*fourcc), 30.0, (64, 48))
    for k in range(n):
        f = np.full((48, 64, 3), 8 * k, np.uint8)
        f[:, 2 * k:2 * k + 4] = 255
        writer.write(f)
        frames.append(f)
    writer.release()
    return frames


def _camera_graph(tmp_path: Path, video: Path) -> Path:
    return write_graph(tmp_path, f"""
nodes:
  - id: cam
    node: opencv_camera
    outputs: [image]
    params: {{device: {video}, realtime: false}}
  - id: log
    node: injectors:StampLog
    inputs: {{image: {{source: cam/image, policy: block, queue_size: 8}}}}
    params: {{out: {tmp_path}/log.json}}
""")


@pytest.mark.graph
def test_opencv_camera_on_a_truncated_avi_publishes_the_readable_prefix_and_says_so(tmp_path):
    video = tmp_path / "cut.avi"
    frames = _write_video(video, "MJPG")
    data = video.read_bytes()
    video.write_bytes(data[:len(data) // 2])
    code, log = launch_graph(_camera_graph(tmp_path, video), timeout_s=120)
    assert code == 0, log
    assert "Traceback" not in log
    got = json.loads((tmp_path / "log.json").read_text())["image"]
    assert 0 < len(got) < 30
    assert f"[cam] WARNING cam: camera '{video}': the file ended after {len(got)} of the 30 frame(s)" in log
    # what was published is the file's prefix: frame k is the k-th frame written (decoded with OpenCV here)
    cap = cv2.VideoCapture(str(video))
    for k in range(len(got)):
        ok, frame = cap.read()
        assert ok and np.abs(frame.astype(int) - frames[k]).mean() < 4.0


@pytest.mark.graph
def test_opencv_camera_on_a_cut_mp4_ends_with_one_clear_error(tmp_path):
    video = tmp_path / "cut.mp4"
    _write_video(video, "mp4v")
    video.write_bytes(video.read_bytes()[:2000])  # the index (moov atom) is at the end: the file cannot be opened
    code, log = launch_graph(_camera_graph(tmp_path, video), timeout_s=120)
    assert code == 1, log
    assert "Traceback" not in log
    assert f"[cam] ERROR cam: node 'cam': DeviceError: camera '{video}': cannot open" in log


class StallingCapture:
    """A cv2.VideoCapture stand-in: ``n`` frames, then ``grab()`` blocks until released (a stalled stream)."""

    def __init__(self, n: int):
        self.n, self.k = n, 0
        self.release_event = threading.Event()

    def get(self, prop):
        return {cv2.CAP_PROP_FRAME_WIDTH: 64, cv2.CAP_PROP_FRAME_HEIGHT: 48}.get(prop, 0.0)

    def grab(self) -> bool:
        if self.k >= self.n:
            self.release_event.wait(60)
            return False
        self.k += 1
        return True

    def retrieve(self):
        return True, np.full((48, 64, 3), self.k, np.uint8)

    def release(self):
        self.release_event.set()


def test_a_stalled_live_camera_ends_with_a_clear_error_within_its_timeout(monkeypatch):
    from probeless.nodes.sensors import opencv_camera
    from probeless.runtime.params import load_params
    from probeless.runtime.testing import RecordingContext

    cap = StallingCapture(5)
    monkeypatch.setattr(opencv_camera, "open_capture", lambda device, settings: cap)
    ctx = RecordingContext("cam", opencv_camera.OpenCvCamera)
    node = opencv_camera.OpenCvCamera(ctx, load_params(opencv_camera.OpenCvCamera.Params,
                                                       {"device": 0, "timeout_s": 0.5, "buffer": 10}, node_id="cam"))
    node.setup()
    t0 = time.monotonic()
    with pytest.raises(DeviceError, match=r"camera 0: no frame for 0.5 s"):
        while time.monotonic() - t0 < 10:
            node.poll()
            time.sleep(0.01)
    stalled_after = time.monotonic() - t0
    assert len(ctx.outputs("image")) == 5  # the frames before the stall were published
    assert 0.5 <= stalled_after < 3.0
    t1 = time.monotonic()
    node.close()  # never waits for the stuck read for more than its join bound
    assert time.monotonic() - t1 < 3.0
    cap.release()
