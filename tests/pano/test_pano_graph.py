"""launch/pano360_ibl.yaml end to end on the shipped 360° video: a few small frames."""

from __future__ import annotations

import io

import cv2
import numpy as np
import pytest
from locations import REPO

from probeless.launch.launcher import Launcher, load_checked
from probeless.nodes.pano.compositor import PanoCompositor
from probeless.pano.view import head_pose, view_equirect

pytestmark = [pytest.mark.graph, pytest.mark.slow]

ROOT = REPO
VIDEO = ROOT.parent / "shared/data/video360/bled_lake_360_timelapse_720p_vp9.webm"


def test_graph_writes_a_composited_video_of_the_360_frames(tmp_path):
    args = {"video": str(VIDEO), "frames": 3, "width": 96, "height": 54, "out_dir": str(tmp_path)}
    log = io.StringIO()
    assert Launcher(load_checked(str(ROOT / "launch/pano360_ibl.yaml"), args), out=log).run() == 0, log.getvalue()
    cap = cv2.VideoCapture(str(tmp_path / "pano360.mp4"))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 3
    last = cv2.imread(str(tmp_path / "pano360_last.png"))[..., ::-1].astype(int)
    assert last.shape == (54, 96, 3)

    src = cv2.VideoCapture(str(VIDEO))
    for _ in range(3):
        ok, frame = src.read()
    p = PanoCompositor.Params()
    t = 2 / src.get(cv2.CAP_PROP_FPS)
    head = head_pose(t, yaw0_deg=p.yaw0_deg, yaw_deg_per_s=p.yaw_deg_per_s, pitch_deg=p.pitch_deg,
                     pitch_amp_deg=p.pitch_amp_deg, pitch_period_s=p.pitch_period_s)
    view = view_equirect(np.ascontiguousarray(frame[..., ::-1]), head, p.fov_deg, 96, 54).astype(int)
    diff = np.abs(last - view).max(axis=-1)
    assert np.percentile(diff[:10], 99) <= 3          # the sky above the objects: the view of the frame
    assert (diff[20:40, 20:76] > 20).mean() > 0.1     # the objects in front of the viewer
