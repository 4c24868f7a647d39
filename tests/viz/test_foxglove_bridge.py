"""foxglove_bridge in a real graph, read by a real WebSocket client speaking Foxglove's protocol.

A recording of images, poses, point clouds and ticks is replayed (looping) into the bridge; a
``websockets`` client connects with the ``foxglove.sdk.v1`` subprotocol (the name foxglove-sdk's
server accepts; the protocol is ``foxglove.websocket.v1`` renamed), reads the advertisements,
subscribes to the image and pose channels and decodes what arrives against the advertised JSON
schemas. The pixels and poses must be the recorded ones; the point cloud, which nobody subscribes
to, must never be converted.
"""

from __future__ import annotations

import asyncio
import base64
import json
import re
import socket
import struct
from pathlib import Path

import jsonschema
import msgpack
import numpy as np
import pytest
import websockets
from faults.faults_common import RunningGraph
from message_examples import examples

from probeless import wire
from probeless.bag.export import ExportSummary
from probeless.bag.foxglove import SCHEMA_OF_TYPE, encode, schema_json, to_foxglove
from probeless.bag.writer import BagWriter
from probeless.errors import ParamError
from probeless.messages import Header, Image, PointCloud, PoseStamped, Tick
from probeless.nodes.viz.foxglove_bridge import FoxgloveBridge, is_loopback
from probeless.runtime.params import load_params
from probeless.runtime.receiver import RawMessage, peek_raw
from probeless.runtime.testing import RecordingContext

SUBPROTOCOL = "foxglove.sdk.v1"
T0 = 1_700_000_000_000_000_000
N = 4


# -- a graph in the background and a Foxglove client (also used by test_foxglove_backpressure) ----

class Graph(RunningGraph):
    """A launched graph with a foxglove_bridge."""

    def bridge_port(self) -> int:
        return int(self.wait_for(r"Foxglove: open connection ws://127\.0\.0\.1:(\d+)").group(1))


def connect(port: int, **kwargs):
    return websockets.connect(f"ws://127.0.0.1:{port}", subprotocols=[SUBPROTOCOL], max_size=None, **kwargs)


async def advertisements(ws, topics: set[str], timeout_s: float = 30.0) -> dict[str, dict]:
    """topic -> advertised channel, once every topic of ``topics`` was advertised (other ops ignored)."""
    channels: dict[str, dict] = {}
    async with asyncio.timeout(timeout_s):
        while not topics <= channels.keys():
            msg = await ws.recv()
            if isinstance(msg, str):
                op = json.loads(msg)
                if op["op"] == "advertise":
                    channels.update({c["topic"]: c for c in op["channels"]})
    return channels


async def subscribe(ws, channel_ids: dict[int, int]) -> None:
    """Subscribe: subscription id -> channel id."""
    await ws.send(json.dumps({"op": "subscribe",
                              "subscriptions": [{"id": s, "channelId": c} for s, c in channel_ids.items()]}))


def message_data(frame: bytes) -> tuple[int, int, dict]:
    """(subscription id, log time [ns], JSON payload) of a binary Message Data frame (opcode 1)."""
    op, sub, log_ns = struct.unpack_from("<BIQ", frame)
    assert op == 1, op
    return sub, log_ns, json.loads(frame[13:])


# -- the recording ---------------------------------------------------------------------------------

def _quat(i: int) -> np.ndarray:
    """A known unit quaternion [x, y, z, w] per frame (axis-angle)."""
    axis = np.array([1.0, 2.0, 2.0 + i]) / np.linalg.norm([1.0, 2.0, 2.0 + i])
    half = 0.3 * (i + 1) / 2
    return np.array([*(np.sin(half) * axis), np.cos(half)])


def _matrix(q: np.ndarray) -> np.ndarray:
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _messages() -> dict[str, list]:
    """N frames of images, poses (known translation and quaternion), point clouds and ticks."""
    rng = np.random.default_rng(7)
    return {
        "image": [Image(Header(T0 + i, "cam", i), rng.integers(0, 256, (6, 8, 3), dtype=np.uint8)) for i in range(N)],
        "pose": [PoseStamped.from_rt(Header(T0 + i, "world", i), "cam", _matrix(_quat(i)),
                                     np.array([0.5 + i, -1.25 * i, 3.0 + 0.1 * i])) for i in range(N)],
        "cloud": [PointCloud(Header(T0 + i, "world", i), rng.random((5, 3), np.float32),
                             rng.integers(0, 256, (5, 3), dtype=np.uint8)) for i in range(N)],
        "tick": [Tick(Header(T0 + i, "tick", i), 50_000_000) for i in range(N)],
    }


def _recording(path: Path) -> dict[str, list]:
    msgs = _messages()
    w = BagWriter(path)
    for i in range(N):
        for topic, seq in msgs.items():
            w.write_frames(wire.encode(topic, seq[i], "p", T0), log_time_ns=T0 + i * 50_000_000)
    w.close()
    return msgs


def _graph(tmp: Path) -> Path:
    path = tmp / "graph.yaml"
    path.write_text(f"""nodes:
  - id: cam
    node: bag_player
    outputs: [image, pose, cloud, tick]
    params: {{path: {tmp / "rec.mcap"}, loop: true}}
  - id: fox
    node: foxglove_bridge
    inputs:
      image: {{source: cam/image, policy: latest}}
      pose: {{source: cam/pose, policy: latest}}
      cloud: {{source: cam/cloud, policy: latest}}
      tick: {{source: cam/tick, policy: latest}}
    params: {{port: 0}}
""")
    return path


async def _watch(port: int) -> tuple[dict[str, dict], dict[str, list]]:
    """Advertisements, then every image and pose received until each recorded frame came at least once."""
    async with connect(port) as ws:
        channels = await advertisements(ws, {"cam/image", "cam/pose", "cam/cloud"})
        await subscribe(ws, {1: channels["cam/image"]["id"], 2: channels["cam/pose"]["id"]})
        got: dict[str, list] = {"cam/image": [], "cam/pose": []}
        async with asyncio.timeout(30):
            while any({_stamp(doc) for _, doc in v} != {T0 + i for i in range(N)} for v in got.values()):
                frame = await ws.recv()
                if isinstance(frame, bytes):
                    sub, log_ns, doc = message_data(frame)
                    got["cam/image" if sub == 1 else "cam/pose"].append((log_ns, doc))
    return channels, got


def _stamp(doc: dict) -> int:
    return doc["timestamp"]["sec"] * 1_000_000_000 + doc["timestamp"]["nsec"]


@pytest.mark.graph
def test_a_foxglove_client_sees_the_graphs_images_and_poses(tmp_path):
    msgs = _recording(tmp_path / "rec.mcap")
    graph = Graph(_graph(tmp_path))
    try:
        channels, got = asyncio.run(_watch(graph.bridge_port()))
    finally:
        out = graph.stop()
    assert graph.proc.returncode == 0, out
    assert "cam/tick" not in channels and "not shown in Foxglove: cam/tick (core/Tick" in out
    for topic, schema in (("cam/image", "foxglove.RawImage"), ("cam/pose", "foxglove.PoseInFrame"),
                          ("cam/cloud", "foxglove.PointCloud")):
        ch = channels[topic]
        assert (ch["schemaName"], ch["schemaEncoding"], ch["encoding"]) == (schema, "jsonschema", "json")
        jsonschema.Draft202012Validator.check_schema(json.loads(ch["schema"]))

    image_schema, pose_schema = (json.loads(channels[t]["schema"]) for t in ("cam/image", "cam/pose"))
    seen_images = set()
    for log_ns, doc in got["cam/image"]:
        jsonschema.validate(doc, image_schema)
        i = _stamp(doc) - T0
        ref = msgs["image"][i]
        assert log_ns == ref.header.stamp_ns and doc["frame_id"] == "cam"
        assert (doc["width"], doc["height"], doc["encoding"], doc["step"]) == (8, 6, "rgb8", 24)
        pixels = np.frombuffer(base64.b64decode(doc["data"]), np.uint8).reshape(6, 8, 3)
        np.testing.assert_array_equal(pixels, ref.data)
        seen_images.add(i)
    seen_poses = set()
    for log_ns, doc in got["cam/pose"]:
        jsonschema.validate(doc, pose_schema)
        i = _stamp(doc) - T0
        assert log_ns == T0 + i and doc["frame_id"] == "world"
        p, q = doc["pose"]["position"], doc["pose"]["orientation"]
        assert [p["x"], p["y"], p["z"]] == msgs["pose"][i].translation.tolist()  # exact: JSON keeps float64
        q, want = np.array([q["x"], q["y"], q["z"], q["w"]]), _quat(i)
        np.testing.assert_allclose(q * np.sign(q[3]), want * np.sign(want[3]), atol=1e-12)
        seen_poses.add(i)
    assert seen_images == seen_poses == set(range(N))

    sent = {t: (int(a), int(b)) for t, a, b in re.findall(r"(cam/\w+): (\d+) sent, (\d+) skipped", out)}
    assert sent["cam/cloud"][0] == 0 and sent["cam/cloud"][1] >= N  # played, never converted
    assert sent["cam/image"][0] >= N and sent["cam/pose"][0] >= N


# -- in process: advertisement before data, conversion on demand, a message that does not decode -----------

def _raw(topic: str, msg, version: int | None = None) -> RawMessage:
    frames = wire.encode(topic, msg, "p", T0)
    if version is not None:  # as from a build with another schema version of the type
        meta = msgpack.unpackb(bytes(frames[1]))
        frames[1] = msgpack.packb({**meta, "version": version})
    return peek_raw(topic, frames, T0)


async def _in_process(caplog) -> None:
    ctx = RecordingContext("fox", FoxgloveBridge)
    ctx.plan = {"nodes": {"fox": {"inputs": [
        {"name": "image", "topic": "cam/image", "type_name": "sensor/Image"},
        {"name": "tick", "topic": "cam/tick", "type_name": "core/Tick"},
        {"name": "pose", "topic": "cam/pose", "type_name": None}]}}}   # a player's output: type known later
    node = FoxgloveBridge(ctx, load_params(FoxgloveBridge.Params, {"port": 0}, node_id="fox"))
    node.setup()
    try:
        images = _messages()["image"]
        async with connect(node.server.port) as ws:
            channels = await advertisements(ws, {"cam/image"})   # before any message
            assert set(channels) == {"cam/image"} and "not shown in Foxglove" in caplog.text
            node.on_input("image", _raw("cam/image", images[0]))
            assert "encode" not in ctx.timings.windows   # no subscriber: not decoded, not converted
            await subscribe(ws, {5: channels["cam/image"]["id"]})
            got = []
            async with asyncio.timeout(10):
                while not got:   # the subscription reaches the server asynchronously
                    node.on_input("image", _raw("cam/image", images[1]))
                    node.on_input("image", _raw("cam/image", images[2], version=99))
                    await asyncio.sleep(0.05)
                    while True:
                        try:
                            frame = await asyncio.wait_for(ws.recv(), 0.05)
                        except TimeoutError:
                            break
                        if isinstance(frame, bytes):
                            got.append(message_data(frame))
            assert {(sub, log_ns) for sub, log_ns, _ in got} == {(5, T0 + 1)}   # the bad one is skipped
            assert caplog.text.count("schema version 99") == 1
            node.on_input("pose", _raw("cam/pose", PoseStamped(Header(T0, "world", 0), "cam", np.eye(4))))
            assert "cam/pose" in await advertisements(ws, {"cam/pose"})     # advertised on its first message
    finally:
        node.close()


def test_the_bridge_converts_only_for_subscribers_and_skips_what_does_not_decode(caplog):
    caplog.set_level("INFO")
    asyncio.run(_in_process(caplog))


@pytest.mark.parametrize("host, loopback", [("127.0.0.1", True), ("localhost", True), ("::1", True),
                                            ("127.0.1.1", True), ("0.0.0.0", False), ("192.168.1.5", False),
                                            ("example.org", False)])
def test_is_loopback(host, loopback):
    assert is_loopback(host) is loopback


def test_a_port_in_use_is_a_param_error_naming_it():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        node = FoxgloveBridge(RecordingContext("fox", FoxgloveBridge),
                              load_params(FoxgloveBridge.Params, {"port": port}, node_id="fox"))
        with pytest.raises(ParamError, match=f"127.0.0.1:{port}.*in use.*port: 0") as info:
            node.setup()
        assert (info.value.node_id, info.value.key) == ("fox", "port")
        node.close()  # nothing to stop: no error


def test_every_converted_type_is_advertised_with_the_schema_its_messages_have():
    notes = ExportSummary()
    for type_name, example in examples().items():
        out = to_foxglove(type_name, example, "t", notes)
        assert (out is None) == (type_name not in SCHEMA_OF_TYPE), type_name
        if out is not None:
            assert out[0] == SCHEMA_OF_TYPE[type_name]
            jsonschema.validate(json.loads(encode(out[1])), json.loads(schema_json(out[0])))
