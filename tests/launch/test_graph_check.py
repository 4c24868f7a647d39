"""`probeless check`: every malformed graph in tests/graphs/ is caught with a message naming file, line, node, key."""

from __future__ import annotations

import re

import pytest
from locations import GRAPHS

from probeless.cli import main
from probeless.launch.graph import parse_graph
from probeless.launch.launcher import load_checked
from probeless.launch.validate import validate

# file -> (line, node id or None, key or None, text the message must contain)
CASES = {
    "bad_unknown_top_key": (1, None, "node", "did you mean 'nodes'"),
    "bad_unknown_node_key": (5, "camera", "parameters", "unknown node key"),
    "bad_unknown_node_type": (3, "camera", "node", "unknown node type 'patern_source' (did you mean pattern_source"),
    "bad_module_class": (3, "camera", "node", "has no class 'NoSuchClass'"),
    "bad_dangling_node": (8, "sink", "inputs.image", "dangling input: no node publishes 'camra/image'"),
    "bad_dangling_output": (8, "sink", "inputs.image", "node 'camera' (pattern_source) has no output 'depth'"),
    "bad_input_name": (7, "sink", "inputs.frames", "summary_sink has no input 'frames'"),
    "bad_type_mismatch": (8, "camera2", "inputs.tick",
                          "camera/image publishes sensor/Image, input 'tick' expects core/Tick"),
    "bad_param_unknown": (7, "camera", "colour", "unknown parameter"),
    "bad_param_type": (6, "camera", "width", "expected int, got a string 'wide'"),
    "bad_param_range": (6, "camera", "height", "below the minimum 1"),
    "bad_param_choice": (8, "fx", "operation", "'sharpen' is not one of"),
    "bad_param_length": (5, "interp", "translation", "needs 3 value(s), got 2"),
    "bad_param_nonfinite": (6, "interp", "rpy_deg", "not finite"),
    "bad_param_missing_file": (6, "player", "path", "no/such/recording.mcap: file not found"),
    "bad_param_rule": (10, "fx", "ksize", "ksize must be odd, got 4"),
    "bad_cycle": (5, "a", "inputs.image", "cycle of blocking inputs a -> b -> a"),
    "bad_duplicate_id": (5, "camera", "id", "duplicate node id"),
    "bad_policy": (8, "sink", "inputs.image", "unknown policy 'newest'"),
    "bad_latest_queue": (8, "sink", "inputs.image", "policy 'latest' keeps one message"),
    "bad_max_bytes": (8, "sink", "inputs.image", "max_bytes must be an integer >= 1"),
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


def test_an_env_value_standing_alone_is_typed_like_a_command_line_value(tmp_path, monkeypatch):
    g = tmp_path / "g.yaml"
    g.write_text("nodes:\n  - id: cam\n    node: pattern_source\n    inputs: {tick: timer/hz/5}\n"
                 "    params: {count: $(env PROBELESS_TEST_COUNT 3), width: $(env PROBELESS_TEST_W)}\n")
    monkeypatch.setenv("PROBELESS_TEST_W", "320")
    graph = parse_graph(g)
    assert graph.nodes["cam"].params == {"count": 3, "width": 320} and validate(graph) == []
    monkeypatch.setenv("PROBELESS_TEST_W", "0320")          # leading zeros: not a number, stays text
    graph = parse_graph(g)
    assert graph.nodes["cam"].params["width"] == "0320"
    assert "expected int, got a string '0320'" in validate(graph)[0].message


def test_arg_defaults_may_use_arguments_declared_above(tmp_path):
    g = tmp_path / "g.yaml"
    g.write_text("args:\n  scene: a.yaml\n  objects: {default: $(arg scene)}\n  both: $(arg scene)+$(arg objects)\n"
                 "nodes:\n  - id: sink\n    node: summary_sink\n    params: {out_dir: $(arg both)}\n")
    assert parse_graph(g).nodes["sink"].params == {"out_dir": "a.yaml+a.yaml"}
    assert parse_graph(g, {"scene": "b.yaml"}).nodes["sink"].params == {"out_dir": "b.yaml+b.yaml"}
    assert parse_graph(g, {"objects": "o.yaml"}).nodes["sink"].params == {"out_dir": "a.yaml+o.yaml"}
    g.write_text("args:\n  objects: {default: $(arg scene)}\n  scene: a.yaml\n"
                 "nodes:\n  - id: sink\n    node: summary_sink\n    params: {out_dir: $(arg objects)}\n")
    errors = [e.format() for e in parse_graph(g).errors]
    assert len(errors) == 1 and "undeclared argument 'scene'" in errors[0] and ":2:" in errors[0], errors


def test_cli_overrides_are_typed_and_unknown_ones_rejected(capsys):
    graph = load_checked(str(GRAPHS.parent.parent / "launch/demo_runtime.yaml"), {"frames": 5})
    assert graph.nodes["camera"].params["count"] == 5
    assert main(["check", str(GRAPHS.parent.parent / "launch/demo_runtime.yaml"), "frame:=3"]) == 2
    assert "unknown argument 'frame'" in capsys.readouterr().err


def test_missing_file_is_a_clear_error(capsys):
    assert main(["check", "no/such/graph.yaml"]) == 2
    assert "no/such/graph.yaml: cannot read" in capsys.readouterr().err


def test_shipped_graphs_validate(monkeypatch):
    monkeypatch.chdir(GRAPHS.parent.parent)  # their default files are relative to the repository
    for path in (GRAPHS.parent.parent / "launch").glob("*.yaml"):
        assert validate(parse_graph(path)) == [], path


def test_check_names_a_missing_scene_file(monkeypatch, capsys):
    """A new user's typo: the scene file is reported by `check` (and so by `launch`), before any node starts."""
    monkeypatch.chdir(GRAPHS.parent.parent)
    assert main(["check", "launch/probeless.yaml", "scene:=nonexistent.yaml"]) == 2
    err = capsys.readouterr().err
    # one error for one bad argument (issue 28): the argument, the missing file, and every param it reached
    # with its file:line (the rig's params in the included source file; the objects default to the scene's)
    errors = [line for line in err.splitlines() if line.startswith("error:")]
    assert len(errors) == 1, errors
    assert errors[0].startswith("error: command line: argument scene:=nonexistent.yaml: nonexistent.yaml: "
                                "file not found"), errors[0]
    assert re.search(r"rig\.scene \(\S*launch/sources/synthetic\.yaml:\d+\)", errors[0]), errors[0]
    assert "envmap.objects_file" in errors[0] and "compositor.objects_file" in errors[0]
    assert "Traceback" not in err
    assert main(["launch", "launch/probeless.yaml", "scene:=nonexistent.yaml"]) == 2  # nothing is started
    assert capsys.readouterr().err == err


def test_check_reports_every_param_rule_with_location(monkeypatch, tmp_path, capsys):
    """Rules that used to run in nodes' setup(): a check= rule across params, a path, a [2H, H] size."""
    monkeypatch.chdir(GRAPHS.parent.parent)
    g = tmp_path / "g.yaml"
    g.write_text(f"""nodes:
  - id: envmap
    node: baseline_envmap
    params:
      object_ids: [a, b]
      object_positions: [[0, 0, 1]]
  - id: camera
    node: fisheye_player
    params: {{path: {GRAPHS.parent.parent}/launch/scenes, calibration: no_calib.yaml}}
  - id: diffuse
    node: diffuse_map
    params:
      out_size: [32, 8]
  - id: slam
    node: dense_slam
    params:
      initial_pose: [0, 0, 0, 0, 0, 0, 0]
""")
    assert main(["check", str(g)]) == 2
    lines = capsys.readouterr().err.splitlines()
    expected = [f"error: {g}:6: node 'envmap': key 'object_positions': 2 object_ids but 1 object_positions",
                f"error: {g}:9: node 'camera': key 'calibration': no_calib.yaml: file not found",
                f"error: {g}:13: node 'diffuse': key 'out_size': out_size must be [2H, H], got [32, 8]",
                f"error: {g}:17: node 'slam': key 'initial_pose': needs 7 finite numbers"]
    for want in expected:
        assert any(line.startswith(want) for line in lines), (want, lines)
    assert lines[-1] == "4 error(s)"


def test_graph_arguments_are_accepted_anywhere_on_the_line():
    from probeless.cli import split_overrides

    rest, overrides = split_overrides(["launch", "g.yaml", "--duration", "2", "fps:=10", "--remap", "a:=b", "x:=1"])
    assert rest == ["launch", "g.yaml", "--duration", "2", "--remap", "a:=b"]
    assert overrides == ["fps:=10", "x:=1"]


def test_check_with_argument_after_option(capsys):
    path = str(GRAPHS.parent.parent / "launch/demo_runtime.yaml")
    assert main(["check", path, "frames:=5"]) == 0
    assert main(["graph", path, "--format", "dot", "frames:=5"]) == 0
