"""A stopped subscriber slows its publisher only when its input is ``block`` (real processes, SIGSTOP).

The experiment of issue 18: a 30 Hz camera feeds two sinks; one sink's process is stopped for 10 s.
With a lossy policy the other sink keeps >= 0.95x its rate and the stopped one reports its losses
(seq gaps) once it runs again; with ``block`` the publisher waits for it and it loses nothing.
"""

from __future__ import annotations

import json
import os
import signal
import time
from pathlib import Path

import pytest
from faults_common import RunningGraph, free_ports, rate_hz

FPS, BEFORE_S, STOP_S, AFTER_S = 30, 2.5, 10.0, 1.5
FRAMES = int(FPS * (BEFORE_S + STOP_S + AFTER_S + 0.5))  # the source's frames, counted from the graph's start
# with ``block`` the source waits out the stop, so its frames last that much longer: give it 6 s of frames left at
# the stop, twice what it would need to pass ``during_hz < 0.3 * baseline`` if it did not wait
BLOCK_FRAMES = int(FPS * (BEFORE_S + 6.0 + 0.5))


def _graph(tmp: Path, stopped_policy: str, tcp: bool, frames: int) -> Path:
    queue = ", queue_size: 4" if stopped_policy != "latest" else ""
    hosts = f"hosts:\n  cam: {{address: 127.0.0.1, port_base: {free_ports(1)}}}\n" if tcp else ""
    text = f"""{hosts}nodes:
  - id: src
    node: pattern_source
{"    host: cam" if tcp else ""}
    inputs: {{tick: timer/hz/{FPS}}}
    params: {{width: 640, height: 480, count: {frames}}}
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


def _run_stall(tmp: Path, stopped_policy: str, tcp: bool = False, frames: int = FRAMES) -> dict:
    g = RunningGraph(_graph(tmp, stopped_policy, tcp, frames))
    try:
        g.wait_started()  # the barrier passed: the source runs from here
        time.sleep(BEFORE_S)  # a steady baseline
        pid = int((tmp / "stopped.pid").read_text())
        t_stop = time.time_ns()
        os.kill(pid, signal.SIGSTOP)
        time.sleep(STOP_S)
        t_cont = time.time_ns()
        os.kill(pid, signal.SIGCONT)
        g.proc.wait(timeout=120)
    finally:
        out = g.stop()
    assert g.proc.returncode == 0, out
    running = [t for _, t in json.loads((tmp / "running.json").read_text())["log"]["image"]]
    stopped = json.loads((tmp / "stopped.json").read_text())["log"]["image"]
    status = json.loads((tmp / "watch.json").read_text())["status"]["stopped"]["image"]
    baseline = rate_hz(running, running[0] + int(0.5e9), t_stop)
    during = rate_hz(running, t_stop + int(0.2e9), t_cont)
    _report(f"{stopped_policy}_{'tcp' if tcp else 'ipc'}", {
        "running_sink_hz_before": round(baseline, 2), "running_sink_hz_while_stopped": round(during, 2),
        "ratio": round(during / baseline, 3), "frames": frames, "stopped_sink_received": len(stopped),
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
    r = _run_stall(tmp_path, "block", frames=BLOCK_FRAMES)
    assert r["baseline_hz"] > 0.5 * FPS, r["log"]
    # the publisher waited: the running sink got at most what the pipes held before the wait began
    assert r["during_hz"] < 0.3 * r["baseline_hz"], (r["baseline_hz"], r["during_hz"])
    assert r["stopped_seqs"] == list(range(BLOCK_FRAMES))     # nothing lost
    assert r["status"]["seq_gaps"] == 0 and r["status"]["dropped"] == 0
