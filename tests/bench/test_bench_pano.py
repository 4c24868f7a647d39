"""Smoke test of ``probeless bench pano --quick``: one JSON object whose figures are complete, consistent
with each other and sane (not timing values: those depend on the machine)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from bench_checks import one_json_object, positive

from probeless.bench import pano as bench_pano

STAGES = {"itmo_gpu_paper", "diffuse_gpu_32x16", "diffuse_matmul_32x16", "upload", "mono_view", "stereo_view",
          "mono_render", "mono_background", "mono_composite", "stereo_render", "stereo_background",
          "stereo_composite", *(f"itmo_numpy_{op}" for op in bench_pano.NUMPY_ITMOS)}


@pytest.fixture(scope="module")
def result() -> dict:
    return one_json_object(lambda: bench_pano.main(json_out=True, quick=True, show_progress=False))


@pytest.mark.gl
@pytest.mark.graph
@pytest.mark.slow
def test_keys_and_timings(result):
    q = bench_pano.QUICK
    assert {"diffuse_speedup", "diffuse_max_rel_error", "glossy_speedup", "glossy_rel_error", "rates",
            "timings_ms", "goals_met", "source"} <= set(result)
    assert set(result["timings_ms"]) == STAGES
    for name, s in result["timings_ms"].items():
        assert all(positive(s[k]) for k in ("mean", "p50", "p95")), name
        assert s["n"] == (q["stereo_frames"] if name.startswith("stereo") else q["frames"]) - 1, name  # warm-up
    assert result["objects"] == 5 and result["frames"] == q["frames"]
    if bench_pano.VIDEO.is_file():
        assert result["source"].startswith(bench_pano.VIDEO.name)


@pytest.mark.gl
@pytest.mark.graph
@pytest.mark.slow
def test_stages_and_rates_are_consistent(result):
    t, r = {k: v["mean"] for k, v in result["timings_ms"].items()}, result["rates"]
    assert sum(t[f"mono_{s}"] for s in ("background", "render", "composite")) <= t["mono_view"] * 1.01
    assert r["mono_fps"] == pytest.approx(1000 / t["mono_view"], rel=1e-9)
    assert r["stereo_fps"] == pytest.approx(1000 / t["stereo_view"], rel=1e-9)
    assert r["mono_new_frame_fps"] == pytest.approx(1000 / (t["mono_view"] + t["upload"]), rel=1e-9)
    assert r["pipeline_mono_fps"] == pytest.approx(
        1000 / (t["itmo_gpu_paper"] + t["diffuse_gpu_32x16"] + t["upload"] + t["mono_view"]), rel=1e-9)


@pytest.mark.gl
@pytest.mark.graph
@pytest.mark.slow
def test_diffuse_side_by_side(result):
    d = result["diffuse"]
    assert (d["size"] == [64, 32] and d["all_texels"] == 2048
            and d["bruteforce_texels"] == bench_pano.QUICK["brute_texels"])
    # the subset's texel loop, per texel, scaled to all texels; the one-off setup counted once
    assert positive(d["bruteforce_setup_ms"]) and positive(d["bruteforce_subset_ms"])
    per_texel = d["bruteforce_subset_ms"] / d["bruteforce_texels"]
    assert d["bruteforce_ms"] == pytest.approx(d["bruteforce_setup_ms"] + per_texel * 2048)
    assert result["diffuse_speedup"] == pytest.approx(d["bruteforce_ms"] / d["matmul_ms"])
    assert d["diffuse_gpu_speedup"] == pytest.approx(d["bruteforce_ms"] / d["gpu_ms"])
    assert result["diffuse_speedup"] > 1 and d["diffuse_gpu_speedup"] > 1
    for method in ("matmul", "gpu"):  # the 128x64 input keeps the map within 1% of the full-frame sum
        assert 0 <= d[f"diffuse_{method}_mean_rel_error"] <= d[f"diffuse_{method}_max_rel_error"] < 0.01, method
    assert result["diffuse_max_rel_error"] == max(d["diffuse_matmul_max_rel_error"], d["diffuse_gpu_max_rel_error"])
    assert result["goals_met"]["diffuse_max_rel_error"] is True


@pytest.mark.gl
@pytest.mark.graph
@pytest.mark.slow
def test_glossy_side_by_side(result):
    g = result["glossy"]
    assert result["glossy_speedup"] > 1 and g["mc_samples"] == bench_pano.QUICK["mc_samples"]
    assert 0 <= result["glossy_rel_error"] < 0.1 and result["glossy_rel_error"] <= g["glossy_max_rel_error"]
    assert 0 <= g["mc_noise"] < result["glossy_rel_error"]  # the reference resolves the ring's error


def test_missing_video_falls_back_to_a_synthetic_frame(tmp_path):
    frames, source = bench_pano.load_frames(2, Path(tmp_path / "missing.webm"))
    assert len(frames) == 2 and frames[0].shape == (640, 1280, 3) and frames[0].dtype == np.uint8
    assert "synthetic" in source and "missing.webm" in source
    assert frames[0].max() == 255 and frames[0].min() < 128  # a clipped sun over a darker scene
