"""The diffuse map evaluation: its exact reference against the brute-force loop, its table and figure."""

import argparse
import json

import cv2
import numpy as np
import pytest

from probeless.eval import add_evaluation
from probeless.pano import diffuse, equirect
from probeless.pano.diffuse_eval import GATE, TIMED, evaluate_diffuse, exact_diffuse, rel_errors, summarize
from probeless.pano.diffuse_report import diffuse_figure, format_table


def sunny_env(w, h):
    d = equirect.pixel_directions(w, h)
    s = np.array([0.4, 0.5, 0.3]) / np.linalg.norm([0.4, 0.5, 0.3])
    lum = 0.2 + 0.4 * np.clip(d[..., 2], 0, None) + 80.0 * (d @ s > np.cos(np.radians(5.0)))
    return (lum[..., None] * np.array([1.0, 0.85, 0.7])).astype(np.float32)


@pytest.mark.parametrize("frame,out", [((256, 128), (16, 8)), ((240, 120), (32, 16))])  # 240 / 32: no FFT
def test_exact_diffuse_is_the_bruteforce_sum(frame, out):
    env = sunny_env(*frame)
    exact = exact_diffuse(env, out)
    idx = np.array([0, 7, out[0] * out[1] // 2 + 1, out[0] * out[1] - 1])
    brute = diffuse.diffuse_map_bruteforce(env, out, texels=idx)  # float32 output
    np.testing.assert_allclose(exact.reshape(-1, 3)[idx], brute, rtol=1e-6)


def test_rel_errors():
    e = rel_errors(np.array([1.1, 2.0, 2.7]), np.array([1.0, 2.0, 3.0]))
    assert e["max_rel_error"] == pytest.approx(0.1) and e["mean_rel_error"] == pytest.approx(0.2 / 3)


@pytest.fixture(scope="module")
def pano(tmp_path_factory):
    path = tmp_path_factory.mktemp("hdri") / "sunny.hdr"
    assert cv2.imwrite(str(path), sunny_env(256, 128)[..., ::-1])
    return path


@pytest.mark.gl
@pytest.mark.graph
def test_evaluate_diffuse_table(pano):
    res = evaluate_diffuse([pano], sizes=((16, 8),), gpu_in_size=(64, 32), show_progress=False)
    row = res["panoramas"]["sunny.hdr"]["16x8"]
    assert res["panoramas"]["sunny.hdr"]["resolution"] == [256, 128]
    # gpu (64x32 input) and matmul (128x64 input) are both Algorithm 1 on an area average; the
    # moments variant is nearly the full-resolution sum; SH9 is the smooth approximation
    assert row["gpu_moments"]["max_rel_error"] < 0.2 * row["gpu"]["max_rel_error"]
    assert row["matmul"]["max_rel_error"] < row["gpu"]["max_rel_error"] < 0.1
    assert row["sh9"]["mean_rel_error"] > row["gpu"]["mean_rel_error"]
    assert row["fast"]["max_rel_error"] < 0.2 * row["matmul"]["max_rel_error"]  # the sun's texels summed exactly
    # equal work: the speed-up reference is the exact convolution of the same frame to the same map
    assert "exact_diffuse" in res["speedup_reference"] and "every texel" in res["speedup_reference"]
    assert row["texels"] == 16 * 8
    assert {k: tuple(v) for k, v in row["output_shapes"].items()} == {m: (8, 16, 3) for m in ("exact",) + TIMED}
    for key in ("gpu_s", "gpu_moments_s", "matmul_s", "fast_s", "exact_s", "matmul_weights_s"):
        assert row[key] > 0
    assert "paper_bruteforce_s" not in row  # a Python loop is not a reference
    assert res["gate"] == {"max_rel_error_max": GATE}
    assert res["summary"]["16x8"]["gpu_max_rel_error"] == row["gpu"]["max_rel_error"]
    head, line, note = format_table(res["summary"], [(16, 8)]).splitlines()
    assert "gpu_moments max / mean" in head and "exact ms" in head and line.startswith("16x8")
    assert f"{row['sh9']['max_rel_error']:.2e}" in line and "exact FFT" in note


def _row(max_err):
    err = {"max_rel_error": max_err, "mean_rel_error": max_err / 10}
    return {**{m: err for m in ("gpu", "gpu_moments", "matmul", "fast", "sh9")},
            **{f"{m}_{k}": 1.0 for m in TIMED for k in ("s", "speedup")},
            "exact_s": 1.0, "matmul_weights_s": 1.0, "matmul_first_use_speedup": 1.0}


def test_summary_gate_is_the_worst_panorama():
    """The gate holds only when every panorama's max error is within it."""
    ok = summarize({"a": {"8x4": _row(0.5 * GATE)}, "b": {"8x4": _row(0.9 * GATE)}}, [(8, 4)])["8x4"]
    bad = summarize({"a": {"8x4": _row(0.5 * GATE)}, "b": {"8x4": _row(2.0 * GATE)}}, [(8, 4)])["8x4"]
    assert all(ok[f"{m}_gate_met"] for m in TIMED) and not any(bad[f"{m}_gate_met"] for m in TIMED)
    assert bad["gpu_max_rel_error"] == 2.0 * GATE


@pytest.mark.slow
@pytest.mark.gl
@pytest.mark.graph
def test_cli_json_and_figure(pano, tmp_path, capsys):
    ap = argparse.ArgumentParser()
    add_evaluation(ap.add_subparsers(), "diffuse")
    out_png = tmp_path / "row.png"
    ns = ap.parse_args(["diffuse", "--panorama", str(pano), "--sizes", "16x8", "--in-size", "64x32", "--json",
                        "--figure", str(out_png), "--no-progress"])
    assert ns.func(ns) == 0
    res = json.loads(capsys.readouterr().out)
    assert set(res["summary"]) == {"16x8"} and res["figure"] == str(out_png)
    img = cv2.imread(str(out_png))
    assert img is not None and img.shape[1] > 4 * img.shape[0]  # one row of five panels


@pytest.mark.slow
@pytest.mark.gl
@pytest.mark.graph
def test_figure_rows_per_panorama(tmp_path):
    out = diffuse_figure([sunny_env(128, 64), sunny_env(128, 64)[:, ::-1]], tmp_path / "two.png", (16, 8), (32, 16))
    one = diffuse_figure(sunny_env(128, 64), tmp_path / "one.png", (16, 8), (32, 16))
    assert cv2.imread(str(out)).shape[0] > 1.5 * cv2.imread(str(one)).shape[0]
