"""A stopped subscriber slows its publisher only when its input is ``block`` (real processes, SIGSTOP).

The experiment of issue 18: a 30 Hz camera feeds two sinks; one sink's process is stopped for 10 s.
With a lossy policy the other sink keeps >= 0.95x its rate and the stopped one reports its losses
(seq gaps) once it runs again; with ``block`` the publisher waits for it and it loses nothing.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from faults_common import free_ports, rate_hz
from locations import TESTS

FPS, BEFORE_S, STOP_S, AFTER_S = 30, 3.0, 10.0, 3.0
FRAMES = int(FPS * (BEFORE_S + STOP_S + AFTER_S + 1))


def _graph(tmp: Path, stopped_policy: str, tcp: bool) -> Path:
    queue = ", queue_size: 4" if stopped_policy != "latest" else ""
    hosts = f"hosts:\n  cam: {{address: 127.0.0.1, port_base: {free_ports(1)}}}\n" if tcp else ""
    text = f"""{hosts}nodes:
  - id: src
    node: pattern_source
{"    host: cam" if tcp else ""}
    inputs: {{tick: timer/hz/{FPS}}}
    params: {{width: 640, height: 480, count: {FRAMES}}}
  - id: running
    node: nodes_for_tests:ArrivalLog
    inputs: {{image: {{source: src/image, policy: latest}}}}
    params: {{out: {tmp}/running.json}}
  - id: stopped
    node: nodes_for_tests:ArrivalLog
    inputs: {{image: {{source: src/image, policy: {stopped_policy}{queue}}}}}
    params: {{out: {tmp}/stopped.json, pid_file: {tmp}/stopped.pid}}
  - id: watch
    node: nodes_for_tests:ArrivalLog
    inputs: {{diag: {{source: stopped/diagnostics, policy: drop_oldest, queue_size: 100}}}}
    params: {{out: {tmp}/watch.json}}
"""
    path = tmp / "graph.yaml"
    path.write_text(text)
    return path


def _run_stall(tmp: Path, stopped_policy: str, tcp: bool = False) -> dict:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(TESTS), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.Popen([sys.executable, "-m", "probeless.cli", "launch", str(_graph(tmp, stopped_policy, tcp))],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    pid_file = tmp / "stopped.pid"
    try:
        deadline = time.monotonic() + 60
        while not pid_file.exists() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert pid_file.exists(), proc.communicate(timeout=30)[0]
        time.sleep(BEFORE_S + 1.0)  # the barrier, then a steady baseline
        pid = int(pid_file.read_text())
        t_stop = time.time_ns()
        os.kill(pid, signal.SIGSTOP)
        time.sleep(STOP_S)
        t_cont = time.time_ns()
        os.kill(pid, signal.SIGCONT)
        out, _ = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 0, out
    running = [t for _, t in json.loads((tmp / "running.json").read_text())["log"]["image"]]
    stopped = json.loads((tmp / "stopped.json").read_text())["log"]["image"]
    status = json.loads((tmp / "watch.json").read_text())["status"]["stopped"]["image"]
    baseline = rate_hz(running, running[0] + int(0.5e9), t_stop)
    during = rate_hz(running, t_stop + int(0.2e9), t_cont)
    _report(f"{stopped_policy}_{'tcp' if tcp else 'ipc'}", {
        "running_sink_hz_before": round(baseline, 2), "running_sink_hz_while_stopped": round(during, 2),
        "ratio": round(during / baseline, 3), "frames": FRAMES, "stopped_sink_received": len(stopped),
        "stopped_sink_seq_gaps": status["seq_gaps"], "stopped_sink_dropped": status["dropped"]})
    return {"baseline_hz": baseline, "during_hz": during, "stopped_seqs": [s for s, _ in stopped],
            "status": status, "log": out}


def _report(case: str, figures: dict) -> None:
    """With PROBELESS_FAULTS_REPORT=FILE, add this case's figures to that JSON file (the docs' table)."""
    path = os.environ.get("PROBELESS_FAULTS_REPORT")
    if path:
        report = json.loads(Path(path).read_text()) if Path(path).is_file() else {}
        report[case] = figures
        Path(path).write_text(json.dumps(report, indent=1))


@pytest.mark.graph
@pytest.mark.slow
@pytest.mark.parametrize("tcp", [False, True], ids=["ipc", "tcp"])
def test_a_stopped_lossy_subscriber_never_slows_the_others(tmp_path, tcp):
    r = _run_stall(tmp_path, "latest", tcp=tcp)
    assert r["baseline_hz"] > 0.5 * FPS, r["log"]
    assert r["during_hz"] >= 0.95 * r["baseline_hz"], (r["baseline_hz"], r["during_hz"])
    # the stopped sink lost frames while stopped, and says so in its diagnostics
    lost = FRAMES - len(r["stopped_seqs"])
    assert lost > 0.5 * FPS * STOP_S, lost
    assert r["status"]["seq_gaps"] + r["status"]["dropped"] >= lost, r["status"]
    assert r["status"]["seq_gaps"] > 0


@pytest.mark.graph
@pytest.mark.slow
def test_a_stopped_block_subscriber_holds_up_its_publisher(tmp_path):
    r = _run_stall(tmp_path, "block")
    assert r["baseline_hz"] > 0.5 * FPS, r["log"]
    # the publisher waited: the running sink got at most what the pipes held before the wait began
    assert r["during_hz"] < 0.3 * r["baseline_hz"], (r["baseline_hz"], r["during_hz"])
    assert r["stopped_seqs"] == list(range(FRAMES))     # nothing lost
    assert r["status"]["seq_gaps"] == 0 and r["status"]["dropped"] == 0
