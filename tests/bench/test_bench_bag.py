"""Smoke test of ``probeless bench bag --quick --json``: one JSON object, no loss, lockstep identical, sane figures."""

from __future__ import annotations

import json
import math

import pytest
from bench_checks import positive

from probeless.bench.bag import main

pytestmark = [pytest.mark.graph, pytest.mark.slow]


@pytest.mark.timeout(120)
def test_bench_bag_quick_json(capsys):
    code = main(json_out=True, quick=True)
    out = capsys.readouterr().out
    result = json.loads(out)  # exactly one JSON document, nothing else on stdout
    assert out.strip().count("\n") == 0
    assert code == 0
    assert {"record", "realtime", "replay_timing", "lockstep", "goals", "goals_met", "meets_goals"} <= set(result)
    assert isinstance(result["meets_goals"], bool)
    assert result["lossless"] is True

    for c in ("none", "lz4"):
        e = result["record"][c]
        for key in ("ours_mb_per_s", "raw_mb_per_s", "record_ratio", "payload_mb", "file_mb"):
            assert positive(e[key]), (c, key)
        # equal work: the raw writer writes the same messages and payload bytes the recorder stored
        assert e["raw_messages"] == sum(e["messages"].values()) and e["raw_payload_mb"] == e["payload_mb"]
        assert "mcap.writer.Writer" in e["record_reference"]
        assert e["lossless"] is True
        assert set(e["messages"]) == {"camera/rgb", "camera/depth", "camera/fisheye"}
        assert e["messages"]["camera/rgb"] == e["messages"]["camera/depth"] == 2 * e["messages"]["camera/fisheye"]

    rt = result["realtime"]
    assert positive(rt["duration_s"]) and rt["lossless"] is True
    for c in ("none", "lz4"):
        assert rt["published"][c] == rt["recorded"][c]
        assert rt["published"][c]["camera/rgb"] == round(rt["duration_s"] * rt["rate_hz"])
        assert rt["runs"][c]["seq_errors"] == {"camera/rgb": 0, "camera/depth": 0, "camera/fisheye": 0}

    for key in ("rate_1", "rate_2"):
        t = result["replay_timing"][key]
        assert t["received"] == t["messages"] and t["complete"] is True
        for k in ("p50_ms", "p99_ms", "max_ms"):
            assert isinstance(t[k], float) and math.isfinite(t[k]) and t[k] >= 0, (key, k)
        assert t["p50_ms"] <= t["p99_ms"] <= t["max_ms"]

    ls = result["lockstep"]
    assert ls["identical"] is True
    assert len(ls["digest"]) == 64 and ls["digests"] == [ls["digest"], ls["digest"]]
    assert positive(ls["ms_per_message"])
    assert isinstance(ls["nonlockstep_identical"], bool)
