"""`probeless check`: every malformed graph in tests/graphs/ is caught with a message naming file, line, node, key."""

from __future__ import annotations

from pathlib import Path

import pytest

from probeless.cli import main
from probeless.launch.graph import parse_graph
from probeless.launch.launcher import load_checked
from probeless.launch.validate import validate

GRAPHS = Path(__file__).parent / "graphs"

# file -> (line, node id or None, key or None, text the message must contain)
CASES = {
    "bad_unknown_top_key": (1, None, "node", "did you mean 'nodes'"),
    "bad_unknown_node_key": (5, "camera", "parameters", "unknown node key"),
    "bad_unknown_node_type": (3, "camera", "node", "unknown node type 'patern_source' (did you mean pattern_source"),
    "bad_module_class": (3, "camera", "node", "has no class 'NoSuchClass'"),
    "bad_dangling_node": (8, "sink", "inputs.image", "dangling input: no node publishes 'camra/image'"),
    "bad_dangling_output": (8, "sink", "inputs.image", "node 'camera' (pattern_source) has no output 'depth'"),
    "bad_input_name": (7, "sink", "inputs.frames", "summary_sink has no input 'frames'"),
    "bad_type_mismatch": (8, "camera2", "inputs.tick", "camera/image publishes sensor/Image, input 'tick' expects core/Tick"),
    "bad_param_unknown": (7, "camera", "colour", "unknown parameter"),
    "bad_param_type": (6, "camera", "width", "expected int, got str 'wide'"),
    "bad_param_range": (6, "camera", "height", "below the minimum 1"),
    "bad_param_choice": (8, "fx", "operation", "'sharpen' is not one of"),
    "bad_cycle": (5, "a", "inputs.image", "cycle of blocking inputs a -> b -> a"),
    "bad_duplicate_id": (5, "camera", "id", "duplicate node id"),
    "bad_policy": (8, "sink", "inputs.image", "unknown policy 'newest'"),
    "bad_latest_queue": (8, "sink", "inputs.image", "policy 'latest' keeps one message"),
    "bad_timer": (4, "camera", "inputs.tick", "invalid timer 'timer/fps/10'"),
    "bad_yaml_syntax": (5, None, None, "invalid YAML"),
    "bad_missing_arg": (2, None, "args.fps", "required argument not given"),
    "bad_undeclared_arg": (4, None, "$(arg fps)", "undeclared argument 'fps'"),
    "bad_include_missing": (2, None, "file", "included file not found"),
    "bad_unknown_host": (6, "camera", "host", "unknown host 'robt'"),
    "bad_cross_host_ipc": (10, "sink", "inputs.image", "input crosses hosts"),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_check_reports_error_with_location(name, capsys):
    line, node_id, key, text = CASES[name]
    path = GRAPHS / f"{name}.yaml"
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    first = err.splitlines()[0]
    assert first.startswith(f"error: {path}:{line}: "), first
    if node_id:
        assert f"node '{node_id}'" in first
    if key:
        assert f"key '{key}'" in first
    assert text in first


def test_every_bad_graph_file_has_a_case():
    assert {p.stem for p in GRAPHS.glob("bad_*.yaml")} == set(CASES)


def test_nonblocking_cycle_is_allowed():
    graph = parse_graph(GRAPHS / "ok_cycle_nonblocking.yaml")
    assert validate(graph) == []


def test_include_namespaces_and_args():
    graph = load_checked(str(GRAPHS / "ok_include.yaml"), {"fps": 25})
    assert set(graph.nodes) == {"left/camera", "left/gray", "right/camera", "right/gray", "left_sink", "right_sink"}
    assert graph.nodes["left/gray"].inputs["image"].source == "left/camera/image"
    assert graph.nodes["left_sink"].inputs["image"].source == "left/gray/image"
    assert graph.nodes["left/camera"].inputs["tick"].timer_period_ns == 40_000_000   # fps passed down: 25 Hz
    assert graph.nodes["right/camera"].inputs["tick"].timer_period_ns == 100_000_000  # sub-graph default: 10 Hz
    assert graph.nodes["left_sink"].params == {"out_dir": "out/include/left"}


def test_arg_defaults_take_dirname_and_env_substitutions(tmp_path, monkeypatch):
    monkeypatch.setenv("PROBELESS_TEST_DIR", "from-env")
    g = tmp_path / "sub" / "g.yaml"
    g.parent.mkdir()
    g.write_text("args:\n  out: $(dirname)/out\n  tag: $(env PROBELESS_TEST_DIR)\n"
                 "nodes:\n  - id: sink\n    node: summary_sink\n    params: {out_dir: $(arg out)/$(arg tag)}\n")
    graph = parse_graph(g)
    assert graph.nodes["sink"].params == {"out_dir": f"{g.parent}/out/from-env"}
    graph = parse_graph(g, {"out": "given"})  # an override is taken as given, not substituted again
    assert graph.nodes["sink"].params == {"out_dir": "given/from-env"}


def test_cli_overrides_are_typed_and_unknown_ones_rejected(capsys):
    graph = load_checked(str(GRAPHS.parent.parent / "launch/demo_runtime.yaml"), {"frames": 5})
    assert graph.nodes["camera"].params["count"] == 5
    assert main(["check", str(GRAPHS.parent.parent / "launch/demo_runtime.yaml"), "frame:=3"]) == 2
    assert "unknown argument 'frame'" in capsys.readouterr().err


def test_missing_file_is_a_clear_error(capsys):
    assert main(["check", "no/such/graph.yaml"]) == 2
    assert "no/such/graph.yaml: cannot read" in capsys.readouterr().err


def test_shipped_graphs_validate():
    for path in (GRAPHS.parent.parent / "launch").glob("*.yaml"):
        assert validate(parse_graph(path)) == [], path


def test_graph_arguments_are_accepted_anywhere_on_the_line():
    from probeless.cli import split_overrides

    rest, overrides = split_overrides(["launch", "g.yaml", "--duration", "2", "fps:=10", "--remap", "a:=b", "x:=1"])
    assert rest == ["launch", "g.yaml", "--duration", "2", "--remap", "a:=b"]
    assert overrides == ["fps:=10", "x:=1"]


def test_check_with_argument_after_option(capsys):
    path = str(GRAPHS.parent.parent / "launch/demo_runtime.yaml")
    assert main(["check", path, "frames:=5"]) == 0
    assert main(["graph", path, "--format", "dot", "frames:=5"]) == 0
