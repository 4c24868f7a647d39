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

from probeless.bench.coarse import SCENE, main, print_table, strided_subset
from probeless.coarse.atlas import fit_atlas
from probeless.coarse.texels import texel_map
from probeless.scene.parse import load_scene

ROOT = REPO
STAGES = {"occlusion", "texture_update", "brightness_all", "brightness_sampled", "brightness_serial_subset",
          "brightness_serial_all_extrapolated", "inpaint_amortised", "inpaint_full", "readback_rgba8"}


@pytest.fixture(scope="module")
def result() -> dict:
    """One small in-process run: 256 x 256 atlas, 3 frames, Δ sampled with 8000 of its texels."""
    return one_json_object(lambda: main(json_out=True, atlas_size=256, frames=3, serial_texels=500,
                                        sample_texels=8000, show_progress=False))


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
def test_speedups_consistent_with_times(result):
    t, b = result["timings_ms"], result["brightness"]
    serial_all = t["brightness_serial_all_extrapolated"]["mean"]
    # the extrapolation is the subset time scaled per texel
    assert b["serial_texels"] == 500 and b["serial_extrapolated"] is True
    assert math.isclose(serial_all, t["brightness_serial_subset"]["mean"] * b["all_texels"] / b["serial_texels"],
                        rel_tol=1e-3)
    assert math.isclose(b["brightness_speedup"], serial_all / t["brightness_all"]["mean"], rel_tol=1e-3)
    assert math.isclose(b["brightness_sampled_speedup"], serial_all / t["brightness_sampled"]["mean"], rel_tol=1e-3)
    assert math.isclose(b["last_frame_speedup_measured"],
                        b["last_frame_serial_all_measured_ms"] / b["last_frame_vectorised_all_ms"], rel_tol=1e-3)
    goal = result["goals"]["brightness_speedup_min"]
    assert result["goals_met"] == {"brightness_speedup": b["brightness_speedup"] >= goal,
                                   "brightness_sampled_speedup": b["brightness_sampled_speedup"] >= goal}


@pytest.mark.gl
@pytest.mark.graph
@pytest.mark.slow
def test_estimates_agree(result):
    b = result["brightness"]
    assert b["serial_vs_vectorised_texels_equal"] is True
    assert 0 <= b["serial_vs_vectorised_max_abs_diff"] < 1e-4
    assert b["sample_texels"] == 8000 < b["all_texels"]  # the sampled estimate really is sampled
    assert math.isfinite(b["sampled_error_max"]) and 0 <= b["sampled_error_mean"] <= b["sampled_error_max"]
    assert b["sampled_error_max"] < 255
    assert b["texels_used_mean"] > 0  # the frames overlap the atlas seen before: Δ is not trivially 0


@pytest.mark.gl
@pytest.mark.graph
@pytest.mark.slow
def test_table_renders(result, capsys):
    print_table(result)
    out = capsys.readouterr().out
    assert "occlusion" in out and "brightness_serial_all_extrapolated" in out and "256x256 atlas" in out


def test_strided_subset_is_even():
    idx = np.arange(10, 1010)
    assert np.array_equal(strided_subset(idx, 100), np.arange(10, 1010, 10))
    assert np.array_equal(strided_subset(idx, 5000), idx)  # fewer texels than asked: all of them
    assert len(strided_subset(np.arange(44259), 500)) == 500


@pytest.mark.graph
@pytest.mark.slow
@pytest.mark.timeout(120)
def test_script_prints_one_json_object():
    cmd = [sys.executable, "-m", "probeless.bench.coarse", "--json", "--atlas-size", "128", "--frames", "2",
           "--serial-texels", "200"]
    proc = subprocess.run(cmd, check=False, capture_output=True, text=True, cwd=ROOT, timeout=110)
    assert proc.returncode == 0, proc.stderr
    r = json.loads(proc.stdout)
    assert proc.stdout.strip().count("\n") == 0
    assert r["frames"] == 2 and r["brightness"]["serial_texels"] == 200 and r["atlas"]["width"] == 128
