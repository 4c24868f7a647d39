"""Shipped sensor graphs run end to end: a TUM folder (converted from real 7-Scenes frames) played
through launch/play_rgbd_dataset.yaml."""

from __future__ import annotations

import io
import json

import cv2
import numpy as np
import pytest
from locations import REPO

from probeless.cli import main as cli
from probeless.launch.launcher import Launcher, load_checked

pytestmark = [pytest.mark.graph]

ROOT = REPO
SEVEN = ROOT.parent / "shared/data/rgbd/sevenscenes_kinect_0000-0399"


@pytest.mark.slow
def test_tum_folder_plays_through_the_shipped_graph(tmp_path):
    tum = tmp_path / "tum"
    assert cli(["dataset", "convert", str(SEVEN), str(tum), "--format", "tum", "--max-frames", "12"]) == 0
    assert (tum / "rgb.txt").is_file() and (tum / "depth.txt").is_file() and (tum / "groundtruth.txt").is_file()
    graph = load_checked(str(ROOT / "launch/play_rgbd_dataset.yaml"),
                         {"path": str(tum), "rate": 0, "out_dir": str(tmp_path / "out")})
    out = io.StringIO()
    assert Launcher(graph, out=out).run() == 0, out.getvalue()
    summary = json.loads((tmp_path / "out/rgb/summary.json").read_text())
    assert (summary["frames"], summary["seq_gaps"]) == (12, 0)
    last = cv2.imread(str(tmp_path / "out/rgb/last_frame.png"))
    original = cv2.imread(str(SEVEN / "frame-000011.color.jpg"))
    assert np.array_equal(last, original)  # the 12th frame, bit-exact through convert, player and bus
