"""``probeless pbgi render`` (probeless.pbgi.cli) on a small synthetic room."""

from __future__ import annotations

import json

import cv2
import numpy as np
import open3d as o3d
import pytest

from probeless.cli import main
from probeless.pbgi.bsh import synthetic_room

pytestmark = pytest.mark.gl
POSITION = ["1.0", "2.0", "1.5"]


@pytest.fixture(scope="module")
def room_ply(tmp_path_factory):
    """20k points of bsh.synthetic_room as an sRGB PLY without normals (they are estimated)."""
    pts, col, _ = synthetic_room(20_000)
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
    pcd.colors = o3d.utility.Vector3dVector(np.clip(col, 0, 1))
    path = tmp_path_factory.mktemp("pbgi_cli") / "room.ply"
    o3d.io.write_point_cloud(str(path), pcd)
    return path


def test_render_writes_a_png_lit_where_the_object_is_and_a_json_report(room_ply, tmp_path, capsys):
    out = tmp_path / "ball.png"
    args = ["pbgi", "render", str(room_ply), "-o", str(out), "--position", *POSITION, "--size", "64",
            "--micro", "16", "--json", "--no-progress", "--exr"]
    assert main(args) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["bsh"]["nodes"] > 0 and report["render"][0]["pixels"] == report["object_pixels"] > 500
    assert set(report["seconds"]) == {"read", "bsh", "render", "write"}
    img = cv2.imread(str(out))[..., ::-1]
    lit = img.max(axis=2) > 0
    # black background: the non-black pixels are the object's, as many as the G-buffer covered
    assert abs(int(lit.sum()) - report["object_pixels"]) <= 0.02 * report["object_pixels"]
    assert lit[32, 32] and not lit[0, 0]
    assert (tmp_path / "ball.exr").is_file()
    # the cloud behind it
    assert main(args[:-2] + ["--background", "cloud", "--mode", "envmap"]) == 0
    assert (cv2.imread(str(out)).max(axis=2) > 0).mean() > 0.9


@pytest.mark.parametrize("extra,message", [
    (["--material", "{type: glass}"], "glass"),
    (["--material", "{type: shiny}"], "shiny"),
    (["--material", "[1, 2]"], "expected a mapping"),
])
def test_bad_materials_are_reported(room_ply, tmp_path, capsys, extra, message):
    assert main(["pbgi", "render", str(room_ply), "-o", str(tmp_path / "x.png"), "--no-progress", *extra]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and message in err


def test_missing_cloud_is_reported(tmp_path, capsys):
    assert main(["pbgi", "render", str(tmp_path / "none.ply"), "-o", str(tmp_path / "x.png"), "--no-progress"]) == 2
    assert "point cloud file not found" in capsys.readouterr().err
