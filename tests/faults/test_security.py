"""CURVE on graphs that span hosts, with real processes on loopback.

A two-host graph runs end to end with CURVE (and still without it). While a CURVE graph runs, a
subscriber without the keys (plain, or with a pair of its own) receives nothing, where one with
an allowed pair receives the stream. A rogue publisher bound where a CURVE subscriber connects
(plain, or with a wrong server key) injects nothing, where one holding the real host's secret
key would. Every subprocess has a timeout.
"""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import zmq
import zmq.auth
from faults_common import ROOT, RunningGraph, finish, free_ports, node_env, start_launch

from probeless import wire
from probeless.cli import main
from probeless.errors import GraphError
from probeless.messages import Header, Image
from probeless.runtime.security import node_curve, tool_curve


def keys(tmp_path: Path) -> Path:
    assert main(["keys", "generate", str(tmp_path / "keys"), "--hosts", "camera_pc,gpu_pc"]) == 0
    return tmp_path / "keys"


def two_host_graph(tmp_path: Path, count: int, curve: bool, hz: int = 100) -> tuple[Path, int]:
    cam_port, gpu_port = free_ports(1), free_ports(1)
    security = "security:\n  curve: {keys: keys}\n" if curve else ""
    path = tmp_path / "graph.yaml"
    path.write_text(f"""{security}hosts:
  camera_pc: {{address: 127.0.0.1, port_base: {cam_port}}}
  gpu_pc: {{address: 127.0.0.1, port_base: {gpu_port}}}
nodes:
  - id: src
    node: nodes_for_tests:Ticker
    host: camera_pc
    inputs: {{tick: timer/hz/{hz}}}
    params: {{count: {count}}}
  - id: sink
    node: nodes_for_tests:Recorder
    host: gpu_pc
    inputs: {{image: {{source: src/image, policy: block}}}}
    params: {{out: {tmp_path}/sink.json}}
""")
    return path, cam_port


@pytest.mark.graph
@pytest.mark.slow
@pytest.mark.parametrize("curve", [True, False], ids=["curve", "plain"])
def test_two_host_graph_runs_end_to_end(tmp_path, curve):
    if curve:
        keys(tmp_path)
    path, _ = two_host_graph(tmp_path, count=40, curve=curve)
    gpu = start_launch(path, "--only", "gpu_pc")
    time.sleep(0.5)
    cam = start_launch(path, "--only", "camera_pc")
    cam_out, gpu_out = finish(cam), finish(gpu)
    assert cam.returncode == 0 and gpu.returncode == 0, cam_out + gpu_out
    assert json.loads((tmp_path / "sink.json").read_text())["seqs"]["image"] == list(range(40))


def _listen(endpoint: str, pair: tuple[bytes, bytes] | None, server_key: bytes | None, seconds: float,
            counts: dict, name: str) -> None:
    """Subscribe to everything at ``endpoint`` for ``seconds``; count the messages in ``counts[name]``."""
    zctx = zmq.Context()
    sub = zctx.socket(zmq.SUB)
    if pair is not None:
        sub.curve_publickey, sub.curve_secretkey = pair
        sub.curve_serverkey = server_key
    sub.setsockopt(zmq.SUBSCRIBE, b"")
    sub.connect(endpoint)
    deadline = time.monotonic() + seconds
    counts[name] = 0
    while time.monotonic() < deadline:
        if sub.poll(50):
            sub.recv_multipart()
            counts[name] += 1
    sub.close(0)
    zctx.term()


@pytest.mark.graph
@pytest.mark.slow
def test_subscriber_without_an_allowed_key_receives_nothing(tmp_path, short_run_dir):
    key_dir = keys(tmp_path)
    path, cam_port = two_host_graph(tmp_path, count=0, curve=True, hz=50)   # count 0: runs until stopped
    cam_public = zmq.auth.load_certificate(key_dir / "public" / "camera_pc.key")[0]
    gpu_pair = zmq.auth.load_certificate(key_dir / "private" / "gpu_pc.key_secret")
    stranger = zmq.curve_keypair()
    env = {**node_env(), "PROBELESS_RUN_DIR": str(short_run_dir)}   # the topic tool finds this graph alone
    graph = RunningGraph(path, env=env)
    try:
        graph.wait_started()
        time.sleep(0.5)   # streaming
        counts: dict[str, int] = {}
        listeners = [threading.Thread(target=_listen, args=args) for args in [
            (f"tcp://127.0.0.1:{cam_port}", None, None, 3.0, counts, "plain (lossless port)"),
            (f"tcp://127.0.0.1:{cam_port + 1}", None, None, 3.0, counts, "plain (lossy port)"),
            (f"tcp://127.0.0.1:{cam_port}", stranger, cam_public, 3.0, counts, "own pair (lossless port)"),
            (f"tcp://127.0.0.1:{cam_port + 1}", stranger, cam_public, 3.0, counts, "own pair (lossy port)"),
            (f"tcp://127.0.0.1:{cam_port + 1}", gpu_pair, cam_public, 3.0, counts, "allowed pair (control)"),
        ]]
        for t in listeners:
            t.start()
        for t in listeners:
            t.join(10)
        # the topic tools use the graph's keys (tool_curve): they read a CURVE graph's tcp topics
        echo = subprocess.run([sys.executable, "-m", "probeless.cli", "topic", "echo", "src/image", "-n", "3",
                               "--no-arrays"], cwd=ROOT, env=env, capture_output=True, text=True, timeout=60)
    finally:
        out = graph.stop()
    assert echo.returncode == 0 and echo.stdout.count("sensor/Image") >= 3, echo.stdout + echo.stderr
    assert graph.proc.returncode == 0, out
    assert counts["allowed pair (control)"] > 20, (counts, out)   # the stream was there to be read
    assert {k: v for k, v in counts.items() if "control" not in k} == {
        "plain (lossless port)": 0, "plain (lossy port)": 0, "own pair (lossless port)": 0,
        "own pair (lossy port)": 0}


def _rogue(endpoint: str, pair: tuple[bytes, bytes] | None, topic: str, stop: threading.Event) -> None:
    """Bind ``endpoint`` and publish well-formed images on ``topic`` until ``stop``."""
    zctx = zmq.Context()
    pub = zctx.socket(zmq.XPUB)
    if pair is not None:
        pub.curve_publickey, pub.curve_secretkey = pair
        pub.curve_server = True
    pub.bind(endpoint)
    seq = 0
    while not stop.is_set():
        frames = wire.encode(topic, Image(Header(time.time_ns(), "rogue"), np.zeros((4, 4, 1), np.uint8), "mono8"),
                             topic.split("/")[0], time.time_ns(), seq=seq)
        pub.send_multipart([bytes(memoryview(f)) if isinstance(f, np.ndarray) else f for f in frames])
        while pub.poll(0):
            pub.recv()
        seq += 1
        time.sleep(0.02)
    pub.close(0)
    zctx.term()


@pytest.mark.graph
@pytest.mark.slow
def test_rogue_publisher_cannot_inject(tmp_path):
    """Three sources live on camera_pc; only gpu_pc's sink runs. Rogues bind the sources' ports: a plain
    one and one with its own server key inject nothing; one holding camera_pc's real secret (the
    control) does, so the sink was listening."""
    key_dir = keys(tmp_path)
    cam_port, gpu_port = free_ports(3), free_ports(1)
    path = tmp_path / "graph.yaml"
    sources = "".join(f"""  - id: src{i}
    node: nodes_for_tests:Ticker
    host: camera_pc
    inputs: {{tick: timer/hz/10}}
""" for i in range(3))
    path.write_text(f"""security:
  curve: {{keys: keys}}
hosts:
  camera_pc: {{address: 127.0.0.1, port_base: {cam_port}}}
  gpu_pc: {{address: 127.0.0.1, port_base: {gpu_port}}}
nodes:
{sources}  - id: sink
    node: nodes_for_tests:Recorder
    host: gpu_pc
    inputs:
      plain: {{source: src0/image, policy: block}}
      wrong_key: {{source: src1/image, policy: block}}
      real_key: {{source: src2/image, policy: block}}
    params: {{out: {tmp_path}/sink.json}}
""")
    ports = {name: cam_port + 2 * i for i, name in enumerate(("plain", "wrong_key", "real_key"))}
    pairs = {"plain": None, "wrong_key": zmq.curve_keypair(),
             "real_key": zmq.auth.load_certificate(key_dir / "private" / "camera_pc.key_secret")}
    stop = threading.Event()
    rogues = [threading.Thread(target=_rogue, args=(f"tcp://127.0.0.1:{ports[n]}", pairs[n], f"src{i}/image", stop))
              for i, n in enumerate(ports)]
    for t in rogues:
        t.start()
    graph = RunningGraph(path, "--only", "gpu_pc")
    try:
        graph.wait_started()
        time.sleep(3.0)   # the sink connects to every rogue and listens
    finally:
        out = graph.stop()
        stop.set()
        for t in rogues:
            t.join(5)
    seqs = json.loads((tmp_path / "sink.json").read_text())["seqs"]
    assert len(seqs.get("real_key", [])) > 10, (seqs, out)   # control: the sink was connected and listening
    assert "plain" not in seqs and "wrong_key" not in seqs, seqs


def test_node_curve_secures_tcp_and_leaves_ipc_alone(tmp_path):
    """In one process: a CURVE server and its allowed client talk; the sockets really use CURVE; ipc stays NULL."""
    key_dir = keys(tmp_path)
    endpoint = f"tcp://127.0.0.1:{free_ports(1)}"
    plan = {"curve": {"keys": str(key_dir), "key_names": {"src": "camera_pc", "sink": "gpu_pc"},
                      "servers": {endpoint: "camera_pc"}}}
    server, client = node_curve(plan, "src"), node_curve(plan, "sink")
    zctx = zmq.Context()
    pub, sub, local = zctx.socket(zmq.PUB), zctx.socket(zmq.SUB), zctx.socket(zmq.PUB)
    try:
        server.server(zctx, pub, endpoint)
        pub.bind(endpoint)
        server.server(zctx, local, f"ipc://{tmp_path}/x.pub")
        client.client(sub, endpoint)
        sub.setsockopt(zmq.SUBSCRIBE, b"")
        sub.connect(endpoint)
        assert (pub.mechanism, sub.mechanism, local.mechanism) == (zmq.CURVE, zmq.CURVE, zmq.NULL)
        assert pub.curve_server and not sub.curve_server
        got = None
        deadline = time.monotonic() + 5
        while got is None and time.monotonic() < deadline:
            pub.send(b"hello")
            if sub.poll(50):
                got = sub.recv()
        assert got == b"hello"
        with pytest.raises(GraphError, match="is no publisher of this graph"):
            client.client(zctx.socket(zmq.SUB), "tcp://127.0.0.1:1")
        assert node_curve({"curve": None}, "src") is None
        assert tool_curve(plan).pair() == zmq.auth.load_certificate(key_dir / "private" / "camera_pc.key_secret")
    finally:
        for sock in (pub, sub, local):
            sock.close(0)
        server.stop()
        zctx.term()
