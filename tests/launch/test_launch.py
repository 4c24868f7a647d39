"""Launcher and runtime lifecycle: readiness barrier, queue policies, crashes, restarts, signals, split hosts."""

from __future__ import annotations

import io
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
from locations import TESTS

from probeless.launch.launcher import Launcher, load_checked

ROOT = TESTS.parent


@pytest.fixture(autouse=True)
def _node_path(monkeypatch):
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(TESTS), os.environ.get("PYTHONPATH", "")]))


def write_graph(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "graph.yaml"
    path.write_text(text)
    return path


def launch(path: Path, **kw) -> tuple[int, str]:
    out = io.StringIO()
    code = Launcher(load_checked(str(path), {}), out=out, **kw).run()
    return code, out.getvalue()


def cli(*args: str, **kw) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "probeless.cli", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, **kw)


@pytest.mark.graph
def test_first_message_is_not_lost_and_streams_end(tmp_path):
    g = write_graph(tmp_path, f"""
nodes:
  - id: src
    node: nodes_for_tests:Ticker
    inputs: {{tick: timer/hz/200}}
    params: {{count: 25}}
  - id: sink
    node: nodes_for_tests:Recorder
    inputs: {{image: {{source: src/image, policy: block, queue_size: 2}}}}
    params: {{out: {tmp_path}/sink.json}}
""")
    code, log = launch(g)
    assert code == 0, log
    rec = json.loads((tmp_path / "sink.json").read_text())
    assert rec["seqs"]["image"] == list(range(25))   # seq 0 arrives: the barrier beat the slow joiner
    assert rec["closed"] == ["image"]                # end of stream reached the sink, which then stopped
    assert "graph finished" in log


@pytest.mark.graph
def test_feedback_input_lets_a_loop_end(tmp_path):
    # a -> b -> a: without `feedback: true` on a's input from b, neither node would ever see its inputs end
    g = write_graph(tmp_path, f"""
nodes:
  - id: src
    node: nodes_for_tests:Ticker
    inputs: {{tick: timer/hz/200}}
    params: {{count: 20}}
  - id: a
    node: nodes_for_tests:LoopRelay
    inputs:
      image: {{source: src/image, policy: block, queue_size: 4}}
      back: {{source: b/out, policy: drop_oldest, queue_size: 4, feedback: true}}
    params: {{out: {tmp_path}/a.json}}
  - id: b
    node: nodes_for_tests:LoopRelay
    inputs: {{image: {{source: a/out, policy: block, queue_size: 4}}}}
""")
    t0 = time.monotonic()
    code, log = launch(g)
    assert code == 0, log
    assert time.monotonic() - t0 < 30
    counts = json.loads((tmp_path / "a.json").read_text())
    assert counts["image"] == 20 and 0 < counts["back"] <= 20
    assert "graph finished" in log


def test_feedback_must_be_a_bool(tmp_path):
    g = write_graph(tmp_path, """
nodes:
  - id: src
    node: nodes_for_tests:Ticker
    inputs: {tick: {source: timer/hz/10, feedback: maybe}}
""")
    with pytest.raises(Exception, match="feedback must be true or false"):
        load_checked(str(g), {})


@pytest.mark.graph
@pytest.mark.slow
@pytest.mark.parametrize("policy, queue", [("latest", 1), ("drop_oldest", 3), ("block", 3)])
def test_queue_policies_count_every_drop(tmp_path, policy, queue):
    count = 60
    g = write_graph(tmp_path, f"""
nodes:
  - id: src
    node: nodes_for_tests:Ticker
    inputs: {{tick: timer/hz/400}}
    params: {{count: {count}}}
  - id: slow
    node: nodes_for_tests:Recorder
    inputs: {{image: {{source: src/image, policy: {policy}, queue_size: {queue}}}}}
    params: {{out: {tmp_path}/slow.json, sleep_ms: 15}}
  - id: monitor
    node: nodes_for_tests:Recorder
    inputs: {{status: {{source: slow/diagnostics, policy: block}}}}
    params: {{out: {tmp_path}/monitor.json}}
""")
    code, log = launch(g)
    assert code == 0, log
    processed = json.loads((tmp_path / "slow.json").read_text())["seqs"]["image"]
    status = json.loads((tmp_path / "monitor.json").read_text())["status"]["image"]
    assert status["received"] == count and status["seq_gaps"] == 0
    assert len(processed) + status["dropped"] == count      # nothing vanishes uncounted
    assert processed == sorted(processed) and processed[-1] == count - 1  # the newest is always kept
    if policy == "block":
        assert status["dropped"] == 0 and processed == list(range(count))
    else:
        assert status["dropped"] > count // 3               # a 15 ms consumer of a 400 Hz stream drops


@pytest.mark.graph
def test_crash_is_reported_and_stops_graph(tmp_path):
    g = write_graph(tmp_path, f"""
nodes:
  - id: src
    node: nodes_for_tests:Ticker
    inputs: {{tick: timer/hz/100}}
    params: {{crash_at: 3}}
  - id: sink
    node: nodes_for_tests:Recorder
    inputs: {{image: src/image}}
    params: {{out: {tmp_path}/sink.json}}
""")
    code, log = launch(g)
    assert code == 1
    assert "ZeroDivisionError: crash requested by test" in log      # the traceback, prefixed
    assert "[src] Traceback (most recent call last):" in log         # an unexpected error keeps it
    assert "[src] " in log and "node src crashed (exit code 1)" in log
    assert json.loads((tmp_path / "sink.json").read_text())["seqs"]["image"] == [0, 1, 2]  # sink closed cleanly


@pytest.mark.graph
def test_our_error_at_setup_is_one_line_and_restart_policy_applies(tmp_path):
    g = write_graph(tmp_path, """
nodes:
  - id: rig
    node: nodes_for_tests:FailsAtSetup
    restart: on-failure
    max_restarts: 1
    restart_backoff_s: 0.05
""")
    code, log = launch(g)
    assert code == 1, log
    line = "[rig] ERROR rig: node 'rig': SceneError: nonexistent.yaml: scene file not found"
    assert log.count(line) == 2, log                                   # the first start and the one restart
    assert "Traceback" not in log and "  File " not in log, log
    assert "restarting rig (1/1)" in log and "node rig crashed (exit code 1)" in log


@pytest.mark.graph
def test_unexpected_error_at_setup_keeps_its_traceback(tmp_path):
    g = write_graph(tmp_path, """
nodes:
  - id: rig
    node: nodes_for_tests:FailsAtSetup
    params: {error: bug}
""")
    code, log = launch(g)
    assert code == 1, log
    assert "[rig] Traceback (most recent call last):" in log and "KeyError: 'a bug in setup'" in log, log
    assert "node rig crashed (exit code 1)" in log


@pytest.mark.graph
@pytest.mark.slow
def test_restart_on_failure_then_finish(tmp_path):
    g = write_graph(tmp_path, f"""
nodes:
  - id: src
    node: nodes_for_tests:Ticker
    inputs: {{tick: timer/hz/50}}
    params: {{count: 30}}
  - id: sink
    node: nodes_for_tests:Recorder
    restart: on-failure
    max_restarts: 2
    restart_backoff_s: 0.1
    inputs: {{image: {{source: src/image, policy: block, queue_size: 100}}}}
    params: {{out: {tmp_path}/sink.json, crash_once_marker: {tmp_path}/marker}}
""")
    code, log = launch(g)
    assert code == 0, log
    assert "node sink crashed (exit code 1); restart in 0.10 s" in log
    assert "restarting sink (1/2)" in log
    seqs = json.loads((tmp_path / "sink.json").read_text())["seqs"]["image"]
    assert seqs == sorted(seqs) and seqs[-1] == 29


@pytest.mark.graph
def test_restart_limit_exhausted_fails(tmp_path):
    g = write_graph(tmp_path, """
nodes:
  - id: src
    node: nodes_for_tests:Ticker
    restart: on-failure
    max_restarts: 1
    restart_backoff_s: 0.05
    inputs: {tick: timer/hz/100}
    params: {crash_at: 0}
""")
    code, log = launch(g)
    assert code == 1
    assert log.count("ZeroDivisionError: crash requested") == 2 and "restarting src (1/1)" in log


@pytest.mark.graph
@pytest.mark.slow
def test_sigint_stops_cleanly_without_orphans(tmp_path):
    g = write_graph(tmp_path, f"""
nodes:
  - id: src
    node: nodes_for_tests:Ticker
    inputs: {{tick: timer/hz/50}}
    params: {{pid_file: {tmp_path}/src.pid}}
  - id: sink
    node: nodes_for_tests:Recorder
    inputs: {{image: src/image}}
    params: {{out: {tmp_path}/sink.json, pid_file: {tmp_path}/sink.pid}}
""")
    proc = cli("launch", str(g))
    deadline = time.monotonic() + 30
    while not (tmp_path / "sink.pid").exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(0.5)
    proc.send_signal(signal.SIGINT)
    out, _ = proc.communicate(timeout=20)
    assert proc.returncode == 0, out
    assert "received SIGINT" in out and "graph finished" in out
    assert len(json.loads((tmp_path / "sink.json").read_text())["seqs"]["image"]) > 5  # close() ran
    for name in ("src", "sink"):
        pid = int((tmp_path / f"{name}.pid").read_text())
        with pytest.raises(ProcessLookupError):
            os.kill(pid, 0)


@pytest.mark.graph
@pytest.mark.slow
def test_duration_stops_graph(tmp_path):
    g = write_graph(tmp_path, f"""
nodes:
  - id: src
    node: nodes_for_tests:Ticker
    inputs: {{tick: timer/hz/20}}
  - id: sink
    node: nodes_for_tests:Recorder
    inputs: {{image: {{source: src/image, policy: block}}}}
    params: {{out: {tmp_path}/sink.json}}
""")
    t0 = time.monotonic()
    code, log = launch(g, duration=1.0)
    assert code == 0, log
    assert 1.0 <= time.monotonic() - t0 < 15
    # the second counts from the start (every node ready), not from the spawn: ~20 frames however slow the start
    assert 12 <= len(json.loads((tmp_path / "sink.json").read_text())["seqs"]["image"]) <= 30


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.graph
@pytest.mark.slow
def test_split_hosts_over_tcp_loopback(tmp_path):
    g = write_graph(tmp_path, f"""
hosts:
  camera_pc: {{address: 127.0.0.1, port_base: {_free_port()}}}
  gpu_pc: {{address: 127.0.0.1, port_base: {_free_port()}}}
nodes:
  - id: src
    node: nodes_for_tests:Ticker
    host: camera_pc
    inputs: {{tick: timer/hz/100}}
    params: {{count: 40}}
  - id: sink
    node: nodes_for_tests:Recorder
    host: gpu_pc
    inputs: {{image: {{source: src/image, policy: block}}}}
    params: {{out: {tmp_path}/sink.json}}
""")
    gpu = cli("launch", str(g), "--only", "gpu_pc")
    time.sleep(0.5)
    cam = cli("launch", str(g), "--only", "camera_pc")
    cam_out, _ = cam.communicate(timeout=60)
    gpu_out, _ = gpu.communicate(timeout=60)
    assert cam.returncode == 0 and gpu.returncode == 0, cam_out + gpu_out
    assert "[sink]" not in cam_out and "[src]" not in gpu_out     # each launcher ran only its host's node
    assert json.loads((tmp_path / "sink.json").read_text())["seqs"]["image"] == list(range(40))


@pytest.mark.graph
@pytest.mark.slow
def test_demo_graph_runs(tmp_path):
    code, log = launch_demo(tmp_path)
    assert code == 0, log
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["frames"] == 30 and summary["seq_gaps"] == 0
    assert 20 < summary["rate_hz"] < 40
    assert (tmp_path / "last_frame.png").stat().st_size > 0


def launch_demo(tmp_path):
    out = io.StringIO()
    graph = load_checked(str(ROOT / "launch/demo_runtime.yaml"), {"frames": 30, "out_dir": str(tmp_path)})
    return Launcher(graph, out=out).run(), out.getvalue()
