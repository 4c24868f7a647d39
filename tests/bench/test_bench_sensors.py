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
    assert result["undistort_speedup"] == result["undistort"]["undistort_speedup"] > 1
    assert result["undistort"]["max_px_diff"] <= 0.5
