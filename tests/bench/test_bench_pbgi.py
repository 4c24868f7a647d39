"""``probeless bench pbgi --quick --json`` (paper 001, Table 3): one JSON object, the three variants' same image."""

from __future__ import annotations

import argparse

import pytest
from bench_checks import one_json_object, positive

from probeless.bench import pbgi
from probeless.bench.pbgi_scenes import VARIANTS

pytestmark = [pytest.mark.gl, pytest.mark.slow]


def test_bench_pbgi_quick_one_json_object():
    ns = argparse.Namespace(json=True, quick=True, scenes=None, views=None, viewports=None, micro=None, repeat=None,
                            supersample=1, budget=pbgi.BUDGET_S, figure=None)
    r = one_json_object(lambda: pbgi.run(ns))
    assert r["benchmark"] == "pbgi" and r["quick"] is True
    assert r["reference"] == pbgi.REFERENCE and isinstance(r["device"], str) and r["device"]
    for key in ("bsh", "table3", "images_equal", "hybrid_speedup", "mipmapped_speedup", "settings", "scenes"):
        assert key in r
    # BSH of the room cloud: clustering leaves fewer nodes than the full binary tree
    (room,) = r["bsh"]["rows"]
    assert room["cloud"] == "room" and room["points"] > 600_000 and positive(room["build_s"])
    assert room["nodes"] == 2 * room["leaves"] - 1 and 0 < room["nodes_clustered"] < room["nodes"]
    # quick: room, View2, 128^2, micro 16^2, every variant timed once, no sweep
    (row,) = r["table3"]
    assert (row["scene"], row["view"], row["viewport"], row["micro"], row["rounds"]) == ("room", 2, 128, 16, 1)
    assert r["hybrid_threshold_sweep"] is None and r["configs_skipped"] == 0
    for v in VARIANTS:
        fig = row["variants"][v]
        assert positive(fig["ms"]) and fig["render_ms"] >= fig["ms"] and positive(fig["micro_mb"])
        assert positive(fig["cpu_ms"])
    assert row["variants"]["classic"]["extra_mb"] == 0
    assert positive(row["variants"]["mipmapped"]["extra_mb"]) and positive(row["variants"]["hybrid"]["extra_mb"])
    # the same cut: the images agree (gate) and the exit code was 0
    assert r["images_equal"] is True and row["equal"] is True
    for v in ("mipmapped", "hybrid"):
        assert row["variants"][v]["rel_rms"] <= pbgi.EQUAL_REL_RMS
    assert 0.2 < row["object_pixels"] / 128 ** 2 < 0.5  # View2: the sphere covers about a third of the viewport
    h = r["hybrid_speedup"]
    assert positive(row["hybrid_speedup"]) and positive(h["max"]) and positive(h["median"]) and h["configs"] == 1
    assert positive(h["cpu"]["max"]) and positive(row["hybrid_speedup_cpu"])
    assert positive(r["mipmapped_speedup"]["max"])
