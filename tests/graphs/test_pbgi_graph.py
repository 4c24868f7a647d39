"""launch/pbgi.yaml end to end: both sources, PNGs of both renderers, and the colour bleeding PBGI adds."""

from __future__ import annotations

import io

import cv2
import numpy as np
import pytest
from locations import REPO

from probeless.color import from_srgb8


def _launch(args: dict) -> str:
    from probeless.launch.launcher import Launcher, load_checked

    log = io.StringIO()
    graph = load_checked(str(REPO / "launch/pbgi.yaml"), args)
    assert Launcher(graph, out=log).run() == 0, log.getvalue()
    return log.getvalue()


def _rgb(path) -> np.ndarray:
    img = cv2.imread(str(path))
    assert img is not None, path
    return img[..., ::-1]


@pytest.mark.parametrize("source", ["synthetic", "fragment"])
def test_check_passes_for_each_source(source):
    from probeless.launch.launcher import load_checked

    assert len(load_checked(str(REPO / "launch/pbgi.yaml"), {"source": source}).nodes) == 6


@pytest.mark.graph
@pytest.mark.slow
@pytest.mark.gl
def test_fragment_source_writes_both_renderers_pngs(tmp_path):
    log = _launch({"source": "fragment", "frames": 2, "render_size": 160, "out_dir": str(tmp_path)})
    for name in ("pbgi", "envmap"):
        files = sorted((tmp_path / name).glob("frame_*.png"))
        assert [f.name for f in files] == ["frame_000000.png", "frame_000001.png", "frame_last.png"]
        assert _rgb(files[0]).shape == (480, 640, 3)
    assert log.count("'frames': 2") == 2, log
    a, b = _rgb(tmp_path / "pbgi/frame_last.png"), _rgb(tmp_path / "envmap/frame_last.png")
    assert np.any(a != b, axis=2).sum() > 1000  # the object, lit two ways


@pytest.mark.graph
@pytest.mark.slow
@pytest.mark.gl
def test_synthetic_source_pbgi_bleeds_more_red_than_the_envmap_on_the_side_facing_the_panel(tmp_path):
    """red_wall: at the end of 3 s the camera sees the sphere's side facing the red panel on the image's left."""
    _launch({"source": "synthetic", "rate": 0, "out_dir": str(tmp_path)})  # lockstep: the same model under load
    pbgi, env = _rgb(tmp_path / "pbgi/frame_last.png"), _rgb(tmp_path / "envmap/frame_last.png")
    obj = np.any(pbgi != env, axis=2)
    cols = np.nonzero(obj.any(axis=0))[0]
    assert obj.sum() > 2000 and cols[-1] - cols[0] > 40
    left = obj.copy()
    left[:, cols[0] + (cols[-1] - cols[0]) // 3:] = False

    def red_excess(img):  # linear red beyond white: the red light the panel sends
        lin = from_srgb8(img[left])
        return float(np.mean(lin[:, 0] - lin[:, 1:].mean(axis=1)))

    # PBGI / envmap was 1.075 with the old voxel (nearest-neighbour spacing); with the default voxel of 0.45 x the
    # point spacing (probeless.pbgi.bsh.VOXEL_PER_SPACING, chosen against Mitsuba on grid clouds) it is 1.016-1.035
    # over four runs on this live SLAM model (issue 27's note: a known loss of bleeding, not yet explained)
    assert red_excess(pbgi) > red_excess(env) > 0.02, (red_excess(pbgi), red_excess(env))
