"""Pattern inputs (``source: "*"``): one input per matching topic, named by it; errors name file, line, node, key."""

from __future__ import annotations

import textwrap

import pytest
from locations import GRAPHS

from probeless.launch.graph import parse_graph
from probeless.launch.plan import build_plan
from probeless.launch.validate import validate

HEAD = """
nodes:
  - id: cam
    node: pattern_source
    inputs: {tick: timer/hz/10}
    outputs: [image]
  - id: fx
    node: image_transform
    inputs: {image: cam/image}
    outputs: [image]
"""


def _graph(tmp_path, tail: str):
    path = tmp_path / "g.yaml"
    path.write_text(HEAD + textwrap.indent(textwrap.dedent(tail).lstrip("\n"), "  "))
    graph = parse_graph(path)
    return graph, validate(graph)


def test_a_pattern_becomes_one_input_per_topic_named_by_it_with_the_pattern_policy(tmp_path):
    graph, errors = _graph(tmp_path, """
      - id: rec
        node: bag_recorder
        params: {path: out.mcap}
        inputs:
          all: {source: "*", policy: latest, max_bytes: 4096}
    """)
    assert errors == []
    inputs = graph.nodes["rec"].inputs
    # every output of every other node, diagnostics included, and nothing of its own
    assert sorted(inputs) == ["cam/diagnostics", "cam/image", "fx/diagnostics", "fx/image"]
    for topic, inp in inputs.items():
        assert inp.source == topic and inp.policy == "latest" and inp.max_bytes == 4096
    plan = build_plan(graph, tmp_path)
    wired = {i["name"]: i["topic"] for i in plan["nodes"]["rec"]["inputs"]}
    assert wired == {t: t for t in inputs}
    assert plan["nodes"]["cam"]["outputs"]["image"]["subscribers"] == 2      # fx and the recorder


def test_exclude_and_narrow_patterns(tmp_path):
    graph, errors = _graph(tmp_path, """
      - id: rec
        node: bag_recorder
        params: {path: out.mcap}
        inputs:
          images: {source: "*/image", exclude: ["fx/*"]}
          explicit: {source: cam/image, policy: block}
    """)
    assert errors == []
    inputs = graph.nodes["rec"].inputs
    # cam/image is wired explicitly (block): the pattern does not add it a second time
    assert sorted(inputs) == ["explicit"] and inputs["explicit"].policy == "block"


def test_two_pattern_nodes_do_not_subscribe_to_each_other(tmp_path):
    graph, errors = _graph(tmp_path, """
      - id: rec1
        node: bag_recorder
        params: {path: a.mcap}
        inputs: {all: "*"}
      - id: rec2
        node: bag_recorder
        params: {path: b.mcap}
        inputs: {all: "*"}
    """)
    assert errors == []
    assert not any(t.startswith("rec") for n in ("rec1", "rec2") for t in graph.nodes[n].inputs)


@pytest.mark.parametrize("tail, line, text", [
    ("""
      - id: rec
        node: bag_recorder
        params: {path: out.mcap}
        inputs:
          all: {source: "nothing/*"}
    """, 15, "pattern 'nothing/*' matches no topic of the graph (topics: cam/diagnostics, cam/image"),
    ("""
      - id: sink
        node: summary_sink
        inputs:
          image: {source: "*"}
    """, 14, "summary_sink takes only its named inputs (image); patterns are for nodes that take any topic"),
    ("""
      - id: rec
        node: bag_recorder
        params: {path: out.mcap}
        inputs:
          all: {source: cam/image, exclude: [x]}
    """, 15, "exclude applies to a pattern source"),
    ("""
      - id: rec
        node: bag_recorder
        params: {path: out.mcap}
        inputs:
          all: {source: "*", exclude: x}
    """, 15, "exclude must be a list of topic patterns"),
])
def test_bad_patterns_are_named(tmp_path, tail, line, text):
    _, errors = _graph(tmp_path, tail)
    assert len(errors) == 1, errors
    assert errors[0].line == line and text in errors[0].message, errors[0]
    assert errors[0].key.startswith("inputs.")


@pytest.mark.parametrize("graph", ["probeless", "tracking", "pano360_ibl"])
@pytest.mark.parametrize("viewer", ["none", "rerun", "foxglove"])
def test_shipped_graphs_take_every_viewer(monkeypatch, graph, viewer):
    monkeypatch.chdir(GRAPHS.parent.parent)
    g = parse_graph(f"launch/{graph}.yaml", {"viewer": viewer})
    assert validate(g) == []
    node = {"rerun": "rerun", "foxglove": "foxglove"}.get(viewer)
    if node is None:
        assert not {"rerun", "foxglove"} & set(g.nodes)
        return
    inputs = g.nodes[node].inputs
    # the viewer sees every other node's declared outputs and diagnostics, each through a lossy input
    others = [d for d in g.nodes.values() if d.id != node]
    assert {f"{d.id}/diagnostics" for d in others} <= set(inputs)
    assert all(i.policy == "latest" for i in inputs.values())
    if graph == "probeless":
        assert {"slam/pose", "rig/rgb", "texturer/atlas", "envmap/envmaps", "compositor/image"} <= set(inputs)
