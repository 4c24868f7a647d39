"""Latched topics (ROS 2 "transient local"), with real processes: late joiners and restarted nodes get the last
floorplan and extrinsics, from a live source and from a replay; a topic that is not latched is never re-sent.

The references are the messages the test itself published or recorded (their vertices, transforms and seq).
``PROBELESS_FAULTS_REPORT=FILE`` writes the restart test's delays as JSON (docs/faults.md).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from faults_common import ROOT, RunningGraph, node_env, write_graph

from probeless import wire
from probeless.bag.writer import BagWriter
from probeless.messages import Header, Image
from probeless.messages.geometry import Floorplan, PoseStamped

pytestmark = pytest.mark.graph

WIDTH_M, CEILING_M = 3.7, 2.45                    # the live source's floorplan (StaticSource params)
EXTRINSIC_T = [0.0, -0.06, -0.02]                 # StaticSource's fisheye_from_rgbd translation [m]
BAG_VERTS = [[0.0, 0.0], [5.0, 0.0], [5.0, 4.0], [2.0, 6.0], [0.0, 4.0]]
BAG_CEILING = 2.8
BAG_T = [0.1, -0.05, 0.03]
T0 = 1_700_000_000_000_000_000


def _lines(path: Path) -> list[dict]:
    if not path.exists():
        return []
    return [json.loads(x) for x in path.read_text().splitlines() if x.endswith("}")]


def _wait(cond, timeout_s: float, what: str, graph: RunningGraph) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if cond():
            return
        time.sleep(0.05)
    out = graph.stop()
    raise AssertionError(f"timed out waiting for {what}:\n{out[-3000:]}")


def _inputs(lines: list[dict], pid: int | None = None) -> list[str]:
    return [x["input"] for x in lines if x["event"] == "message" and (pid is None or x["pid"] == pid)]


def test_a_late_joiner_gets_the_last_latched_messages_and_nothing_else(tmp_path):
    """A graph started after the source published reads its topics (``external:``): it gets the floorplan and the
    extrinsics, published before it existed, exactly once each, and never the image (not latched)."""
    src = write_graph(tmp_path, f"""nodes:
  - id: src
    node: latch_nodes:StaticSource
    inputs: {{tick: timer/hz/20}}
    params: {{width_m: {WIDTH_M}, ceiling_m: {CEILING_M}}}
""", "src.yaml")
    out = tmp_path / "late.jsonl"
    late = write_graph(tmp_path, f"""nodes:
  - id: late
    node: latch_nodes:ArrivalLines
    inputs:
      floorplan: {{source: src/floorplan, external: src.yaml, policy: latest}}
      extrinsics: {{source: src/fisheye_from_rgbd, external: src.yaml, policy: drop_oldest}}
      image: {{source: src/image, external: src.yaml, policy: drop_oldest}}
    params: {{out: {out}}}
""", "late.yaml")
    graphs = [RunningGraph(src)]
    try:
        graphs[0].wait_for("published the static messages", 30)
        graphs.append(RunningGraph(late))
        graphs[1].wait_started(30)
        _wait(lambda: {"floorplan", "extrinsics"} <= set(_inputs(_lines(out))), 8.0,
              "the late joiner to get the latched messages", graphs[1])
        time.sleep(0.5)  # room for anything else that would (wrongly) come
    finally:
        for g in graphs:  # both stop at once
            if g.proc.poll() is None:
                g.proc.send_signal(signal.SIGINT)
        for g in graphs:
            g.stop()
    got = _lines(out)
    assert sorted(_inputs(got)) == ["extrinsics", "floorplan"], got  # once each; the image is not latched
    plan = next(x for x in got if x.get("input") == "floorplan")
    np.testing.assert_allclose(plan["vertices"], [[0, 0], [WIDTH_M, 0], [WIDTH_M, 3], [0, 3]])
    assert plan["ceiling"] == CEILING_M and plan["seq"] == 0
    pose = next(x for x in got if x.get("input") == "extrinsics")
    np.testing.assert_allclose(np.array(pose["T"])[:3, 3], EXTRINSIC_T)


def _record(path: Path, seconds: float, hz: float) -> int:
    """A rig recording: floorplan and fisheye_from_rgbd once at the start, then 4x4 rgb frames at ``hz``."""
    T = np.eye(4)
    T[:3, 3] = BAG_T
    first = [("rig/floorplan", Floorplan(Header(T0, "world"), np.array(BAG_VERTS), BAG_CEILING)),
             ("rig/fisheye_from_rgbd", PoseStamped(Header(T0, "rgbd"), "fisheye", T))]
    n = int(seconds * hz)
    with BagWriter(path) as w:
        for topic, msg in first:
            w.write_frames(wire.encode(topic, msg, "rig", T0, seq=0), log_time_ns=T0)
        for i in range(n):
            t = T0 + int((i + 1) * 1e9 / hz)
            img = Image(Header(t, "rgbd"), np.full((4, 4, 1), i % 256, np.uint8), "mono8")
            w.write_frames(wire.encode("rig/rgb", img, "rig", t, seq=i), log_time_ns=t)
    return n


def _sink(name: str, out: Path, restart: bool) -> str:
    lifecycle = "\n    restart: on-failure\n    restart_backoff_s: 0.1" if restart else ""
    return f"""  - id: {name}
    node: latch_nodes:ArrivalLines
    inputs:
      floorplan: {{source: rig/floorplan, policy: block, queue_size: 2}}
      extrinsics: {{source: rig/fisheye_from_rgbd, policy: latest}}
      rgb: {{source: rig/rgb, policy: drop_oldest}}
    params: {{out: {out}}}{lifecycle}
"""


def test_a_node_restarted_downstream_of_a_replay_gets_the_floorplan_and_extrinsics_again(tmp_path):
    """SIGKILL a node fed by a ``bag_player`` (the recording source of launch/probeless.yaml): its new process gets
    the recorded floorplan and extrinsics again (a ``block`` and a ``latest`` input), while a node that ran
    throughout never sees them twice."""
    bag = tmp_path / "rig.mcap"
    _record(bag, seconds=12.0, hz=20.0)
    sink, witness = tmp_path / "sink.jsonl", tmp_path / "witness.jsonl"
    graph = write_graph(tmp_path, f"""nodes:
  - id: rig
    node: bag_player
    outputs: [floorplan, fisheye_from_rgbd, rgb]
    params:
      path: {bag}
      remap: ["rig/floorplan:=floorplan", "rig/fisheye_from_rgbd:=fisheye_from_rgbd", "rig/rgb:=rgb"]
{_sink("sink", sink, restart=True)}{_sink("witness", witness, restart=False)}""")
    g = RunningGraph(graph)
    try:
        g.wait_started(30)
        _wait(lambda: {"floorplan", "extrinsics"} <= set(_inputs(_lines(sink)))
              and _inputs(_lines(sink)).count("rgb") >= 3, 8.0, "the sink's first messages", g)
        first_pid = _lines(sink)[0]["pid"]
        t_kill = time.time_ns()
        os.kill(first_pid, signal.SIGKILL)
        new_pids = lambda: {x["pid"] for x in _lines(sink)} - {first_pid}  # noqa: E731

        def restarted_got_all() -> bool:
            pids = new_pids()
            return bool(pids) and {"floorplan", "extrinsics", "rgb"} <= set(_inputs(_lines(sink), pids.pop()))
        _wait(restarted_got_all, 8.0, "the restarted sink to get the latched messages again", g)
    finally:
        log = g.stop()
    assert "restarting sink (1/3)" in log, log[-3000:]
    pid = new_pids().pop()
    again = [x for x in _lines(sink) if x["pid"] == pid and x["event"] == "message"]
    plan = next(x for x in again if x["input"] == "floorplan")
    np.testing.assert_allclose(plan["vertices"], BAG_VERTS)
    assert plan["ceiling"] == BAG_CEILING and plan["seq"] == 0 and plan["stamp_ns"] == T0  # the recorded message
    pose = next(x for x in again if x["input"] == "extrinsics")
    np.testing.assert_allclose(np.array(pose["T"])[:3, 3], BAG_T)
    assert [x["input"] for x in again].count("floorplan") == 1
    # the node that ran throughout got each latched message once: the re-send for the restarted sink is not its
    seen = _inputs(_lines(witness))
    assert seen.count("floorplan") == 1 and seen.count("extrinsics") == 1, seen
    assert seen.count("rgb") >= 3
    if os.environ.get("PROBELESS_FAULTS_REPORT"):
        setup = next(x["t_ns"] for x in _lines(sink) if x["pid"] == pid and x["event"] == "setup")
        Path(os.environ["PROBELESS_FAULTS_REPORT"]).write_text(json.dumps({
            "kill_to_new_process_setup_s": round((setup - t_kill) / 1e9, 3),
            "setup_to_floorplan_ms": round((plan["t_ns"] - setup) / 1e6, 1),
            "setup_to_extrinsics_ms": round((pose["t_ns"] - setup) / 1e6, 1),
            "setup_to_first_rgb_ms": round((next(x["t_ns"] for x in again if x["input"] == "rgb") - setup) / 1e6, 1),
        }, indent=1))


def test_check_names_a_latched_key_that_is_no_output(tmp_path):
    graph = write_graph(tmp_path, """nodes:
  - id: src
    node: latch_nodes:StaticSource
    inputs: {tick: timer/hz/20}
    latched: [floorplan, imgae]
""")
    proc = subprocess.run([sys.executable, "-m", "probeless.cli", "check", str(graph)], cwd=ROOT, env=node_env(),
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode != 0
    assert f"{graph}:5" in proc.stdout + proc.stderr
    assert "latched: latch_nodes:StaticSource has no output 'imgae' (did you mean 'image'?" in proc.stdout + proc.stderr
