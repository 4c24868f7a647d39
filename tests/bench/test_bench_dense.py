"""probeless bench dense: both sides render the same fused model; the reported ratios follow from the times."""

from __future__ import annotations

import pytest

from probeless.bench.dense_render import bench_dense_render

pytestmark = [pytest.mark.gl, pytest.mark.graph, pytest.mark.slow]


def test_bench_dense_small():
    r = bench_dense_render(size=64, frames=2, repeats=3)  # best of 3: single runs of a few ms are noisy
    assert r["points"] > 1000 and r["active_blocks"] > 10
    assert r["ours_ms"] > 0 and r["open3d_raycast_ms"] > 0 and 0 < r["ours_coarse_only_ms"] <= r["ours_ms"] * 1.5
    assert r["dense_render_speedup"] == pytest.approx(r["open3d_raycast_ms"] / r["ours_ms"])
    assert 0.05 < r["raycast_hit_fraction"] <= 1.0  # the raycast sees the fused model from the object
    assert 0.0 <= r["colour_agreement"] <= 1.0
