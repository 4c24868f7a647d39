"""``probeless bench sensors --quick --json`` prints one JSON object with the documented figures."""

from __future__ import annotations

import json

import pytest

from probeless.cli import main as cli

pytestmark = [pytest.mark.gl, pytest.mark.graph, pytest.mark.slow]


def test_bench_sensors_quick_json(capsys):
    assert cli(["bench", "sensors", "--quick", "--json"]) == 0
    out = capsys.readouterr().out.strip().splitlines()
    assert len(out) == 1
    result = json.loads(out[0])
    assert result["rig"]["rgbd_fps"] > 0 and result["rig"]["fisheye_fps"] > 0
    u = result["undistort"]
    assert u["max_px_diff"] <= 0.5 and u["lut_build_ms"] > 0 and u["remap_ms"] > 0
    ref = u["reference"]  # equal work: the same mapping, the same output, within the gate
    assert "cv2.omnidir.initUndistortRectifyMap" in result["undistort_reference"]
    assert ref["output_shapes"]["ours"] == ref["output_shapes"]["cv2"] == [1024, 1024, 3]
    assert ref["map_agreement_px"] <= ref["gate"]["map_agreement_px_max"] and ref["map_agreement_pixels"] > 500_000
    assert ref["output_max_abs_diff"] <= 1 and ref["gate_met"] is True and result["goals_met"] is True
