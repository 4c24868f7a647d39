"""Paths in a graph: input files from the graph file's folder, command-line paths and outputs from the
working folder; every shipped graph checks from any working folder; an unwritable output folder is one line."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest
from locations import REPO, SHARED_DATA

from probeless.cli import main
from probeless.errors import GraphErrors
from probeless.launch.launcher import load_checked

SHIPPED = sorted((REPO / "launch").glob("*.yaml"))

READER = '''
from dataclasses import dataclass

from probeless.runtime import Node, param


class Reader(Node):
    """Reads a file at setup (here: only declares it)."""

    @dataclass(frozen=True)
    class Params:
        path: str = param(path="file", must_exist=True, doc="an input file")
        out_dir: str = param("out/x", doc="an output folder: relative to the working folder")
'''


@pytest.mark.parametrize("graph", SHIPPED, ids=[g.name for g in SHIPPED])
def test_every_shipped_graph_checks_from_another_working_folder(graph, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    try:
        load_checked(str(graph), {})
    except GraphErrors as exc:
        shared = str(SHARED_DATA.resolve())
        if not SHARED_DATA.exists() and all(shared in e.message or "shared/data" in e.message for e in exc.errors):
            pytest.skip(f"{graph.name} needs the shared data ({SHARED_DATA}), absent here")
        raise
    assert not (tmp_path / "launch").exists() and list(tmp_path.iterdir()) == []  # check writes nothing


def _project(tmp_path: Path) -> tuple[Path, Path]:
    """proj/graph.yaml including proj/sub/part.yaml; input files in both folders; a separate working folder."""
    proj = tmp_path / "proj"
    (proj / "sub" / "data").mkdir(parents=True)
    (proj / "data").mkdir()
    for f in ("data/a.txt", "data/b.txt", "sub/data/c.txt"):
        (proj / f).write_text(f)
    (proj / "reader.py").write_text(READER)
    (proj / "graph.yaml").write_text("""
args:
  a: {default: data/a.txt}
  b: data/b.txt
nodes:
  - id: literal
    node: reader.py:Reader
    params: {path: data/a.txt}
  - id: from_arg
    node: reader.py:Reader
    params: {path: $(arg a)}
include:
  - {file: sub/part.yaml, namespace: sub, args: {given: $(arg b), literal: data/b.txt}}
""")
    (proj / "sub" / "part.yaml").write_text("""
args:
  given: {doc: a path from the including file}
  literal: {doc: another}
  own: data/c.txt
nodes:
  - id: given
    node: ../reader.py:Reader
    params: {path: $(arg given)}
  - id: literal
    node: ../reader.py:Reader
    params: {path: $(arg literal)}
  - id: own
    node: ../reader.py:Reader
    params: {path: $(arg own), out_dir: out/own}
""")
    work = tmp_path / "work"
    (work / "data").mkdir(parents=True)
    (work / "data" / "a.txt").write_text("working folder's a")
    return proj, work


def test_relative_inputs_come_from_the_file_that_wrote_them(tmp_path, monkeypatch):
    proj, work = _project(tmp_path)
    monkeypatch.chdir(work)
    monkeypatch.setattr(sys, "path", list(sys.path))
    graph = load_checked(str(proj / "graph.yaml"), {})
    paths = {nid: Path(d.params["path"]) for nid, d in graph.nodes.items()}
    assert paths == {"literal": proj / "data/a.txt", "from_arg": proj / "data/a.txt",
                     "sub/given": proj / "data/b.txt", "sub/literal": proj / "data/b.txt",
                     "sub/own": proj / "sub/data/c.txt"}
    assert graph.nodes["sub/own"].params["out_dir"] == "out/own"  # outputs: as written, the working folder's
    # a path given on the command line is the working folder's, as in a shell
    graph = load_checked(str(proj / "graph.yaml"), {"a": "data/a.txt"})
    assert Path(os.path.abspath(graph.nodes["from_arg"].params["path"])) == work / "data/a.txt"
    assert Path(graph.nodes["literal"].params["path"]) == proj / "data/a.txt"


def test_a_missing_input_names_the_value_and_the_graph_folder(tmp_path, monkeypatch, capsys):
    proj, work = _project(tmp_path)
    (proj / "data" / "a.txt").unlink()
    monkeypatch.chdir(work)
    monkeypatch.setattr(sys, "path", list(sys.path))
    assert main(["check", str(proj / "graph.yaml")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err[0] == (f"error: {proj / 'graph.yaml'}:8: node 'literal': key 'path': data/a.txt: file not found "
                      f"(relative to the graph's folder {proj})")
    assert err[-1] == "2 error(s)"  # `literal` and `from_arg`; the working folder's data/a.txt is not taken


def test_unwritable_output_folder_is_one_line_at_check(tmp_path, capsys):
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    graph = REPO / "launch" / "demo_runtime.yaml"
    assert main(["check", str(graph), f"out_dir:={blocker}/out"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if line.startswith("error:")]
    assert lines and all(f"cannot create the folder, {blocker} is a file" in line for line in lines)
    assert main(["launch", str(graph), f"out_dir:={blocker}/out"]) == 2  # refused before anything starts


def test_every_writer_refuses_an_unwritable_output_at_check(tmp_path, capsys):
    """png_writer, video_writer and bag_recorder (hdr_cloud_writer: the same check) refuse an unwritable output as
    summary_sink does: one line per node naming file, line, node and key (before: a traceback at the first write)."""
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    g = tmp_path / "g.yaml"
    g.write_text(f"""nodes:
  - id: cam
    node: pattern_source
    inputs: {{tick: timer/hz/10}}
  - id: png
    node: png_writer
    inputs: {{image: cam/image}}
    params: {{out_dir: {blocker}/frames}}
  - id: video
    node: video_writer
    inputs: {{image: cam/image}}
    params: {{path: {blocker}/v.mp4}}
  - id: rec
    node: bag_recorder
    inputs: {{image: cam/image}}
    params: {{path: {blocker}/run.mcap}}
""")
    assert main(["check", str(g)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err == [f"error: {g}:8: node 'png': key 'out_dir': {blocker}/frames: cannot create the folder, {blocker} "
                   f"is a file",
                   f"error: {g}:12: node 'video': key 'path': {blocker}/v.mp4: cannot create the folder, {blocker} "
                   f"is a file",
                   f"error: {g}:16: node 'rec': key 'path': {blocker}/run.mcap: cannot create the folder, {blocker} "
                   f"is a file",
                   "3 error(s)"]
    from probeless.runtime.params import writable_file_problem

    assert writable_file_problem(str(tmp_path / "new" / "x.ply")) is None  # missing folders are created
    assert "is a file" in writable_file_problem(f"{blocker}/x.ply")


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes anywhere")
def test_output_folder_without_permission_is_reported(tmp_path, capsys):
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    assert main(["check", str(REPO / "launch" / "demo_runtime.yaml"), f"out_dir:={locked}/out"]) == 2
    assert f"cannot write in {locked} (permission denied)" in capsys.readouterr().err
