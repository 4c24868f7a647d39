"""Replay respects swaps: a node whose type differs from the recorded one runs live, and the launcher says so.

The process tests record a three-node graph (camera -> filter -> summary) once with the filter being a
user's node in a file beside the graph, then replay it with the graph's default filter (the issue's
trap: record with ``envmap_node:=baseline_envmap``, replay without the argument). The reference for
what the summary saw is OpenCV applied to the recorded camera frames.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from probeless.bag.reader import BagReader
from probeless.errors import GraphError
from probeless.launch.launcher import load_checked
from probeless.launch.replay import add_player

USER_NODE = '''
import dataclasses

import cv2

from probeless.messages.sensor import Image
from probeless.runtime import Node


class Invert(Node):
    """Inverts every image."""
    INPUTS = {"image": Image}
    OUTPUTS = {"image": Image}

    def on_input(self, name, msg):
        self.ctx.publish("image", dataclasses.replace(msg, data=cv2.bitwise_not(msg.data)))
'''

GRAPH = '''
args:
  filter: image_transform
  out_dir: out/summary
nodes:
  - id: camera
    node: pattern_source
    inputs: {tick: timer/hz/50}
    params: {width: 64, height: 48, count: 4}
  - id: filter
    node: $(arg filter)
    inputs: {image: {source: camera/image, policy: block, queue_size: 8}}
  - id: summary
    node: summary_sink
    inputs: {image: {source: filter/image, policy: block, queue_size: 8}}
    params: {out_dir: $(arg out_dir)}
'''

RECORDED = {"camera": "pattern_source", "filter": "invert.py:Invert", "summary": "summary_sink",
            "bag_recorder": "bag_recorder"}
TOPICS = {"camera/image": "sensor/Image", "filter/image": "sensor/Image"}


def _graph_dir(tmp_path: Path) -> Path:
    folder = tmp_path / "graphs"
    folder.mkdir(exist_ok=True)
    (folder / "invert.py").write_text(USER_NODE)
    (folder / "swap.yaml").write_text(GRAPH)
    return folder


def _cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(Path(__file__).parents[2]),
                                                       os.environ.get("PYTHONPATH", "")]))
    return subprocess.run([sys.executable, "-m", "probeless.cli", *args], cwd=cwd, capture_output=True,
                          text=True, timeout=120, stdin=subprocess.DEVNULL, env=env)


# --- the plan, without processes -----------------------------------------------------------------

def test_a_swapped_node_and_what_it_feeds_run_live(tmp_path):
    graph = load_checked(str(_graph_dir(tmp_path) / "swap.yaml"), {})
    notes: list[str] = []
    replaced = add_player(graph, "rec.mcap", TOPICS, recorded_nodes=RECORDED, notes=notes)
    assert replaced == ["camera"]
    assert "filter: recorded as invert.py:Invert, graph has image_transform: running image_transform live" in notes
    assert "from the recording: camera (pattern_source)" in notes
    assert graph.nodes["filter"].inputs["image"].source == "bag_player/camera/image"
    assert "filter" in graph.nodes and "camera" not in graph.nodes


def test_same_type_is_replaced_and_keep_overrides(tmp_path):
    path = str(_graph_dir(tmp_path) / "swap.yaml")
    same = dict(RECORDED, filter="image_transform")
    graph = load_checked(path, {})
    assert sorted(add_player(graph, "rec.mcap", TOPICS, recorded_nodes=same)) == ["camera", "filter"]
    graph, notes = load_checked(path, {}), []
    assert add_player(graph, "rec.mcap", TOPICS, recorded_nodes=same, keep=["filter"], notes=notes) == ["camera"]
    assert "live: filter (--keep), summary (fed by filter)" in notes
    # an explicit --replace wins over the swap, and says so
    graph, notes = load_checked(path, {}), []
    assert add_player(graph, "rec.mcap", TOPICS, recorded_nodes=RECORDED, replace=["camera", "filter"],
                      notes=notes) == ["camera", "filter"]
    assert any("replaced by the recording (--replace names it)" in n for n in notes)


def test_changed_params_count_as_a_swap(tmp_path):
    graph, notes = load_checked(str(_graph_dir(tmp_path) / "swap.yaml"), {"out_dir": "elsewhere"}), []
    same = dict(RECORDED, filter="image_transform")
    recorded_params = {"camera": dict(graph.nodes["camera"].params), "filter": {"operation": "edges"},
                       "summary": {"out_dir": "out/summary"}}
    assert add_player(graph, "rec.mcap", TOPICS, recorded_nodes=same, recorded_params=recorded_params,
                      notes=notes) == ["camera"]
    assert "filter: recorded with operation='edges', graph has operation=None: running image_transform live" in notes
    assert not any(n.startswith("summary:") for n in notes)  # a sink is live anyway: its out_dir is no news


def test_keep_and_replace_errors_name_the_node(tmp_path):
    path = str(_graph_dir(tmp_path) / "swap.yaml")
    with pytest.raises(GraphError, match="--keep: no node 'nope'"):
        add_player(load_checked(path, {}), "rec.mcap", TOPICS, keep=["nope"])
    with pytest.raises(GraphError, match="both --replace and --keep"):
        add_player(load_checked(path, {}), "rec.mcap", TOPICS, keep=["filter"], replace=["filter"])


# --- real processes ------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """A recording of the graph with the user's Invert node as ``filter`` (made from another folder)."""
    tmp = tmp_path_factory.mktemp("swap")
    folder = _graph_dir(tmp)
    run = _cli("launch", str(folder / "swap.yaml"), "filter:=invert.py:Invert", f"out_dir:={tmp}/rec_out",
               "--record", str(tmp / "rec.mcap"), cwd=tmp)
    assert run.returncode == 0, run.stderr
    with BagReader(tmp / "rec.mcap") as reader:
        frames = {t: [reader.decode(m).data for m in reader.messages(t)] for t in ("camera/image", "filter/image")}
    assert len(frames["camera/image"]) == 4
    return tmp, folder, frames


def _last_frame(out_dir: Path) -> np.ndarray:
    return cv2.cvtColor(cv2.imread(str(out_dir / "last_frame.png")), cv2.COLOR_BGR2RGB)


@pytest.mark.graph
def test_replay_without_the_swap_runs_the_graphs_node_live(recording):
    tmp, folder, frames = recording
    run = _cli("launch", str(folder / "swap.yaml"), f"out_dir:={tmp}/live", "--replay", str(tmp / "rec.mcap"),
               cwd=tmp)
    assert run.returncode == 0, run.stderr
    assert "filter: recorded as invert.py:Invert, graph has image_transform: running image_transform live" \
        in run.stderr
    assert "from the recording: camera (pattern_source)" in run.stderr
    # the summary saw image_transform's Gaussian blur of the recorded camera frames, not the recorded inversion
    expected = cv2.GaussianBlur(frames["camera/image"][-1], (5, 5), 0)
    np.testing.assert_array_equal(_last_frame(tmp / "live"), expected)


@pytest.mark.graph
def test_replay_of_the_same_user_node_comes_from_the_recording(recording):
    tmp, folder, frames = recording
    run = _cli("launch", str(folder / "swap.yaml"), "filter:=invert.py:Invert", f"out_dir:={tmp}/played",
               "--replay", str(tmp / "rec.mcap"), cwd=tmp)
    assert run.returncode == 0, run.stderr
    assert "from the recording: camera (pattern_source), filter (invert.py:Invert)" in run.stderr
    assert "running" not in run.stderr.split("live:")[0]  # no swap reported
    np.testing.assert_array_equal(_last_frame(tmp / "played"), frames["filter/image"][-1])
    np.testing.assert_array_equal(frames["filter/image"][-1], cv2.bitwise_not(frames["camera/image"][-1]))
