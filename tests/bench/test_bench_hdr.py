"""``probeless bench hdr`` (paper 001, Table 1): one JSON object, the shipped command timed end to end."""

from __future__ import annotations

import argparse

import pytest
from bench_checks import one_json_object, positive

from probeless.bench import hdr


@pytest.mark.slow
@pytest.mark.gl
def test_bench_hdr_small_cloud_one_json_object():
    ns = argparse.Namespace(json=True, quick=True, scene=str(hdr.SCENE), frames=2, voxel=0.04, size=128,
                            method="pmatch-lum", repeat=1)
    r = one_json_object(lambda: hdr.run(ns))
    assert r["benchmark"] == "hdr" and r["reference"]["hdr_seconds"] == 50.4 and r["shots"] == 1
    assert r["points"] > 1000 and 0 < r["points_overexposed"] < r["points"]
    # the process's wall time contains every stage it timed itself
    assert positive(r["end_to_end_s"]) and r["end_to_end_s"] * 1e3 > sum(r["stages_ms"].values())
    assert set(r["stages_ms"]) == {"read", "exposure", "views", "transfer", "poisson", "write"}
    # fewer than 800k points can never meet the goal, however fast
    assert r["goal_met"] is False
    # the expanded cloud is nearer the synthetic truth than the LDR cloud on the over-exposed points
    assert r["quality_gate_passed"] is True
    assert r["cloud_rms_overexposed"]["expanded"] < r["cloud_rms_overexposed"]["ldr"]
    assert set(r["patchmatch_quality"]) == {"rgb", "lum"}
    assert all(0 < q <= 1.0 + 1e-6 for q in r["patchmatch_quality"].values())  # the exact field is a lower bound
    # Poisson fill (Eq. 2-3) against nearest-neighbour copying: where the removed points are not clipped the
    # LDR gradients are the HDR ones, so the fill is far better than copying
    q = r["poisson"]["random"]
    assert q["removed"] > 0 and q["left_ldr"] == 0 and q["fill_rms"] <= 0.5 * q["nearest_copy_rms"]
    assert r["patchmatch_1024_s"] is None  # quick: not timed
