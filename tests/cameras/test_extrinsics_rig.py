"""``probeless calibrate extrinsics`` on the synthetic rig's own renders (convex_room, moving rig,
fisheye 13 ms after the RGB-D camera) recovers the scene file's fisheye_from_rgbd within 0.5 deg and 5 mm."""

from __future__ import annotations

import numpy as np
import pytest
from locations import REPO

from probeless.cameras.extrinsics import load_extrinsics, rotation_error_deg
from probeless.cli import main as cli
from probeless.scene.parse import load_scene

pytestmark = [pytest.mark.gl, pytest.mark.graph, pytest.mark.slow]

ROOT = REPO
SCENE = ROOT / "launch/scenes/convex_room.yaml"


def test_extrinsics_from_rendered_rig_sequence(tmp_path):
    bag, out = tmp_path / "rig.mcap", tmp_path / "extrinsics.yaml"
    assert cli(["scene", "render", str(SCENE), "-o", str(bag), "--duration", "0.5", "--no-envmaps"]) == 0
    assert cli(["calibrate", "extrinsics", "--bag", str(bag), "--pairs", "6", "-o", str(out), "--no-progress"]) == 0
    truth = load_scene(SCENE).fisheye_from_rgbd
    T = load_extrinsics(out)
    assert rotation_error_deg(T[:3, :3], truth[:3, :3]) < 0.5
    assert np.linalg.norm(T[:3, 3] - truth[:3, 3]) < 0.005
