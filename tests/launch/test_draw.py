"""``probeless graph``: Mermaid, DOT, PNG and SVG drawings of launch graphs."""

from __future__ import annotations

import json
import subprocess

import cv2
import pytest
from locations import REPO

from probeless.cli import main
from probeless.errors import ProbelessError
from probeless.launch import draw as draw_mod
from probeless.launch.draw import draw
from probeless.launch.launcher import load_checked

DEMO = REPO / "launch/demo_runtime.yaml"

NAMESPACED = """\
include:
  - {file: cam.yaml, namespace: left-cam}
nodes:
  - id: my-transform
    node: probeless.nodes.demo.transform:ImageTransform
    inputs:
      image: {source: left-cam/camera/image, policy: latest}
  - id: sink
    node: summary_sink
    inputs:
      image: my-transform/image
"""
CAM = """\
nodes:
  - id: camera
    node: pattern_source
    inputs: {tick: timer/ms/50}
    outputs: [image]
"""


@pytest.fixture
def demo():
    return load_checked(str(DEMO), {})


@pytest.fixture
def namespaced(tmp_path):
    (tmp_path / "main.yaml").write_text(NAMESPACED)
    (tmp_path / "cam.yaml").write_text(CAM)
    return load_checked(str(tmp_path / "main.yaml"), {})


def dot_json(text: str) -> dict:
    """Parse DOT with Graphviz itself; fails the test on any syntax error."""
    proc = subprocess.run(["dot", "-Tjson"], input=text, capture_output=True, text=True, check=True)
    assert proc.stderr == ""
    return json.loads(proc.stdout)


def test_mermaid_default(demo):
    text = draw(demo, None, None)
    assert text.startswith("flowchart LR\n")
    for node_id, decl in demo.nodes.items():
        assert f'"{node_id}<br/>{decl.node}"' in text
    assert '-->|"image → image<br/>sensor/Image<br/>block/4"|' in text
    assert '(["timer 30 Hz"])' in text and text.count("-->") == 3


@pytest.mark.graph
def test_dot_parses_with_right_counts(demo):
    text = draw(demo, "dot", None)
    for node_id in demo.nodes:
        assert f'"{node_id}" [label=' in text
    assert '"camera" -> "transform" [label="image → image\\nsensor/Image\\nblock/4"]' in text
    parsed = dot_json(text)
    names = [o["name"] for o in parsed["objects"]]
    assert sorted(names) == sorted([*demo.nodes, "timer:camera/tick"])
    pairs = {(names[e["tail"]], names[e["head"]]) for e in parsed["edges"]}
    assert pairs == {("timer:camera/tick", "camera"), ("camera", "transform"), ("transform", "summary")}
    plain = subprocess.run(["dot", "-Tplain"], input=text, capture_output=True, text=True, check=True).stdout
    assert sum(line.startswith("node ") for line in plain.splitlines()) == 4
    assert sum(line.startswith("edge ") for line in plain.splitlines()) == 3


@pytest.mark.graph
def test_png_and_svg(demo, tmp_path):
    png = tmp_path / "sub/g.png"
    text = draw(demo, None, str(png))
    assert text.startswith("digraph probeless {")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    image = cv2.imread(str(png))
    assert image is not None and image.shape[0] > 50 and image.shape[1] > 200
    svg = tmp_path / "g.svg"
    draw(demo, None, str(svg))
    body = svg.read_text()
    assert "<svg" in body and "sensor/Image" in body and "timer 30 Hz" in body


@pytest.mark.graph
def test_namespaced_ids_policies_and_timer_units(namespaced):
    text = draw(namespaced, "dot", None)
    parsed = dot_json(text)
    names = sorted(o["name"] for o in parsed["objects"])
    assert names == sorted(["left-cam/camera", "my-transform", "sink", "timer:left-cam/camera/tick"])
    labels = [e["label"].replace("\\n", "\n") for e in parsed["edges"]]  # json keeps the \n escapes
    assert sorted(labels) == ["image → image\nsensor/Image",  # default drop_oldest/10 not shown
                              "image → image\nsensor/Image\nlatest", "tick"]
    mermaid = draw(namespaced, "mermaid", None)
    assert '"left-cam/camera<br/>pattern_source"' in mermaid and "timer 50 ms" in mermaid
    assert '"my-transform<br/>probeless.nodes.demo.transform:ImageTransform"' in mermaid
    for line in mermaid.splitlines()[1:]:  # bare mermaid ids are n0.. / t0..: graph ids only inside quotes
        bare = "".join(line.split('"')[0::2])
        assert "/" not in bare and "left-cam" not in bare and "my-transform" not in bare, line


def test_format_from_suffix_and_errors(demo, tmp_path, monkeypatch):
    assert draw(demo, None, str(tmp_path / "g.mmd")).startswith("flowchart LR")
    assert (tmp_path / "g.md").exists() is False
    md = draw(demo, None, str(tmp_path / "g.md"))
    assert md.startswith("```mermaid\nflowchart LR") and (tmp_path / "g.md").read_text() == md
    assert draw(demo, None, str(tmp_path / "g.gv")).startswith("digraph")
    assert (tmp_path / "g.gv").read_text().startswith("digraph")
    with pytest.raises(ProbelessError, match="cannot tell the format"):
        draw(demo, None, str(tmp_path / "g.txt"))
    with pytest.raises(ProbelessError, match="unknown graph format"):
        draw(demo, "jpeg", None)
    with pytest.raises(ProbelessError, match="needs an output file"):
        draw(demo, "png", None)
    monkeypatch.setattr(draw_mod.shutil, "which", lambda name: None)
    with pytest.raises(ProbelessError, match="install graphviz"):
        draw(demo, "png", str(tmp_path / "x.png"))
    assert not (tmp_path / "x.png").exists()


@pytest.mark.graph
def test_cli_graph_png(tmp_path, capsys):
    out = tmp_path / "g.png"
    assert main(["graph", str(DEMO), "--out", str(out)]) == 0
    assert f"wrote {out}" in capsys.readouterr().out
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert main(["graph", str(DEMO), "fps:=15"]) == 0
    assert "timer 15 Hz" in capsys.readouterr().out
