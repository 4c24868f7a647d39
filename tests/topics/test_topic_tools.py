"""``probeless topic list | echo | hz | info`` against graphs launched in a subprocess."""

from __future__ import annotations

import io
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from locations import TESTS

from probeless.errors import ProbelessError
from probeless.messages import Header, Image, InputCounters, NodeStatus
from probeless.topics import (
    RateStats,
    RunningGraph,
    TopicReader,
    format_message,
    graph_topics,
    hz,
    running_graphs,
    select_graph,
    summarize_array,
    topic_info,
    topic_main,
    wait_for_start,
)


@pytest.fixture(autouse=True)
def run_base(monkeypatch):
    """A private runs directory for the launcher and the tools (short: ipc paths are limited to ~107 bytes)."""
    base = Path(tempfile.mkdtemp(prefix="pltt-", dir="/tmp"))
    monkeypatch.setenv("PROBELESS_RUN_DIR", str(base))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(TESTS), os.environ.get("PYTHONPATH", "")]))
    yield base
    shutil.rmtree(base, ignore_errors=True)


@dataclass
class Launched:
    proc: subprocess.Popen
    graph: RunningGraph
    log: Path

    def output(self) -> str:
        return self.log.read_text()


def launch(tmp_path: Path, text: str) -> Launched:
    """Start ``probeless launch`` in a subprocess; return once its graph.json is visible."""
    path = tmp_path / "graph.yaml"
    path.write_text(text)
    log = tmp_path / "launch.log"
    proc = subprocess.Popen([sys.executable, "-m", "probeless.cli", "launch", str(path)],
                            stdout=log.open("w"), stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        mine = [g for g in running_graphs() if g.launcher_pid == proc.pid]
        if mine:
            return Launched(proc, mine[0], log)
        if proc.poll() is not None:
            break
        time.sleep(0.02)
    proc.kill()
    proc.wait()
    pytest.fail(f"graph did not come up:\n{log.read_text()}")


def wait_started(g: Launched, node: str = "src", timeout: float = 30) -> None:
    """Wait until ``node`` publishes its first NodeStatus (only sent once the graph has started)."""
    endpoint = g.graph.plan["nodes"][node]["endpoint"]
    with TopicReader([(f"{node}/diagnostics", endpoint)], policy="latest") as r:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if r.take(0.1):
                return
    pytest.fail(f"graph did not start:\n{g.output()}")


def stop(g: Launched) -> str:
    """SIGINT the launcher; it must exit 0. (Waits for the start first: a node signalled while it is
    still importing dies of the launcher's SIGTERM before installing its handler, a failed stop.)"""
    if g.proc.poll() is None:
        wait_started(g)
        g.proc.send_signal(signal.SIGINT)
    try:
        g.proc.wait(timeout=30)
    except subprocess.TimeoutExpired:
        g.proc.kill()
        g.proc.wait()
        pytest.fail(f"launcher did not stop on SIGINT:\n{g.output()}")
    out = g.output()
    assert g.proc.returncode == 0, out
    return out


class Lines(threading.Thread):
    """The lines a process writes to one of its pipes, read as they come."""

    def __init__(self, pipe):
        super().__init__(daemon=True)
        self.pipe, self.lines = pipe, []
        self.start()

    def run(self) -> None:
        for line in self.pipe:
            self.lines.append(line)

    def wait_for(self, pred, what: str, timeout: float = 30.0) -> None:
        """Until a line satisfies ``pred``; fails the test after ``timeout``."""
        deadline, seen = time.monotonic() + timeout, 0
        while time.monotonic() < deadline:
            new, seen = self.lines[seen:], seen + len(self.lines[seen:])
            if any(pred(line) for line in new):
                return
            time.sleep(0.02)
        pytest.fail(f"no {what} within {timeout} s:\n{self.text}")

    @property
    def text(self) -> str:
        return "".join(self.lines)


def tool_cli(*args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "probeless.topic_tools", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def ticker_graph(tmp_path: Path, hz_: int = 50, count: int = 0, extra: str = "") -> str:
    return f"""
nodes:
  - id: src
    node: nodes_for_tests:Ticker
    inputs: {{tick: timer/hz/{hz_}}}
    params: {{count: {count}}}
  - id: sink
    node: nodes_for_tests:Recorder
    inputs: {{image: {{source: src/image, policy: block, queue_size: 2}}}}
    params: {{out: {tmp_path}/sink.json}}
{extra}"""


MESSAGE_HEAD = re.compile(r"^--- src/image sensor/Image seq (\d+)$", re.M)
DATA_LINE = re.compile(r"^data: ndarray uint8 \(4, 4, 1\) min (\d+) max (\d+)$", re.M)


# -- formatting (no graph) -----------------------------------------------------------------------------
def test_array_summaries():
    assert summarize_array(np.full((480, 640, 3), 7, np.uint8)) == "ndarray uint8 (480, 640, 3) min 7 max 7"
    assert summarize_array(np.array([[1.0, 3.0]], np.float32)) == "ndarray float32 (1, 2) min 1 max 3 mean 2"
    assert summarize_array(np.zeros((0, 3), np.float32)) == "ndarray float32 (0, 3) empty"
    assert summarize_array(np.array([1.0, np.nan, np.inf], np.float64)) == \
        "ndarray float64 (3,) min 1 max 1 mean 1 nan/inf 2"
    assert summarize_array(np.array([np.nan], np.float16)) == "ndarray float16 (1,) no finite values (1 nan/inf)"
    assert summarize_array(np.array([True, False, True])) == "ndarray bool (3,) true 2 of 3"
    assert summarize_array(np.full((2, 2), 5, np.uint16), stats=False) == "ndarray uint16 (2, 2)"


def test_message_format_is_yaml_like():
    img = Image(Header(123, "cam", 4), np.full((2, 3, 1), 9, np.uint8), "mono8")
    assert format_message(img) == ["header:", "  stamp_ns: 123", "  frame_id: cam", "  seq: 4",
                                   "data: ndarray uint8 (2, 3, 1) min 9 max 9", "encoding: mono8"]
    status = NodeStatus(Header(1, ""), "n", "running", 1.5,
                        inputs=(InputCounters("in", "a/b", "block", 2, 0, 10, 1, 2, 0),), published=("a/x=3",))
    lines = format_message(status)
    assert '  frame_id: ""' in lines and "timings: []" in lines and "published: [a/x=3]" in lines
    i = lines.index("inputs:")
    assert lines[i + 1:i + 4] == ["  - name: in", "    topic: a/b", "    policy: block"]


def test_rate_stats_ignore_tool_drops():
    s = RateStats(window=100)
    for seq in range(0, 100, 3):  # the tool kept every third message of a 100 Hz stream
        s.add(seq * 10_000_000, seq * 10_000_000, seq)
    rep = s.report()
    assert rep["rate_hz"] == pytest.approx(100.0)
    assert rep["min_ms"] is None   # no consecutive pair: no period statistics


# -- against running graphs ---------------------------------------------------------------------------------
@pytest.mark.graph
def test_no_running_graph_is_a_clear_error(run_base, capsys, tmp_path):
    assert topic_main(["list"]) == 2
    assert "no running probeless graph found" in capsys.readouterr().err
    stale = run_base / "000000-stale"   # a graph whose launcher is gone
    stale.mkdir()
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    (stale / "graph.json").write_text(json.dumps({"file": "x.yaml", "launcher_pid": dead.pid,
                                                  "started_ns": 1, "nodes": {}}))
    assert topic_main(["echo", "src/image"]) == 2
    assert "no running probeless graph found" in capsys.readouterr().err
    assert topic_main(["info", "src/image", "--graph-dir", str(stale)]) == 2
    assert "is not running" in capsys.readouterr().err
    proc = tool_cli("hz", "src/image")
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 2 and "no running probeless graph found" in err


@pytest.mark.graph
@pytest.mark.slow
def test_list_shows_topics_types_and_subscribers(tmp_path, capsys):
    g = launch(tmp_path, ticker_graph(tmp_path))
    try:
        assert topic_main(["list"]) == 0
        out = capsys.readouterr().out
        assert re.search(r"^src/image\s+sensor/Image\s+src\s+1$", out, re.M), out
        assert re.search(r"^src/diagnostics\s+diagnostics/NodeStatus\s+src\s+0$", out, re.M), out
        assert re.search(r"^sink/diagnostics\s+diagnostics/NodeStatus\s+sink\s+0$", out, re.M), out
        assert topic_main(["list", "-v"]) == 0
        assert "-> sink.image  policy block  queue_size 2" in capsys.readouterr().out
        topics = graph_topics(g.graph)
        assert topics["src/image"].subscribers[0].node == "sink"
        assert topics["src/image"].endpoint == g.graph.plan["nodes"]["src"]["endpoint"]
    finally:
        stop(g)


@pytest.mark.graph
@pytest.mark.slow
def test_several_graphs_the_tools_ask_which_never_guess(tmp_path, capsys):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    g1 = launch(tmp_path / "a", ticker_graph(tmp_path / "a"))
    try:
        time.sleep(0.05)
        g2 = launch(tmp_path / "b", ticker_graph(tmp_path / "b"))
        try:
            deadline = time.monotonic() + 10
            while len(running_graphs()) < 2 and time.monotonic() < deadline:
                time.sleep(0.02)
            err = io.StringIO()
            with pytest.raises(ProbelessError, match="2 graphs are running; choose one with --graph RUN_ID"):
                select_graph(err=err)
            listed = err.getvalue()
            assert g1.graph.run_id in listed and g2.graph.run_id in listed
            # a run id, a run directory, or the graph file it was launched from names exactly one
            assert select_graph(g1.graph.run_id).run_dir == g1.graph.run_dir
            assert select_graph(g2.graph.run_dir).run_dir == g2.graph.run_dir
            assert select_graph(str(tmp_path / "a" / "graph.yaml")).run_dir == g1.graph.run_dir
            # the CLI: a one-line error saying to pass --graph, exit code non-zero; `runs` lists both
            assert topic_main(["list"]) == 2
            assert capsys.readouterr().err.strip().splitlines()[-1] == \
                "error: 2 graphs are running; choose one with --graph RUN_ID"
            assert topic_main(["list", "--graph", g1.graph.run_id]) == 0
            assert "src/image" in capsys.readouterr().out
            from probeless.cli import main

            assert main(["runs"]) == 0
            out = capsys.readouterr().out
            assert g1.graph.run_id in out and g2.graph.run_id in out
        finally:
            stop(g2)
    finally:
        stop(g1)


@pytest.mark.graph
@pytest.mark.slow
def test_echo_prints_n_messages_with_array_summaries(tmp_path, capsys):
    g = launch(tmp_path, ticker_graph(tmp_path, hz_=50))
    try:
        assert topic_main(["echo", "src/image", "-n", "3"]) == 0
        out = capsys.readouterr().out
        seqs = [int(s) for s in MESSAGE_HEAD.findall(out)]
        data = DATA_LINE.findall(out)
        assert len(seqs) == 3 and len(data) == 3, out
        assert seqs == list(range(seqs[0], seqs[0] + 3))           # consecutive
        assert [(int(lo), int(hi)) for lo, hi in data] == [(s % 256, s % 256) for s in seqs]  # pixel = frame index
        assert out.count("encoding: mono8") == 3 and out.count("  frame_id: t") == 3
        assert topic_main(["echo", "src/image", "--once", "--no-arrays"]) == 0
        out = capsys.readouterr().out
        assert len(MESSAGE_HEAD.findall(out)) == 1 and "data: ndarray uint8 (4, 4, 1)\n" in out
        assert topic_main(["echo", "src/imag", "-n", "1"]) == 2
        assert "did you mean src/image" in capsys.readouterr().err
    finally:
        stop(g)


@pytest.mark.graph
@pytest.mark.slow
def test_echo_exits_by_itself_at_end_of_stream(tmp_path):
    g = launch(tmp_path, ticker_graph(tmp_path, hz_=10, count=20))
    tool = tool_cli("echo", "src/image")
    try:
        out, err = tool.communicate(timeout=60)
    finally:
        if tool.poll() is None:
            tool.kill()
    assert tool.returncode == 0, err
    seqs = [int(s) for s in MESSAGE_HEAD.findall(out)]
    assert seqs and seqs[-1] == 19 and seqs == list(range(seqs[0], 20)), out
    assert f"src/image: end of stream after {len(seqs)} message(s)" in err
    g.proc.wait(timeout=30)                      # the graph ends by itself; the tool did not hold it up
    assert g.proc.returncode == 0 and "graph finished" in g.output()
    assert json.loads((tmp_path / "sink.json").read_text())["seqs"]["image"] == list(range(20))


@pytest.mark.graph
@pytest.mark.slow
@pytest.mark.exclusive  # rates: alone under xdist (tests/conftest.py)
def test_hz_reports_the_rate_of_a_50_hz_source(tmp_path):
    g = launch(tmp_path, ticker_graph(tmp_path, hz_=50))
    try:
        wait_started(g)
        out = io.StringIO()
        rep = hz(g.graph, "src/image", duration=3.0, out=out)
        text = out.getvalue()
        assert rep["reason"] == "duration"
        assert rep["rate_hz"] == pytest.approx(50, rel=0.15), text
        assert rep["receive_hz"] == pytest.approx(50, rel=0.15), text
        assert rep["count"] >= 100 and rep["seq_gaps"] == 0 and rep["tool_dropped"] == 0
        assert 18 <= rep["mean_ms"] <= 23 and rep["min_ms"] <= rep["mean_ms"] <= rep["max_ms"]
        periodic = [line for line in text.splitlines() if line.startswith("src/image: rate ")]
        assert len(periodic) >= 2, text                # printed once a second
        assert "tool dropped 0" in periodic[-1] and "seq gaps 0" in periodic[-1]
    finally:
        stop(g)


@pytest.mark.graph
@pytest.mark.slow
@pytest.mark.exclusive  # rates: alone under xdist (tests/conftest.py)
def test_info_shows_subscribers_and_their_drop_counters(tmp_path, capsys):
    g = launch(tmp_path, ticker_graph(tmp_path, hz_=200, extra=f"""
  - id: slow
    node: nodes_for_tests:Recorder
    inputs: {{image: {{source: src/image, policy: drop_oldest, queue_size: 3}}}}
    params: {{out: {tmp_path}/slow.json, sleep_ms: 15}}
"""))
    try:
        wait_started(g)
        time.sleep(1.5)
        info = topic_info(g.graph, "src/image")
        assert info["type"] == "sensor/Image"
        assert info["publisher"]["node"] == "src" and info["publisher"]["node_type"] == "nodes_for_tests:Ticker"
        assert info["publisher"]["published"] > 0
        subs = {s["node"]: s for s in info["subscribers"]}
        assert subs["sink"]["policy"] == "block" and subs["sink"]["queue_size"] == 2
        assert subs["sink"]["counters"]["received"] > 0 and subs["sink"]["counters"]["dropped"] == 0
        assert subs["slow"]["counters"]["dropped"] > 0       # a 15 ms consumer of a 200 Hz stream drops
        assert topic_main(["info", "src/image"]) == 0
        out = capsys.readouterr().out
        assert "type: sensor/Image" in out and "publisher: src (nodes_for_tests:Ticker) at ipc://" in out
        assert re.search(r"^  sink\.image  policy block  queue_size 2  received \d+  dropped 0  seq_gaps 0", out, re.M)
        m = re.search(r"^  slow\.image  policy drop_oldest  queue_size 3  received \d+  dropped (\d+)", out, re.M)
        assert m and int(m.group(1)) > 0, out
    finally:
        stop(g)


@pytest.mark.graph
@pytest.mark.slow
@pytest.mark.exclusive  # rates: alone under xdist (tests/conftest.py)
def test_paused_tool_does_not_slow_the_graph(tmp_path):
    """The tool stops reading for 1 s while a ``block`` subscriber must still get every message in time."""
    count = 900   # 3 s at 300 Hz; a 1 s stall of the reader's socket would hold the publisher after ~200
    g = launch(tmp_path, ticker_graph(tmp_path, hz_=300, count=count))
    endpoint = g.graph.plan["nodes"]["src"]["endpoint"]
    got = []
    assert wait_for_start(g.graph)   # as the tools do: never stand in for a subscriber at the barrier
    with TopicReader([("src/image", endpoint)], queue_size=5) as reader:
        deadline = time.monotonic() + 30
        while not got and time.monotonic() < deadline:
            got += reader.take(0.1)
        assert got, g.output()
        time.sleep(1.0)                                   # paused: reads nothing
        assert reader.counters("src/image")["dropped"] > 200   # yet its receiver kept draining the socket
        while not reader.ended and time.monotonic() < deadline:
            got += reader.take(0.1)
        assert reader.ended
    msgs = [m for _, _, m in got]
    assert msgs[-1].header.seq == count - 1
    span_s = (msgs[-1].header.stamp_ns - msgs[0].header.stamp_ns) / 1e9
    rate = (msgs[-1].header.seq - msgs[0].header.seq) / span_s
    assert rate > 255, f"publisher slowed down to {rate:.0f} Hz"
    g.proc.wait(timeout=30)
    assert g.proc.returncode == 0, g.output()
    assert json.loads((tmp_path / "sink.json").read_text())["seqs"]["image"] == list(range(count))


@pytest.mark.graph
@pytest.mark.slow
@pytest.mark.exclusive  # rates: alone under xdist (tests/conftest.py)
def test_ctrl_z_unsubscribes_so_a_stopped_echo_does_not_stall_the_graph(tmp_path):
    g = launch(tmp_path, ticker_graph(tmp_path, hz_=200))
    tool = None
    try:
        wait_started(g)
        tool = tool_cli("echo", "src/image", "--no-arrays")
        out_lines, err_lines = Lines(tool.stdout), Lines(tool.stderr)
        out_lines.wait_for(MESSAGE_HEAD.match, "message echoed")  # subscribed, its Ctrl-Z handler in place
        tool.send_signal(signal.SIGTSTP)               # Ctrl-Z: the tool unsubscribes, then stops
        err_lines.wait_for(lambda line: "suspended: unsubscribed" in line, "suspension")
        before = topic_info(g.graph, "src/image")["subscribers"][0]["counters"]["received"]
        time.sleep(2.0)                                # 400 messages: far more than socket buffers hold
        after = topic_info(g.graph, "src/image")["subscribers"][0]["counters"]["received"]
        assert after - before > 300, (before, after)
        tool.send_signal(signal.SIGCONT)
        out_lines.wait_for(lambda line: (m := MESSAGE_HEAD.match(line)) is not None and int(m.group(1)) > after,
                           f"message after seq {after} echoed")
        tool.send_signal(signal.SIGINT)
        tool.wait(timeout=30)
        out_lines.join(10)
        err_lines.join(10)
        out, err = out_lines.text, err_lines.text
        assert tool.returncode == 0, err
        assert "suspended: unsubscribed" in err and "resumed: subscribed again" in err
        seqs = [int(s) for s in MESSAGE_HEAD.findall(out)]
        assert seqs and seqs[-1] > after               # it printed again after the resume
    finally:
        if tool is not None and tool.poll() is None:
            tool.kill()
        stop(g)
