"""Graph-mode scoring (probeless.eval.envmap_graph): pairing maps with the truth and the common texels."""

from __future__ import annotations

import numpy as np
import pytest

from probeless.color import linear_to_srgb
from probeless.envmap.score import score_envmap
from probeless.errors import ProbelessError
from probeless.eval.envmap_graph import GraphRun, Truth, _down, score_runs

S = 16


def truth_at(stamps, rng):
    t = Truth()
    for s in stamps:
        hdr = rng.uniform(0.05, 2.0, (6, S, S, 3)).astype(np.float32)
        t.hdr["o", s], t.exposure[s] = hdr, np.full(3, 0.8)
        t.ldr["o", s] = linear_to_srgb(np.clip(hdr * 0.8, 0, 1)).astype(np.float32)
    return t


def test_maps_are_scored_on_shared_stamps_and_the_texels_both_observed():
    rng = np.random.default_rng(3)
    truth = truth_at([10, 20, 30], rng)
    good = {("o", s): (np.clip(truth.ldr["o", s] + 0.01, 0, 1), np.ones((6, 2 * S, 2 * S), bool)) for s in (10, 20)}
    half = np.zeros((6, 2 * S, 2 * S), bool)
    half[:3] = True
    half[3, 0, 0] = True  # one fine texel of a coarse one: the coarse texel is not observed
    bad = {("o", s): (np.full((6, S, S, 3), 0.5, np.float32), half) for s in (20, 30)}
    out = score_runs({"a": GraphRun("a", good, None), "b": GraphRun("b", bad, None)}, truth)
    assert out["a"]["o"]["times_s"] == out["b"]["o"]["times_s"] and len(out["a"]["o"]["times_s"]) == 1  # stamp 20
    common = np.zeros((6, S, S), bool)
    common[:3] = True
    fine = np.kron(good["o", 20][0], np.ones((1, 2, 2, 1)))  # est at twice the truth's size: box-filtered back
    want = score_envmap(fine, truth.ldr["o", 20], truth.hdr["o", 20], exposure=np.full(3, 0.8),
                        observed=np.ones((6, S, S), bool), common=common)
    for k, v in want.items():
        assert out["a"]["o"][k] == pytest.approx(v, nan_ok=True), k
    assert out["a"]["o"]["common_coverage"] == pytest.approx(0.5)
    assert out["b"]["o"]["coverage"] == pytest.approx(0.5) and out["a"]["o"]["psnr_common"] > 35
    assert out["b"]["o"]["psnr_common"] < out["a"]["o"]["psnr_common"] - 15


def test_nothing_shared_is_an_error_and_masks_must_divide():
    truth = truth_at([10], np.random.default_rng(0))
    runs = {"a": GraphRun("a", {("o", 11): (truth.ldr["o", 10], None)}, None)}
    with pytest.raises(ProbelessError, match="no map stamp"):
        score_runs(runs, truth)
    with pytest.raises(ProbelessError, match="not a multiple"):
        _down(np.ones((6, 12, 12), bool), S)


# `probeless eval envmap --graph` end to end: tests/pipeline/test_graph_scene_files.py (one render, both runs).
