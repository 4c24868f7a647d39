"""Sweep files: up-front errors name the file, line and key; axes cross, zip and exclude into stable runs;
collected keys are picked out of a run's JSON."""

from __future__ import annotations

import pytest
from sweep_common import ROOT, write_sweep

from probeless.errors import SweepError
from probeless.sweep.driver import prepare
from probeless.sweep.expand import expand
from probeless.sweep.spec import load_sweep
from probeless.sweep.table import collect_value


def _sweep(tmp_path, text: str):
    path = tmp_path / "s.yaml"
    path.write_text(text)
    return path


def _error(path, tmp_path) -> SweepError:
    with pytest.raises(SweepError) as info:
        prepare(path, tmp_path / "out")
    return info.value


def _line_of(path, needle: str) -> int:
    return next(i for i, line in enumerate(path.read_text().splitlines(), 1) if needle in line)


def test_unknown_keys_are_errors_with_file_and_line(tmp_path):
    path = _sweep(tmp_path, "run:\n  eval: envmap\n  argz: []\naxes:\n  a: [1]\ncolect: {}\n")
    err = _error(path, tmp_path)
    assert f"{path}:3: key 'run.argz': unknown key" in str(err)
    assert f"{path}:6: key 'colect': unknown key" in str(err)


def test_a_bad_flag_names_the_run_and_the_args_line(tmp_path):
    path = write_sweep(tmp_path / "s.yaml")
    path.write_text(path.read_text().replace('"--stride"', '"--no-such-flag"').replace("--stride", "--no-such-flag"))
    err = _error(path, tmp_path)
    assert (err.file, err.line, err.key) == (str(path), _line_of(path, "args:"), "run.args")
    assert "unrecognized arguments: --no-such-flag" in err.message and "run red_wall-ours" in err.message


def test_a_bad_choice_from_an_axis_is_an_error(tmp_path):
    err = _error(write_sweep(tmp_path / "s.yaml", methods=("ours", "oursx")), tmp_path)
    assert "invalid choice: 'oursx'" in err.message and "run red_wall-oursx" in err.message


def test_a_missing_input_file_names_the_axis_value_line(tmp_path):
    path = write_sweep(tmp_path / "s.yaml", scenes=(str(tmp_path / "nowhere.yaml"),))
    err = _error(path, tmp_path)
    assert (err.line, err.key) == (_line_of(path, "nowhere.yaml"), "axes.scene")
    assert "no such file" in err.message


def test_unknown_placeholder_and_unknown_evaluation(tmp_path):
    path = _sweep(tmp_path, "run:\n  eval: envmapp\n  args: ['{scen}']\naxes:\n  scene: [a]\n")
    err = _error(path, tmp_path)
    assert f"{path}:2: key 'run.eval': unknown evaluation 'envmapp'" in str(err)
    assert f"{path}:3: key 'run.args': unknown placeholder {{scen}}" in str(err)


def test_a_graph_arg_that_the_graph_does_not_declare_is_an_error(tmp_path):
    path = _sweep(tmp_path, f"run:\n  graph: {ROOT}/launch/demo_runtime.yaml\n  args: {{framez: '{{n}}'}}\n"
                            "axes:\n  n: [3]\n")
    err = _error(path, tmp_path)
    assert err.line == 3 and "unknown argument 'framez'" in err.message


def test_cross_zip_exclude_and_mapping_values(tmp_path):
    text = ("run:\n  eval: envmap\n  args: ['{scene}', '{mode_args}']\naxes:\n"
            "  scene: [a.yaml, b.yaml]\n"
            "  mode:\n    - {name: oracle, mode_args: [--oracle]}\n    - {name: graph, mode_args: [--graph, g.yaml]}\n"
            "exclude:\n  - {scene: b.yaml, mode: graph}\n")
    runs = expand(load_sweep(_sweep(tmp_path, text)), tmp_path / "out")
    assert [r.run_id for r in runs] == ["a-oracle", "a-graph", "b-oracle"]
    assert runs[1].argv[:5] == ["eval", "envmap", "a.yaml", "--graph", "g.yaml"]
    assert runs[1].labels == {"scene": "a.yaml", "mode": "graph"}
    assert runs[0].run_dir == str((tmp_path / "out" / "a-oracle").resolve())
    zipped = expand(load_sweep(_sweep(tmp_path, text.split("exclude")[0] + "combine: zip\n")), tmp_path)
    assert [r.run_id for r in zipped] == ["a-oracle", "b-graph"]


def test_resume_key_follows_the_command_and_the_input_bytes(tmp_path):
    scene = tmp_path / "scene.yaml"
    scene.write_text("a: 1\n")
    text = f"run:\n  eval: envmap\n  args: ['{scene}', '--stride', '{{s}}']\naxes:\n  s: [1, 2]\n"
    one, two = expand(load_sweep(_sweep(tmp_path, text)), tmp_path / "out")
    assert one.key() != two.key()
    assert one.key() == expand(load_sweep(_sweep(tmp_path, text)), tmp_path / "elsewhere")[0].key()
    key = one.key()
    scene.write_text("a: 2\n")
    assert one.key() != key


def test_collect_paths():
    result = {"ours": {"sphere": {"psnr": 20.0}, "cube": {"psnr": 30.0}, "torus": {"psnr": None}},
              "times": [1, 2, 3]}
    assert collect_value(result, "ours.sphere.psnr") == 20.0
    assert collect_value(result, "ours.*.psnr") == 25.0  # mean over the matches, nulls skipped
    assert collect_value(result, "times.-1") == 3
    assert collect_value(result, "ours.nothing.psnr") is None


def test_ray_missing_names_the_extra(tmp_path, monkeypatch):
    from probeless.sweep.ray_runner import import_ray

    monkeypatch.setitem(__import__("sys").modules, "ray", None)  # `import ray` raises ImportError
    with pytest.raises(SweepError, match=r"pip install 'probeless\[cluster\]'"):
        import_ray()
