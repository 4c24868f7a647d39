"""Smoke test of ``probeless bench bus --quick --json``: one JSON object, complete counts, sane figures."""

from __future__ import annotations

import json
import math

import pytest

from probeless.bench.bus import QUEUE_SIZE, main
from probeless.bench.bus_raw import subscriber_buffer
from probeless.runtime.transport import BLOCK_RECV_HWM

SIDE_KEYS = ("msgs_per_s", "mb_per_s", "latency_p50_ms", "latency_p99_ms")


@pytest.mark.graph
@pytest.mark.slow
@pytest.mark.timeout(120)
def test_bench_bus_quick_json(capsys):
    code = main(json_out=True, quick=True)
    out = capsys.readouterr().out
    result = json.loads(out)  # exactly one JSON document, nothing else on stdout
    assert out.strip().count("\n") == 0
    assert code == 0
    assert result["lossless"] is True
    assert isinstance(result["meets_goals"], bool)
    assert set(result["goals"]) == {"throughput_ratio_min", "latency_added_p50_ms_max"}
    assert set(result["payloads"]) == {"640x480x3", "1280x1024x3"}
    for name, entry in result["payloads"].items():
        for side in ("ours", "raw"):
            s = entry[side]
            for key in SIDE_KEYS:
                assert isinstance(s[key], float) and math.isfinite(s[key]) and s[key] > 0, (name, side, key)
            assert s["received"] == s["expected"] == entry["throughput_messages"] + entry["latency_messages"]
            assert s["seq_gaps"] == 0 and s["out_of_order"] == 0 and s["lossless"] is True
            assert s["latency_p99_ms"] >= s["latency_p50_ms"]
        assert math.isfinite(entry["throughput_ratio"]) and entry["throughput_ratio"] > 0
        assert math.isfinite(entry["latency_added_p50_ms"])
    # equal work and equal buffering: same messages both sides (above), same subscriber buffer, reference named
    buf = result["subscriber_buffer_messages"]
    assert buf["ours"] == buf["raw"] == BLOCK_RECV_HWM + QUEUE_SIZE
    assert "raw pyzmq" in result["throughput_reference"]


def test_raw_subscriber_gets_the_whole_buffer_of_a_block_input():
    assert subscriber_buffer(QUEUE_SIZE) == BLOCK_RECV_HWM + QUEUE_SIZE > BLOCK_RECV_HWM
