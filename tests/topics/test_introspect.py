"""``probeless node list|info``, ``param get|set``, ``topic pub``, ``external:`` inputs and ``bag record`` against
real graphs: a 32x24 pattern source at 20 Hz feeding an OpenCV transform."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
from test_topic_tools import Launched, launch, run_base, stop, wait_started  # noqa: F401 (run_base: fixture)

from probeless.bag.reader import BagReader
from probeless.cli import main
from probeless.errors import ProbelessError
from probeless.topics import TopicReader
from probeless.topics.nodes import node_info, node_infos, param_get, param_set
from probeless.topics.pub import publish

PIPELINE = """
nodes:
  - id: src
    node: pattern_source
    inputs: {tick: timer/hz/20}
    params: {width: 32, height: 24}
  - id: fx
    node: image_transform
    inputs: {image: src/image}
    params: {operation: blur}
"""


def _pairs(g: Launched, n: int, timeout: float = 20.0, src: str = "src/image", out: str = "fx/image",
           out_graph: Launched | None = None) -> list[tuple[np.ndarray, np.ndarray]]:
    """``n`` (input, output) image pairs of the transform, matched by stamp."""
    og = out_graph or g
    ins, outs, pairs = {}, {}, []
    topics = [(src, g.graph.plan["nodes"][src.split("/")[0]]["endpoint"]),
              (out, og.graph.plan["nodes"][out.split("/")[0]]["endpoint"])]
    with TopicReader(topics, queue_size=200) as reader:
        deadline = time.monotonic() + timeout
        while len(pairs) < n and time.monotonic() < deadline:
            for topic, _, msg in reader.take(0.1):
                (ins if topic == src else outs)[msg.header.stamp_ns] = msg.data
            for stamp in sorted(set(ins) & set(outs)):
                pairs.append((ins.pop(stamp), outs.pop(stamp)))
    assert len(pairs) >= n, f"only {len(pairs)} matched pairs"
    return pairs


def _infos_with_rates(g: Launched, timeout: float = 20.0) -> dict:
    """``node_infos`` once the source's output reports a rate (from its second diagnostics period on, ~1 s)."""
    deadline = time.monotonic() + timeout
    while True:
        infos = node_infos(g.graph)
        if "src" in infos and infos["src"]["outputs"][0]["rate_hz"] is not None:
            return infos
        assert time.monotonic() < deadline, f"no rates after {timeout} s: {infos}"
        time.sleep(0.1)


def _parent_pid(pid: int) -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("PPid:"):
            return int(line.split()[1])
    raise AssertionError(pid)


@pytest.mark.graph
@pytest.mark.slow
def test_node_info_and_param_set_change_a_running_node(tmp_path, capsys):
    g = launch(tmp_path, PIPELINE)
    try:
        wait_started(g)
        infos = _infos_with_rates(g)
        assert set(infos) == {"src", "fx"}
        for node_id, info in infos.items():
            assert info["state"] == "running"
            assert _parent_pid(info["pid"]) == g.proc.pid  # a real node process of this launcher
        src_rate = infos["src"]["outputs"][0]["rate_hz"]
        assert 5 < src_rate < 25, src_rate  # timer/hz/20, loaded machine
        fx = infos["fx"]
        assert fx["inputs"][0]["topic"] == "src/image" and fx["inputs"][0]["queue_size"] == 10
        assert fx["params"] == {"operation": "blur", "ksize": 5} and set(fx["dynamic"]) == {"operation", "ksize"}
        assert main(["node", "list"]) == 0
        listed = capsys.readouterr().out
        assert str(infos["src"]["pid"]) in listed and "image_transform" in listed
        assert main(["node", "info", "fx"]) == 0
        assert "operation: 'blur'  (dynamic)" in capsys.readouterr().out

        # before: the output is OpenCV's 5x5 Gaussian blur of the input
        for rgb, out in _pairs(g, 3):
            assert np.array_equal(out, cv2.GaussianBlur(rgb, (5, 5), 0))
        # set at run time, applied between callbacks: from then on each output is the inverted input
        assert param_set(g.graph, "fx", "operation", "invert") == "invert"
        assert param_get(g.graph, "fx", "operation")["params"] == {"operation": "invert"}
        for rgb, out in _pairs(g, 3):
            assert np.array_equal(out, 255 - rgb)
        assert main(["param", "set", "fx", "ksize", "9"]) == 0 and "fx: ksize = 9" in capsys.readouterr().out

        # validated like `probeless check`, naming node and key; the node keeps its value
        with pytest.raises(ProbelessError, match=r"node 'fx': key 'operation': 'bogus' is not one of"):
            param_set(g.graph, "fx", "operation", "bogus")
        with pytest.raises(ProbelessError, match=r"key 'ksize': ksize must be odd, got 4"):
            param_set(g.graph, "fx", "ksize", 4)
        with pytest.raises(ProbelessError, match=r"key 'width': not a dynamic parameter"):
            param_set(g.graph, "src", "width", 64)
        assert main(["param", "set", "fx", "opration", "gray"]) == 2
        assert "did you mean 'operation'?" in capsys.readouterr().err
        assert param_get(g.graph, "fx")["params"] == {"operation": "invert", "ksize": 9}
    finally:
        stop(g)


@pytest.mark.graph
@pytest.mark.slow
def test_topic_pub_reaches_the_subscribers_of_a_topic(tmp_path):
    g = launch(tmp_path, PIPELINE.replace("operation: blur", "operation: invert"))
    try:
        wait_started(g)
        pixel = [[[10, 200, 30]]]
        out_endpoint = g.graph.plan["nodes"]["fx"]["endpoint"]
        with TopicReader([("fx/image", out_endpoint)], queue_size=500) as reader:
            time.sleep(0.5)
            sent = publish(g.graph, "src/image", "sensor/Image", {"data": pixel, "encoding": "rgb8"},
                           rate_hz=10, count=2)
            assert sent == 2
            assert main(["topic", "pub", "src/image", "sensor/Image", "{data: [[[10, 200, 30]]], encoding: rgb8}"]) == 0
            got, deadline = [], time.monotonic() + 10
            while len(got) < 3 and time.monotonic() < deadline:
                got += [m.data for _, _, m in reader.take(0.1) if m.data.shape == (1, 1, 3)]
        # the transform received the tool's 1x1 images next to the 32x24 ones and inverted them
        assert len(got) == 3 and all(np.array_equal(d, 255 - np.array(pixel, np.uint8)) for d in got)
        fx_in = node_info(g.graph, "fx")["inputs"][0]
        assert fx_in["invalid"] == 0 and fx_in["seq_gaps"] == 0  # the tool's own seq is not a gap
        with pytest.raises(ProbelessError, match="carries sensor/Image, not core/Tick"):
            publish(g.graph, "src/image", "core/Tick", {"period_ns": 1})
        with pytest.raises(ProbelessError, match=r"Image: unknown field\(s\) dat"):
            publish(g.graph, "src/image", "sensor/Image", {"dat": 1})
    finally:
        stop(g)


@pytest.mark.graph
@pytest.mark.slow
def test_external_input_reads_a_topic_of_another_running_graph(tmp_path, capsys):
    (tmp_path / "up").mkdir()
    (tmp_path / "down").mkdir()
    up = launch(tmp_path / "up", PIPELINE)
    try:
        wait_started(up)
        # the second graph names the first by its graph file, relative to its own file
        down_text = """
nodes:
  - id: fx2
    node: image_transform
    inputs: {image: {source: src/image, external: ../up/graph.yaml, policy: latest}}
    params: {operation: invert}
"""
        down = launch(tmp_path / "down", down_text)
        try:
            wait_started(down, node="fx2")
            for rgb, out in _pairs(up, 3, out="fx2/image", out_graph=down):
                assert np.array_equal(out, 255 - rgb)
            assert node_info(down.graph, "fx2")["inputs"][0]["topic"] == "src/image"
        finally:
            down.proc.send_signal(signal.SIGINT)
            assert down.proc.wait(timeout=60) == 0, down.output()
        # a typo in the topic gets a did-you-mean; a graph that is not running is an error at check time
        bad = tmp_path / "down" / "bad.yaml"
        bad.write_text(down_text.replace("src/image", "src/imgae"))
        assert main(["check", str(bad)]) == 2
        assert "publishes no topic 'src/imgae' (did you mean 'src/image'?" in capsys.readouterr().err
    finally:
        stop(up)
    assert main(["check", str(tmp_path / "down" / "graph.yaml")]) == 2
    assert "external graph '../up/graph.yaml' is not running" in capsys.readouterr().err


@pytest.mark.graph
@pytest.mark.slow
def test_background_bag_record_with_inherited_stdin_records_and_says_how_much(tmp_path):
    g = launch(tmp_path, PIPELINE)
    try:
        wait_started(g)
        out = tmp_path / "rec.mcap"
        # as `probeless bag record ... &` from a shell: stdin inherited and left open (a pipe nobody writes)
        cmd = [sys.executable, "-m", "probeless.cli", "bag", "record", "-o", str(out), "--duration", "2",
               "src/image", "--graph", g.graph.run_id]
        proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                text=True)
        text, _ = proc.communicate(timeout=120)
    finally:
        stop(g)
    assert proc.returncode == 0, text
    with BagReader(out) as reader:
        count = sum(t.count for t in reader.topics().values())
    assert count >= 10, text  # 2 s of a 20 Hz topic, counted from when recording started
    assert f"{count} messages written to {out}" in text
