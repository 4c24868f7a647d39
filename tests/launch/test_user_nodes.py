"""User nodes outside the repo: ``file.py:Class`` and ``module:Class`` beside the graph, one-line errors,
``probeless nodes list|info``, and an installed package registering a node type by entry point."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from probeless.cli import main
from probeless.nodes import BUILTIN
from probeless.nodes.demo.pattern import pattern_image
from probeless.nodes.demo.transform import OPERATIONS

ROOT = Path(__file__).parents[2]

BLUR = '''
from dataclasses import dataclass

import cv2

from probeless.messages.sensor import Image
from probeless.runtime import Node, param


class Blur(Node):
    """Box blur of every image."""
    INPUTS = {"image": Image}
    OUTPUTS = {"image": Image}

    @dataclass(frozen=True)
    class Params:
        ksize: int = param(3, min=1, max=31, doc="box size [px]")

    def on_input(self, name, msg):
        k = self.params.ksize
        self.ctx.publish("image", Image(msg.header, cv2.blur(msg.data, (k, k)), msg.encoding))
'''

GRAPH = '''
nodes:
  - id: camera
    node: pattern_source
    inputs: {{tick: timer/hz/50}}
    params: {{width: 64, height: 48, count: 3}}
  - id: blur
    node: {node}
    inputs: {{image: {{source: camera/image, policy: block, queue_size: 4}}}}
    params: {{ksize: 5}}
  - id: summary
    node: summary_sink
    inputs: {{image: {{source: blur/image, policy: block, queue_size: 4}}}}
    params: {{out_dir: {out}}}
'''


def cli(*args: str, cwd: Path, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "probeless.cli", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=120, stdin=subprocess.DEVNULL, env=env)


def user_folder(tmp_path: Path, node: str, module: str = BLUR) -> tuple[Path, Path]:
    """A user's folder with ``mynode.py`` and ``graph.yaml``; and an unrelated working folder."""
    folder = tmp_path / "project"
    folder.mkdir(exist_ok=True)
    (folder / "mynode.py").write_text(module)
    (folder / "graph.yaml").write_text(GRAPH.format(node=node, out=tmp_path / "out"))
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir(exist_ok=True)
    return folder / "graph.yaml", elsewhere


@pytest.fixture(autouse=True)
def _forget_user_module():
    yield
    sys.modules.pop("mynode", None)  # the user's module imported by name in this process


def check(graph: Path, cwd: Path, capsys, monkeypatch) -> tuple[int, str, str]:
    """``probeless check GRAPH`` run in this process from ``cwd`` (a subprocess costs seconds of imports)."""
    monkeypatch.chdir(cwd)
    monkeypatch.setattr(sys, "path", list(sys.path))      # the registry adds the graph's folder
    sys.modules.pop("mynode", None)                       # a `mynode` of an earlier test
    capsys.readouterr()
    code = main(["check", str(graph)])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("node", ["mynode:Blur", "./mynode.py:Blur", "mynode.py:Blur"])
def test_user_node_beside_the_graph_checks_from_any_folder(tmp_path, node, capsys, monkeypatch):
    graph, elsewhere = user_folder(tmp_path, node)
    code, out, err = check(graph, elsewhere, capsys, monkeypatch)
    assert code == 0, err
    assert "OK (3 nodes" in out


@pytest.mark.parametrize("module, where, what", [
    ("import os\ndef f(:\n    pass\n", "mynode.py:2", "SyntaxError"),
    ("import os\nimport not_a_module_anywhere\n", "mynode.py:2", "No module named 'not_a_module_anywhere'"),
    ("x = 1\nraise RuntimeError('boom')\n", "mynode.py:2", "RuntimeError: boom"),
])
@pytest.mark.parametrize("node", ["mynode.py:Blur", "mynode:Blur"])
def test_errors_in_a_user_module_are_one_line_naming_file_and_line(tmp_path, module, where, what, node, capsys,
                                                                   monkeypatch):
    graph, elsewhere = user_folder(tmp_path, node, module)
    code, _, err = check(graph, elsewhere, capsys, monkeypatch)
    assert code == 2
    assert "Traceback" not in err
    errors = [line for line in err.splitlines() if line.startswith("error:")]
    assert len(errors) == 1, err
    assert f"{graph}:8: node 'blur'" in errors[0] and where in errors[0] and what in errors[0]


def test_missing_user_node_names_where_it_looked(tmp_path, capsys, monkeypatch):
    graph, elsewhere = user_folder(tmp_path, "nothere:Blur")
    code, _, err = check(graph, elsewhere, capsys, monkeypatch)
    assert code == 2 and f"nor in the graph's folder {graph.parent}" in err
    graph.write_text(GRAPH.format(node="sub/nothere.py:Blur", out="out"))
    code, _, err = check(graph, elsewhere, capsys, monkeypatch)
    assert code == 2 and f"no file {graph.parent / 'sub' / 'nothere.py'} (relative to the graph's folder" in err


@pytest.mark.graph
def test_a_user_node_file_runs_in_a_graph_launched_from_elsewhere(tmp_path):
    graph, elsewhere = user_folder(tmp_path, "mynode.py:Blur")
    run = cli("launch", str(graph), cwd=elsewhere)
    assert run.returncode == 0, run.stderr
    got = cv2.cvtColor(cv2.imread(str(tmp_path / "out" / "last_frame.png")), cv2.COLOR_BGR2RGB)
    np.testing.assert_array_equal(got, cv2.blur(pattern_image(64, 48, 2), (5, 5)))


def _main_out(capsys, *argv: str) -> tuple[int, str, str]:
    capsys.readouterr()
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_nodes_list_and_info(tmp_path, capsys, monkeypatch):
    code, out, err = _main_out(capsys, "nodes", "list", "--json")
    assert code == 0, err
    listed = {e["type"]: e for e in json.loads(out)}
    assert set(BUILTIN) <= set(listed)
    assert listed["image_transform"]["target"] == BUILTIN["image_transform"]
    assert all("error" not in listed[n] for n in ("image_transform", "summary_sink", "pattern_source"))
    info = json.loads(_main_out(capsys, "nodes", "info", "image_transform", "--json")[1])
    assert info["inputs"] == {"image": "sensor/Image"} and info["outputs"] == {"image": "sensor/Image"}
    params = {p["name"]: p for p in info["params"]}
    assert params["operation"]["choices"] == list(OPERATIONS) and params["operation"]["default"] == "blur"
    assert (params["ksize"]["min"], params["ksize"]["max"], params["ksize"]["type"]) == (1, 99, "int")
    text = _main_out(capsys, "nodes", "info", "image_transform")[1]
    assert "ksize: int = 5  [min 1, max 99" in text and "Gaussian kernel size" in text
    graph, _ = user_folder(tmp_path, "mynode.py:Blur")
    monkeypatch.chdir(graph.parent)
    text = _main_out(capsys, "nodes", "info", "mynode.py:Blur")[1]
    assert "ksize: int = 3  [min 1, max 31]" in text and "box size [px]" in text
    code, _, err = _main_out(capsys, "nodes", "info", "no_such_node")
    assert code == 2 and "unknown node type 'no_such_node'" in err


@pytest.mark.slow
@pytest.mark.graph
def test_installed_package_registers_a_node_type_by_entry_point(tmp_path):
    """examples/my_nodes built offline and installed into a temporary folder (not into .venv)."""
    src = tmp_path / "my_nodes"
    shutil.copytree(ROOT / "examples" / "my_nodes", src, ignore=shutil.ignore_patterns("build", "*.egg-info"))
    target = tmp_path / "site"
    pip = subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation",
                          "--no-index", "--target", str(target), str(src)], capture_output=True, text=True,
                         timeout=300)
    assert pip.returncode == 0, pip.stderr
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(target), os.environ.get("PYTHONPATH", "")]))
    run = cli("nodes", "info", "my_threshold", "--json", cwd=tmp_path, env=env)
    assert run.returncode == 0, run.stderr
    info = json.loads(run.stdout)
    assert (info["target"], info["builtin"]) == ("my_nodes.threshold:Threshold", False)
    assert [(p["name"], p["min"], p["max"]) for p in info["params"]] == [("level", 0, 255)]
    run = cli("launch", str(ROOT / "examples" / "my_nodes" / "graph.yaml"), "level:=100",
              f"out_dir:={tmp_path}/out", cwd=tmp_path, env=env)
    assert run.returncode == 0, run.stderr
    gray = cv2.cvtColor(pattern_image(160, 120, 9), cv2.COLOR_RGB2GRAY)
    expected = np.repeat(np.where(gray > 100, 255, 0).astype(np.uint8)[..., None], 3, axis=2)
    got = cv2.cvtColor(cv2.imread(str(tmp_path / "out" / "last_frame.png")), cv2.COLOR_BGR2RGB)
    np.testing.assert_array_equal(got, expected)
