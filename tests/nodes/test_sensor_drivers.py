"""Fisheye player (image folder + stamps, video), OpenCV camera driver on a video file, RealSense error path.
References: OpenCV reading the same files independently, the stamps written by the test, the
OCamCalib file's own numbers."""

from __future__ import annotations

import time
from pathlib import Path

import cv2
import numpy as np
import pytest
from locations import SHARED_DATA

from probeless.datasets.capture import capture_frames, open_capture
from probeless.datasets.fisheye import fisheye_frames, open_fisheye
from probeless.datasets.framethread import FrameThread
from probeless.datasets.framethread import drain as drain_frames
from probeless.datasets.playback import drain
from probeless.errors import DatasetError, DeviceError
from probeless.nodes.sensors.fisheye_player import FisheyePlayer
from probeless.nodes.sensors.opencv_camera import OpenCvCamera
from probeless.nodes.sensors.realsense import RealSenseCamera
from probeless.runtime.params import load_params
from probeless.runtime.testing import RecordingContext

FISHEYE = SHARED_DATA / "fisheye" / "ocamcalib"
CALIB = FISHEYE / "calib_results_fisheye.txt"


def run_source(cls, params: dict, ctx: RecordingContext | None = None, timeout_s: float = 20.0):
    ctx = ctx or RecordingContext("src", cls)
    node = cls(ctx, load_params(cls.Params, params, node_id="src"))
    node.setup()
    try:
        drain(ctx.timers[0][1], ctx, timeout_s)
    finally:
        node.close()
    ctx.node = node
    return ctx


@pytest.fixture(scope="module")
def fisheye_folder(tmp_path_factory) -> tuple[Path, Path, list[float]]:
    """5 grey 1024x768 frames made from the real fisheye image, and a stamps file."""
    d = tmp_path_factory.mktemp("fisheye")
    img = cv2.imread(str(FISHEYE / "test_fisheye.jpg"), cv2.IMREAD_GRAYSCALE)
    assert img.shape == (768, 1024)
    for k in range(5):
        cv2.imwrite(str(d / f"img_{k * 5}.png"), np.roll(img, 13 * k, axis=1))  # 0, 5, 10: natural order
    stamps = [1700000000.0 + 0.1 * k + 0.003 * k * k for k in range(5)]
    stamps_file = d.parent / "stamps.txt"
    stamps_file.write_text("# seconds\n" + "".join(f"{s:.6f}\n" for s in stamps))
    return d, stamps_file, stamps


@pytest.fixture(scope="module")
def video(tmp_path_factory) -> Path:
    """A 12-frame 30 Hz MJPG video with moving content."""
    path = tmp_path_factory.mktemp("video") / "clip.avi"
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 30, (160, 120))
    yy, xx = np.mgrid[0:120, 0:160]
    for k in range(12):
        frame = np.stack([(xx * 1.5 + 10 * k) % 256, (yy * 2) % 256, np.full_like(xx, 20 * k)], -1).astype(np.uint8)
        w.write(frame)
    w.release()
    return path


def read_all(path: Path) -> list[np.ndarray]:
    cap = cv2.VideoCapture(str(path))
    frames = []
    while True:
        ok, f = cap.read()
        if not ok:
            return frames
        frames.append(f)


# --- fisheye player ---------------------------------------------------------------------------

def test_fisheye_folder_frames_stamps_and_calibration(fisheye_folder):
    folder, stamps_file, stamps = fisheye_folder
    ctx = run_source(FisheyePlayer, {"path": str(folder), "calibration": str(CALIB), "stamps": str(stamps_file),
                                     "time_offset_s": 0.5, "rate": 0})
    images, infos = ctx.outputs("fisheye"), ctx.outputs("fisheye/camera_info")
    assert len(images) == len(infos) == 5 and ctx.stopped
    for k, (im, info) in enumerate(zip(images, infos)):
        ref = cv2.imread(str(folder / f"img_{k * 5}.png"), cv2.IMREAD_UNCHANGED)
        assert im.encoding == "mono8"
        np.testing.assert_array_equal(im.data[:, :, 0], ref)
        want = round((stamps[k] + 0.5) * 1e9)
        assert abs(im.header.stamp_ns - want) < 1000 and info.header.stamp_ns == im.header.stamp_ns
        assert info.header.frame_id == im.header.frame_id == "fisheye"
    info = infos[0]
    assert (info.model, info.width, info.height) == ("ocam", 1024, 768)
    # the numbers as written in calib_results_fisheye.txt
    np.testing.assert_allclose(info.ocam_center, [381.777786, 505.480427])
    np.testing.assert_allclose(info.ocam_poly, [-5.517655e2, 0, 8.372454e-4, -6.474789e-7, 1.235631e-9])
    assert ctx.published[0][0] == "fisheye/camera_info"  # before the first frame


def test_fisheye_video_frames_equal_opencv(tmp_path):
    path = tmp_path / "fish.avi"
    img = cv2.imread(str(FISHEYE / "test_fisheye.jpg"))
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 15, (1024, 768))
    for k in range(4):
        w.write(np.roll(img, 20 * k, axis=0))
    w.release()
    footage = open_fisheye(path)
    got = list(fisheye_frames(footage))
    ref = read_all(path)
    assert len(got) == len(ref) == 4 and footage.fps == 15
    for k, ((stamp, data, enc), r) in enumerate(zip(got, ref)):
        assert enc == "rgb8" and stamp == round(k * 1e9 / 15)
        np.testing.assert_array_equal(data, r[:, :, ::-1])
    ctx = run_source(FisheyePlayer, {"path": str(path), "calibration": str(CALIB), "rate": 0, "color": "mono8"})
    np.testing.assert_array_equal(ctx.outputs("fisheye")[2].data[:, :, 0], cv2.cvtColor(ref[2], cv2.COLOR_BGR2GRAY))


def test_fisheye_errors(fisheye_folder, video, tmp_path):
    folder = fisheye_folder[0]
    with pytest.raises(DatasetError, match=r"calib_results_fisheye.txt.*clip.avi \(160x120 frames\)"):
        run_source(FisheyePlayer, {"path": str(video), "calibration": str(CALIB)})
    short = tmp_path / "short.txt"
    short.write_text("1.0\n2.0\n")
    with pytest.raises(DatasetError, match=r"short.txt: 2 stamp\(s\) but .* has 5 image\(s\)"):
        open_fisheye(folder, stamps=str(short))
    short.write_text("1.0\n0.5\n")
    with pytest.raises(DatasetError, match=r"short.txt:2: timestamp 0.5 is not after"):
        open_fisheye(folder, stamps=str(short))
    with pytest.raises(DatasetError, match="no such image folder or video file"):
        open_fisheye(tmp_path / "nothing")
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "a.png").write_bytes(b"garbage")
    with pytest.raises(DatasetError, match=r"a.png: cannot decode"):
        list(fisheye_frames(open_fisheye(bad)))


# --- OpenCV camera driver ---------------------------------------------------------------------

def test_capture_frames_equal_opencv_and_stamps_follow_the_file(video):
    cap = open_capture(str(video))
    got = list(capture_frames(cap, str(video), file=True, clock=lambda: 5_000_000_000))
    cap.release()
    ref = read_all(video)
    assert len(got) == len(ref) == 12
    for (stamp, frame), r in zip(got, ref):
        np.testing.assert_array_equal(frame, r)
    stamps = np.array([s for s, _ in got])
    np.testing.assert_allclose(stamps - 5_000_000_000, np.arange(12) * 1e9 / 30, atol=1e6)


def test_opencv_camera_node_on_a_video_file(video):
    t0 = time.time_ns()
    ctx = run_source(OpenCvCamera, {"device": str(video), "realtime": False, "frame_id": "cam"})
    images, ref = ctx.outputs("image"), read_all(video)
    assert len(images) == 12 and ctx.stopped and not ctx.outputs("camera_info")
    for im, r in zip(images, ref):
        assert im.encoding == "rgb8" and im.header.frame_id == "cam"
        np.testing.assert_array_equal(im.data, r[:, :, ::-1])
    stamps = np.array([im.header.stamp_ns for im in images])
    assert np.all(np.diff(stamps) > 0) and t0 <= stamps[0] <= time.time_ns()


def test_opencv_camera_realtime_pacing(video):
    ctx = run_source(OpenCvCamera, {"device": str(video)}, RecordingContext("src", OpenCvCamera))
    t = np.array(ctx.times()) - ctx.node.thread.pace_origin
    expected = np.arange(12) / 30
    assert len(t) == 12
    assert np.all(t >= expected - 0.001), t  # never early (lateness only from CPU load)
    assert t[-1] < expected[-1] + 0.3, t


def test_opencv_camera_errors(video, tmp_path):
    with pytest.raises(DeviceError, match=r"camera '/nonexistent/cam.mp4': cannot open"):
        run_source(OpenCvCamera, {"device": "/nonexistent/cam.mp4"})
    with pytest.raises(DeviceError, match=r"camera 97: cannot open"):
        run_source(OpenCvCamera, {"device": 97})
    with pytest.raises(DeviceError, match=r"gives 160x120 frames; calibration .*calib_results_fisheye.txt"):
        run_source(OpenCvCamera, {"device": str(video), "calibration": str(CALIB)})


class FailingDevice:
    """Stands in for a camera that delivers two frames, then fails (unplugged)."""

    def __init__(self):
        self.left = 2

    def grab(self) -> bool:
        self.left -= 1
        return self.left >= 0

    def retrieve(self):
        return True, np.zeros((4, 4, 3), np.uint8)


def test_live_capture_failure_names_the_device():
    frames = capture_frames(FailingDevice(), "/dev/video7", file=False)
    assert len([next(frames), next(frames)]) == 2
    with pytest.raises(DeviceError, match=r"camera '/dev/video7': stopped delivering frames .*after 2 frame"):
        next(frames)


def test_live_frame_thread_keeps_the_newest_frames():
    thread = FrameThread(iter([(k, k) for k in range(10)]), "t", buffer=2)
    thread.start()
    deadline = time.monotonic() + 5
    while thread.dropped < 8 and time.monotonic() < deadline:
        time.sleep(0.001)
    got: list[int] = []
    while not drain_frames(thread, lambda stamp, frame: got.append(frame)):
        time.sleep(0.001)
    assert got == [8, 9] and thread.dropped == 8


# --- RealSense --------------------------------------------------------------------------------

def test_realsense_without_device_raises_device_error():
    ctx = RecordingContext("rs", RealSenseCamera)
    node = RealSenseCamera(ctx, load_params(RealSenseCamera.Params, {}, node_id="rs"))
    with pytest.raises(DeviceError, match="RealSense: no device connected"):
        node.setup()
    node.close()
    assert not ctx.published
