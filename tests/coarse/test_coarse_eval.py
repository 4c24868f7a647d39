"""End to end on synthetic scenes: the texture against the scene's true surface colours (paper Figure 6
with and without Δ), the preview pictures, and the shipped coarse_model graph."""

from __future__ import annotations

import glob
import io
import json

import cv2
import numpy as np
import pytest
from locations import REPO

from probeless.coarse.atlas import fit_atlas
from probeless.coarse.evaluate import evaluate_scene, summarize, texel_errors
from probeless.coarse.model import INPAINTED_S
from probeless.coarse.truth import true_atlas
from probeless.launch.launcher import Launcher, load_checked
from probeless.scene.parse import load_scene
from probeless.scene.rig import Rig, expose

ROOT = REPO
SWITCH_S = 3.0  # light_switch.yaml turns its light on here


@pytest.fixture(scope="module")
def light_switch_runs():
    kw = dict(duration=4.6, every=1, stride=4, cube_size=192, show_progress=False)  # 18 frames, 6 after the switch
    return [evaluate_scene(ROOT / "launch/scenes/light_switch.yaml", use_delta=d, **kw) for d in (True, False)]


@pytest.mark.slow
@pytest.mark.gl
@pytest.mark.graph
def test_true_atlas_matches_a_pinhole_render_of_a_wall():
    # Independent reference: a pinhole camera in the room looking straight at wall 0's centre.
    scene = load_scene(ROOT / "launch/scenes/convex_room.yaml")
    rig = Rig(scene, envmaps=False)
    layout = fit_atlas(scene.floorplan, scene.ceiling_height, 256)
    scale = rig.light_scale(0.0)
    truth = true_atlas(rig.renderer, layout, scale, scene.fisheye.exposure)
    wall = layout.surfaces[0]
    centre = wall.origin + wall.u_axis * wall.size_m[0] / 2 + wall.v_axis * wall.size_m[1] / 2
    eye = centre + wall.normal * 1.5
    z, x = -wall.normal, wall.u_axis
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = np.stack([x, np.cross(z, x), z], axis=1), eye
    K = np.array([[200.0, 0, 32.0], [0, 200.0, 32.0], [0, 0, 1]])
    radiance, _ = rig.renderer.render_pinhole(T, K, 64, 64, scale)
    x0, y0, w, h = wall.rect
    d = layout.texels_per_m
    r = 2  # texels: the truth patch is 4 texels (4 / d metres) wide around the wall centre
    patch = truth[y0 + h // 2 - r:y0 + h // 2 + r, x0 + w // 2 - r:x0 + w // 2 + r].reshape(-1, 3).mean(axis=0)
    px = int(round(r / d * 200 / 1.5))  # the same extent in pinhole pixels (f = 200 px at 1.5 m)
    seen = expose(radiance, scene.fisheye.exposure)[32 - px:32 + px, 32 - px:32 + px].reshape(-1, 3).mean(axis=0)
    rig.release()
    np.testing.assert_allclose(patch * 255, seen, atol=4.0)


def test_texel_errors_classes():
    core = np.ones((2, 3), bool)
    seen = np.array([[1.0, 1.0, 0.5], [-1.0, INPAINTED_S, INPAINTED_S]], np.float32)
    truth = np.zeros((2, 3, 3), np.float32)
    rgb = np.zeros((2, 3, 3), np.float32)
    rgb[0, 2] = 0.1  # stale, 25.5 too bright
    rgb[1, 1:] = 0.2  # inpainted, 51 off
    e = texel_errors(rgb, seen, truth, core, 1.0)
    assert e["in_view"] == 0 and e["stale"] == pytest.approx(25.5) and e["inpainted"] == pytest.approx(51)
    assert e["stale_bias"] == pytest.approx(25.5) and e["observed_fraction"] == pytest.approx(0.5)


@pytest.mark.gl
@pytest.mark.graph
@pytest.mark.slow
def test_figure6_brightness_compensation(light_switch_runs):
    with_d, without = light_switch_runs
    before = [summarize(r, None) for r in (with_d, without)]
    assert before[0]["in_view_mean"] < 5  # texels in view match the truth to a few codes
    t = np.asarray(with_d.t_s)
    pre, post = t < SWITCH_S, t >= SWITCH_S
    for run in light_switch_runs:
        assert np.nanmean(run.series("stale")[pre]) < 4  # before the switch nothing changes out of view
    stale_with, stale_without = with_d.series("stale")[post], without.series("stale")[post]
    bias_with, bias_without = with_d.series("stale_bias")[post], without.series("stale_bias")[post]
    # without Δ the room out of view keeps its old, darker colours; with Δ it follows the light
    assert np.nanmean(stale_without) > 25 and np.nanmean(bias_without) < -20
    assert np.nanmean(stale_with) < 0.5 * np.nanmean(stale_without)
    assert abs(np.nanmean(bias_with)) < 0.4 * abs(np.nanmean(bias_without))
    assert max(d[0] for d in with_d.delta) > 20  # the switch frame's Δ in 0..255 codes


@pytest.mark.gl
@pytest.mark.graph
@pytest.mark.slow
def test_preview_writes_the_pictures(tmp_path):
    from probeless.cli import main

    out = tmp_path / "prev"
    assert main(["coarse", "preview", str(ROOT / "launch/scenes/partition_room.yaml"), "-o", str(out),
                 "--duration", "0.5", "--atlas-size", "256", "--no-progress"]) == 0
    names = {p.stem for p in out.glob("*.png")}
    assert names == {"atlas", "observed", "occlusion", "visibility", "filling", "model_overview", "model_inside",
                     "sheet"}
    occ = cv2.imread(str(out / "occlusion.png"))[..., ::-1]
    assert np.all(occ == (200, 40, 40), axis=2).sum() > 100  # the partition hides part of the room
    view = cv2.imread(str(out / "model_overview.png"))
    assert view.std() > 10


def test_every_shipped_graph_checks():
    for path in glob.glob(str(ROOT / "launch/*.yaml")):
        load_checked(path, {})


@pytest.mark.graph
@pytest.mark.slow
def test_shipped_coarse_graph_runs(tmp_path):
    graph = load_checked(str(ROOT / "launch/coarse_model.yaml"),
                         {"seconds": 0.5, "rate": 1.0, "atlas_size": 256, "out_dir": str(tmp_path)})
    out = io.StringIO()
    assert Launcher(graph, out=out).run() == 0, out.getvalue()
    log = out.getvalue()
    assert "'applied': 8" in log, log  # every fisheye frame in 0..0.5 s (0.013 + k/15) textured
    atlas = json.loads((tmp_path / "atlas/summary.json").read_text())
    assert atlas["frames"] == 8 and atlas["seq_gaps"] == 0
    assert (tmp_path / "coarse.mcap").stat().st_size > 0
