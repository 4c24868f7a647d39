"""Smoke test of ``probeless bench coarse`` on a small atlas: one JSON object with consistent, sane figures."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest
from bench_checks import one_json_object, positive
from locations import REPO

from probeless.bench.coarse import NODE_PARAMS, SCENE, main, node_estimate, print_table
from probeless.bench.coarse_numba import estimate_delta_numba
from probeless.cameras.omnidir import OmnidirModel
from probeless.coarse.atlas import fit_atlas
from probeless.coarse.brightness import draw_sample, estimate_delta, estimate_delta_serial
from probeless.coarse.model import CoarseConfig, make_layout
from probeless.coarse.texels import texel_map
from probeless.errors import SchemaError
from probeless.messages.geometry import Floorplan, PoseStamped
from probeless.messages.header import Header
from probeless.messages.sensor import Image
from probeless.nodes.coarse.brightness import BrightnessEstimator
from probeless.runtime.params import load_params
from probeless.runtime.testing import RecordingContext
from probeless.scene.parse import load_scene

ROOT = REPO
STAGES = {"occlusion", "texture_update", "brightness_all", "brightness_sampled", "brightness_numba_all",
          "inpaint_amortised", "inpaint_full", "readback_rgba8"}


@pytest.fixture(scope="module")
def result() -> dict:
    """One small in-process run: 256 x 256 atlas, 3 frames, Δ sampled with 8000 of its texels."""
    return one_json_object(lambda: main(json_out=True, atlas_size=256, frames=3, sample_texels=8000,
                                        show_progress=False))


@pytest.mark.gl
@pytest.mark.graph
@pytest.mark.slow
def test_keys_and_layout(result):
    assert {"scene", "frames", "atlas", "timings_ms", "brightness", "inpaint", "goals", "goals_met",
            "meets_goals"} <= set(result)
    assert set(result["timings_ms"]) == STAGES
    scene = load_scene(SCENE)
    layout = fit_atlas(scene.floorplan, scene.ceiling_height, 256)
    a = result["atlas"]
    assert (a["width"], a["height"]) == (layout.width, layout.height)
    assert a["core_texels"] == int(texel_map(layout).core.sum()) == result["brightness"]["all_texels"]
    assert result["frames"] == 3 and result["warmup_frames"] == 1


@pytest.mark.gl
@pytest.mark.graph
@pytest.mark.slow
def test_timings_positive_finite(result):
    for name, s in result["timings_ms"].items():
        for k in ("mean", "p50", "p95"):
            assert positive(s[k]), (name, k)
        assert s["n"] == (3 if name == "inpaint_full" else 2), name  # frame 0 is the warm-up


@pytest.mark.gl
@pytest.mark.graph
@pytest.mark.slow
def test_reference_does_the_same_work(result):
    """The numba loop and the vectorised estimate: same texels, same Δ from the same texel count (the gate)."""
    b = result["brightness"]
    assert "numba" in b["brightness_reference"] and b["reference_texels"] == b["all_texels"]
    assert b["numba_vs_vectorised_texels_equal"] is True
    assert 0 <= b["numba_vs_vectorised_max_abs_diff"] <= b["agreement_gate"]["max_abs_diff_max"]
    assert b["agreement_gate_met"] is True and result["goals_met"]["agreement_gate"] is True
    assert b["texels_used_mean"] > 0  # the frames overlap the atlas seen before: Δ is not trivially 0


@pytest.mark.gl
@pytest.mark.graph
@pytest.mark.slow
def test_sampled_estimate_against_all_texels(result):
    b = result["brightness"]
    assert b["sample_texels"] == 8000 < b["all_texels"]  # the sampled estimate really is sampled
    assert "all core texels" in b["sampled_reference"]
    assert math.isfinite(b["sampled_error_max"]) and 0 <= b["sampled_error_mean"] <= b["sampled_error_max"] < 2.0
    # the headline is the sampled estimate (what the node runs), gated on its error in the same run
    assert "brightness_sampled" in b["speedup_definition"] and "node" in b["speedup_definition"]
    assert b["sample_gate_met"] is (b["sampled_error_max"] <= b["sample_gate"]["sampled_error_max_max"])
    assert result["goals_met"]["sample_gate"] is b["sample_gate_met"]
    assert positive(b["brightness_full_speedup"]) and "brightness_all" in b["full_speedup_definition"]


@pytest.mark.gl
@pytest.mark.graph
@pytest.mark.slow
def test_table_renders(result, capsys):
    print_table(result)
    out = capsys.readouterr().out
    assert "occlusion" in out and "brightness_numba_all" in out and "256x256 atlas" in out


def _synthetic_inputs(tm=None):
    """A non-convex room's texel map, a random RGBA8 atlas's RGB view (what the bench passes), a random frame,
    a fisheye inside the room looking along +x (no GL)."""
    scene = load_scene(SCENE)
    tm = tm or texel_map(fit_atlas(scene.floorplan, scene.ceiling_height, 256))
    rng = np.random.default_rng(0)
    atlas = rng.integers(25, 230, tm.core.shape + (4,), dtype=np.uint8)[..., :3]
    pose = np.eye(4)
    pose[:3, :3] = np.column_stack([(0, -1, 0), (0, 0, -1), (1, 0, 0)])
    pose[:3, 3] = [1.5, 3.0, 1.5]
    image = rng.integers(3, 250, (256, 256, 3), dtype=np.uint8)
    args = (atlas, rng.random(tm.core.shape) < 0.7, tm, image, OmnidirModel.from_fov(256, 256, 185.0), pose,
            185.0, scene.floorplan)
    return args, tm


def test_numba_reference_equals_the_python_serial_loop_and_the_vectorised_estimate():
    """The bench's compiled reference against the paper's plain Python loop (independent code) on the
    same texels, and against the vectorised estimate on all of them."""
    args, tm = _synthetic_inputs()
    sample = draw_sample(tm, 3000, seed=1)
    d_nb, n_nb = estimate_delta_numba(*args, sample_idx=sample)
    d_py, n_py = estimate_delta_serial(*args, sample_idx=sample)
    assert n_nb == n_py > 200
    np.testing.assert_allclose(d_nb, d_py, atol=1e-6)
    everything = draw_sample(tm)
    d_nb, n_nb = estimate_delta_numba(*args, sample_idx=everything)
    d_vec, n_vec = estimate_delta(*args, sample_idx=everything)
    assert n_nb == n_vec > 2000
    np.testing.assert_allclose(d_nb, d_vec, atol=1e-6)


def test_numba_reference_rejects_a_distorted_model():
    args, tm = _synthetic_inputs()
    distorted = OmnidirModel(256, 256, np.array([[100.0, 0, 128], [0, 100, 128], [0, 0, 1]]), 1.0,
                             np.array([0.1, 0.0, 0.0, 0.0]))
    with pytest.raises(SchemaError, match="ideal omnidir"):
        estimate_delta_numba(*args[:4], distorted, *args[5:], sample_idx=draw_sample(tm, 10))


@pytest.mark.graph
@pytest.mark.slow
@pytest.mark.timeout(120)
def test_script_prints_one_json_object():
    cmd = [sys.executable, "-m", "probeless.bench.coarse", "--json", "--atlas-size", "128", "--frames", "2"]
    proc = subprocess.run(cmd, check=False, capture_output=True, text=True, cwd=ROOT, timeout=110)
    assert proc.returncode == 0, proc.stderr
    r = json.loads(proc.stdout)
    assert proc.stdout.strip().count("\n") == 0
    assert r["frames"] == 2 and r["atlas"]["width"] == 128 and "numba" in r["brightness"]["brightness_reference"]


def test_bench_times_what_the_node_runs():
    """The sampled estimate the bench times is the brightness_estimator node's own computation: its default
    params, its rgba8 atlas, the same Δ and texel count as the node publishes (non-convex room, so the
    node's occlusion offset matters)."""
    defaults = BrightnessEstimator.Params()
    assert {k: getattr(defaults, k) for k in NODE_PARAMS} == NODE_PARAMS
    scene = load_scene(SCENE)
    params = {"atlas_size": 128, "samples": 4000, "fov_deg": 185.0, "deadband": 0.0}
    layout = make_layout(scene.floorplan, scene.ceiling_height, CoarseConfig(128))
    tm = texel_map(layout)
    (_, _, _, image, camera, pose, _, _), _ = _synthetic_inputs(tm)
    rng = np.random.default_rng(3)
    rgba = np.concatenate([rng.integers(25, 230, tm.core.shape + (3,), dtype=np.uint8),
                           np.where(rng.random(tm.core.shape + (1,)) < 0.7, 255, 0).astype(np.uint8)], axis=2)
    ctx = RecordingContext("brightness", BrightnessEstimator)
    node = BrightnessEstimator(ctx, load_params(BrightnessEstimator.Params, {**NODE_PARAMS, **params},
                                                node_id="brightness"))
    node.setup()
    feed = [("camera_info", camera.to_camera_info("fisheye", 0)),
            ("floorplan", Floorplan(Header(0, "world"), scene.floorplan, scene.ceiling_height)),
            ("fisheye", Image(Header(100, "fisheye"), image, "rgb8")),
            ("fisheye_pose", PoseStamped(Header(100, "world"), "fisheye", pose)),
            ("atlas", Image(Header(100, "world"), rgba, "rgba8")),
            ("fisheye", Image(Header(200, "fisheye"), image, "rgb8")),
            ("fisheye_pose", PoseStamped(Header(200, "world"), "fisheye", pose))]
    for name, msg in feed:
        node.on_input(name, msg)
    published = ctx.outputs("delta")[-1]
    assert published.header.stamp_ns == 200 and published.sampled and published.texels_used > 300
    sample = draw_sample(tm, params["samples"], NODE_PARAMS["seed"])
    delta, used = node_estimate(rgba, tm, image, camera, pose, params["fov_deg"], layout, sample)
    assert used == published.texels_used
    np.testing.assert_array_equal(delta, published.delta)
    # the node's settings matter here: estimate_delta's own defaults count other texels
    _, used_defaults = estimate_delta(rgba[..., :3], rgba[..., 3] > 0, tm, image, camera, pose, 185.0,
                                      scene.floorplan, sample_idx=sample)
    assert used_defaults != used
