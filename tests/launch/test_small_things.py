"""The small things a new user trips over (issue 28, item 7): each message says what is wrong in the user's terms."""

from __future__ import annotations

import difflib
from pathlib import Path

import pytest
import yaml
from locations import REPO as ROOT

from probeless.cli import main
from probeless.launch.graph import parse_graph
from probeless.launch.validate import validate
from probeless.nodes.demo.summary import summary_line

DEMO = ROOT / "launch" / "demo_runtime.yaml"


def _errors(text: str, tmp_path: Path, **overrides) -> list:
    path = tmp_path / "g.yaml"
    path.write_text(text)
    return validate(parse_graph(path, overrides))


SOURCE = """
args:
  fps: {default: 30, min: 1, max: 240}
nodes:
  - id: src
    node: pattern_source
    inputs: {tick: timer/hz/$(arg fps)}
    params: {width: 32, height: 24}
"""


def test_latency_is_printed_with_sensible_precision():
    p50 = 3.0082839999999997
    line = summary_line("out/summary.json", {"frames": 90, "rate_hz": 29.97, "latency_ms_p50": p50})
    assert line == f"wrote out/summary.json: 90 frames, 30.0 Hz, latency p50 {round(p50, 2)} ms"
    assert summary_line("s.json", {"frames": 0, "rate_hz": None, "latency_ms_p50": None}).endswith(
        "0 frames, n/a Hz, latency p50 n/a ms")


def test_a_wrong_param_type_is_named_in_yaml_terms(tmp_path):
    errors = _errors(SOURCE.replace("width: 32", "width: [3]"), tmp_path)
    assert len(errors) == 1
    msg = errors[0].format()
    assert "key 'width': expected int, got a list [3]" in msg and "LineList" not in msg
    errors = _errors(SOURCE.replace("width: 32", "width: {a: 1}"), tmp_path)
    assert "got a mapping {a: 1}" in errors[0].format() and "LineDict" not in errors[0].format()


def test_a_dangling_input_gets_a_did_you_mean(tmp_path):
    text = SOURCE + """
  - id: fx
    node: image_transform
    inputs: {image: src/imgae}
"""
    (error,) = _errors(text, tmp_path)
    expected = difflib.get_close_matches("imgae", ["image", "diagnostics"], n=1)[0]
    assert f"has no output 'imgae' (did you mean '{expected}'?" in error.message
    (error,) = _errors(text.replace("src/imgae", "scr/image"), tmp_path)
    assert "no node publishes 'scr/image' (did you mean 'src/image'?" in error.message


def test_a_bad_command_line_argument_is_a_command_line_error(tmp_path):
    (error,) = _errors(SOURCE, tmp_path, fsp=3)
    assert error.file == "command line" and error.line is None
    assert error.format() == ("command line: argument fsp:=3: unknown argument 'fsp' "
                              "(did you mean 'fps'? declared: fps)")


def test_fps_zero_names_fps_and_its_range(tmp_path):
    errors = validate(parse_graph(DEMO, {"fps": 0}))
    assert [e.format() for e in errors] == ["command line: argument fps:=0: 0 is out of range (allowed: 1 to 240)"]
    # a literal timer of rate 0 says what is wrong with it
    (error,) = _errors(SOURCE.replace("timer/hz/$(arg fps)", "timer/hz/0"), tmp_path)
    assert "timer 'timer/hz/0': the rate must be above 0, got 0" in error.message


def test_one_bad_scene_argument_is_one_error():
    errors = validate(parse_graph(ROOT / "launch" / "probeless.yaml", {"scene": "nope.yaml"}))
    assert len(errors) == 1, [e.format() for e in errors]
    msg = errors[0].format()
    assert msg.startswith("command line: argument scene:=nope.yaml: nope.yaml: file not found")
    for use in ("rig.scene", "envmap.objects_file", "compositor.objects_file"):  # every param it reached
        assert use in msg


def test_launch_show_args_lists_the_graph_arguments(capsys):
    assert main(["launch", str(DEMO), "--show-args"]) == 0
    out = capsys.readouterr().out
    declared = yaml.safe_load(DEMO.read_text())["args"]
    for name, spec in declared.items():
        assert f"    {name}:\n" in out
        default = spec["default"] if isinstance(spec, dict) else spec
        assert f"default: {default!r}" in out
    assert "allowed: 1 to 240" in out and "frames to publish before the graph ends" in out


@pytest.mark.parametrize("argv", [["check", str(DEMO), "fps:=0"], ["launch", str(DEMO), "fps:=0"]])
def test_fps_zero_on_the_command_line_stops_before_anything_starts(argv, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "argument fps:=0: 0 is out of range (allowed: 1 to 240)" in err and "timer/hz/0" not in err
