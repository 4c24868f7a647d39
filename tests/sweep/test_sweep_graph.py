"""Graph runs in a sweep: `probeless launch` with the axes as graph arguments, in parallel, each with its own
run dir, collected from the JSON file the graph writes there (the demo graph's summary sink)."""

from __future__ import annotations

import json

import pytest
from sweep_common import ROOT, read_csv

from probeless.sweep.driver import run_sweep

pytestmark = pytest.mark.graph


def test_graph_sweep_collects_from_the_file_each_run_writes(tmp_path):
    sweep = tmp_path / "graph.yaml"
    sweep.write_text(f"""run:
  graph: {ROOT}/launch/demo_runtime.yaml
  args: {{frames: "{{n}}", operation: "{{op}}", fps: 60, out_dir: "{{run_dir}}/out"}}
  result: "{{run_dir}}/out/summary.json"
  timeout_s: 60
axes:
  n: [4, 9]
  op: [blur, invert]
collect:
  received: frames
  gaps: seq_gaps
""")
    s = run_sweep(sweep, tmp_path / "res", jobs=2, show_progress=False)
    assert (s.ok, s.failed) == (4, 0), s.failures
    rows = read_csv(tmp_path / "res" / "results.csv")
    assert sorted(r["run_id"] for r in rows) == ["4-blur", "4-invert", "9-blur", "9-invert"]
    for r in rows:  # the source publishes n frames; the block policy delivers all of them
        assert int(float(r["received"])) == int(r["n"]) and float(r["gaps"]) == 0
        summary = json.loads((tmp_path / "res" / r["run_id"] / "out" / "summary.json").read_text())
        assert summary["frames"] == int(r["n"])
        argv = json.loads((tmp_path / "res" / r["run_id"] / "run.json").read_text())["argv"]
        assert argv[:3] == ["probeless", "launch", str(ROOT / "launch/demo_runtime.yaml")]
        assert f"operation:={r['op']}" in argv
