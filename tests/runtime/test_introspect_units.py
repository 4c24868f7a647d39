"""Run-time params and run lookup without starting a graph (the graph tests are in tests/topics/test_introspect.py)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import dataclass

import pytest

from probeless.errors import ParamError, ProbelessError
from probeless.runtime import param
from probeless.runtime.control import dynamic_keys, updated_params
from probeless.runtime.runs import resolve_runs, running_graphs


@dataclass(frozen=True)
class Params:
    gain: float = param(1.0, min=0.0, max=10.0, dynamic=True)
    mode: str = param("a", choices=("a", "b"), dynamic=True)
    width: int = param(64, min=1)


def test_only_dynamic_params_change_and_values_are_checked_like_check():
    assert dynamic_keys(Params) == ["gain", "mode"]
    new = updated_params(Params, Params(), "gain", 2, node_id="n")
    assert new == Params(gain=2.0) and isinstance(new.gain, float)   # converted like at load
    with pytest.raises(ParamError, match=r"node 'n': key 'gain': 11.0 is above the maximum 10.0"):
        updated_params(Params, Params(), "gain", 11, node_id="n")
    with pytest.raises(ParamError, match=r"key 'mode': 'c' is not one of \['a', 'b'\]"):
        updated_params(Params, Params(), "mode", "c", node_id="n")
    with pytest.raises(ParamError, match=r"key 'width': not a dynamic parameter.*dynamic: gain, mode"):
        updated_params(Params, Params(), "width", 32, node_id="n")
    with pytest.raises(ParamError, match=r"key 'gian': unknown parameter \(did you mean 'gain'\?"):
        updated_params(Params, Params(), "gian", 1.0, node_id="n")
    with pytest.raises(ParamError, match=r"expected float, got a list \[1\]"):
        updated_params(Params, Params(), "gain", [1], node_id="n")


def _fake_run(base, name: str, graph_file, pid: int):
    run = base / name
    run.mkdir(parents=True)
    (run / "graph.json").write_text(json.dumps({"file": str(graph_file), "file_abs": str(graph_file),
                                                "launcher_pid": pid, "started_ns": 1, "nodes": {}}))
    return run


def test_runs_are_named_by_id_dir_or_graph_file_and_a_dead_run_is_an_error(tmp_path):
    base, graph = tmp_path / "runs", tmp_path / "g.yaml"
    graph.write_text("nodes: []\n")
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    _fake_run(base, "100000-aaaa", graph, os.getpid())
    _fake_run(base, "100001-bbbb", graph, int(dead.stdout))  # its launcher has exited
    assert [g.run_id for g in running_graphs(base)] == ["100000-aaaa"]
    assert [g.run_id for g in resolve_runs("100000-aaaa", base=base)] == ["100000-aaaa"]
    assert [g.run_id for g in resolve_runs(str(base / "100000-aaaa"), base=base)] == ["100000-aaaa"]
    assert [g.run_id for g in resolve_runs("g.yaml", base=base, relative_to=tmp_path)] == ["100000-aaaa"]
    with pytest.raises(ProbelessError, match="run 100001-bbbb .* is not running any more"):
        resolve_runs("100001-bbbb", base=base)
    with pytest.raises(ProbelessError, match="neither the id of a running graph nor a graph file"):
        resolve_runs("nothing", base=base)
