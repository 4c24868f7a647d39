"""Smoke test of ``probeless bench pano --quick``: one JSON object whose figures are complete, consistent
with each other and sane (not timing values: those depend on the machine)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from bench_checks import one_json_object, positive

from probeless.bench import pano as bench_pano
from probeless.pano.sources import HDRI_DIR as HDRI

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
    assert {"diffuse_speedup", "diffuse_reference", "diffuse_gate_met", "weights_build_ms", "diffuse_max_rel_error",
            "glossy_equal_cost_error_ratio", "glossy_equal_cost_reference", "glossy_rel_error", "rates",
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
def test_diffuse_side_by_side_is_equal_work_within_the_gate(result):
    """Reference and fast paths: same frame in, same 64x32 map out, every texel scored, gate checked."""
    d = result["diffuse"]
    assert "exact_diffuse" in result["diffuse_reference"] == d["diffuse_reference"]
    assert d["size"] == [64, 32] and d["texels"] == 2048
    assert d["output_shapes"] == {"exact": [32, 64, 3], "fast": [32, 64, 3], "matmul": [32, 64, 3],
                                  "gpu": [32, 64, 3]}
    assert d["frame"] == [1280, 640]
    for key in ("exact_ms", "fast_ms", "matmul_ms", "gpu_ms", "weights_build_ms", "matmul_first_use_ms",
                "gpu_first_use_ms", "fast_kernels_build_ms", "fast_first_use_ms"):
        assert positive(d[key]), key
    assert d["matmul_first_use_ms"] > d["matmul_ms"]  # the first use pays the weight build
    assert "diffuse_map_fast" in d["diffuse_method"] and d["diffuse_gate"]["method"] == "fast"
    gate = d["diffuse_gate"]["max_rel_error_max"]
    errors = [*d["frame_errors"].values(), *(e for p in d["hdr_panoramas"].values() for e in p.values())]
    assert all(0 <= e["mean_rel_error"] <= e["max_rel_error"] for e in errors)
    fast = [d["frame_errors"]["fast"]["max_rel_error"], *(p["fast"]["max_rel_error"]
                                                         for p in d["hdr_panoramas"].values())]
    assert d["diffuse_max_rel_error"] == max(fast) and d["diffuse_gate_met"] is (max(fast) <= gate)
    assert d["frame_errors"]["matmul"]["max_rel_error"] < gate  # the video frame is smooth: well inside
    if HDRI.is_dir() and list(HDRI.glob("*.hdr")):
        assert len(d["hdr_panoramas"]) == bench_pano.QUICK["hdr_panoramas"] and d["hdr_panoramas_skipped"] is None
    else:
        assert d["hdr_panoramas"] == {} and "no HDR panoramas" in d["hdr_panoramas_skipped"]


@pytest.mark.gl
@pytest.mark.graph
@pytest.mark.slow
def test_glossy_at_equal_cost(result):
    g = result["glossy"]
    assert g["lookups"] == 36 and "36 lookups" in result["glossy_equal_cost_reference"]
    assert g["truth_mc_samples"] == bench_pano.QUICK["mc_samples"]
    assert 0 <= g["truth_noise"]["mean"] < g["ring_rel_error"]["mean"] < 0.1  # the truth resolves the ring's error
    assert g["mc_equal_rel_error"]["mean"] > g["truth_noise"]["mean"]  # 36 MC samples are far from converged
    assert result["glossy_equal_cost_error_ratio"] > 0


def test_missing_video_falls_back_to_a_synthetic_frame(tmp_path):
    frames, source = bench_pano.load_frames(2, Path(tmp_path / "missing.webm"))
    assert len(frames) == 2 and frames[0].shape == (640, 1280, 3) and frames[0].dtype == np.uint8
    assert "synthetic" in source and "missing.webm" in source
    assert frames[0].max() == 255 and frames[0].min() < 128  # a clipped sun over a darker scene
