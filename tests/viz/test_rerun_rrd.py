""".rrd files read back with Rerun's own dataframe API (rerun.server.Server + catalog client):

- ``export_rerun`` of a recording written here: every entity path, its archetypes, one row per message
  logged and the stamps written;
- a real graph (pattern_source -> rerun_sink with ``rrd:``, recorded with ``--record`` too): the sink's file
  holds what it says it logged, at the stamps the independent recording holds.
"""

from __future__ import annotations

import re
import socket
from collections import defaultdict

import numpy as np
import pyarrow as pa
import pytest
import rerun as rr
from faults.faults_common import launch_graph, write_graph
from mcap.writer import Writer

from probeless import wire
from probeless.bag.reader import BagReader
from probeless.bag.writer import BagWriter
from probeless.errors import BagError, ParamError, TransportError
from probeless.geom.rotation import matrix_from_quat
from probeless.messages.diagnostics import NodeStatus, StageTiming
from probeless.messages.geometry import PoseStamped
from probeless.messages.header import Header, Tick
from probeless.messages.lighting import Cubemap
from probeless.messages.mesh import PointCloud
from probeless.messages.sensor import CameraInfo, DepthImage, Image
from probeless.nodes.viz.rerun_sink import RerunSink
from probeless.runtime.params import load_params
from probeless.runtime.receiver import RawMessage, peek_raw
from probeless.runtime.testing import RecordingContext
from probeless.viz.rerun_export import export_rerun

T0 = 1_700_000_000_000_000_000
DT = 33_333_333
N = 5


class Rrd:
    """Archetypes per entity path and the ``stamp`` values of each path's rows, from the dataframe API."""

    def __init__(self, path):
        with rr.server.Server(host="127.0.0.1", datasets={"run": [str(path)]}) as srv:
            ds = srv.client().get_dataset("run")
            self.archetypes: dict[str, set[str]] = defaultdict(set)
            for col in ds.schema():
                if getattr(col, "entity_path", None) and not col.is_property:
                    self.archetypes[col.entity_path].add((col.archetype or "untyped").removeprefix("rerun.archetypes."))
            self.stamps = {p: self._stamps(ds, p) for p in self.archetypes}

    @staticmethod
    def _stamps(ds, path: str) -> list[int]:
        tbl = ds.filter_contents([path]).reader(index="stamp").to_arrow_table()
        return tbl.column("stamp").cast(pa.int64()).to_pylist()


def _pose(i: int, child: str = "rgbd") -> PoseStamped:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = matrix_from_quat(np.array([0.0, 0.0, np.sin(i / 10), np.cos(i / 10)])), [i * 0.1, 0, 1]
    return PoseStamped(Header(T0 + i * DT, "world"), child, T)


def _messages(i: int) -> dict:
    h = Header(T0 + i * DT, "rgbd")
    K = np.array([[50.0, 0, 15.5], [0, 50.0, 11.5], [0, 0, 1]])
    rng = np.random.default_rng(i)
    out = {
        "rig/gt/rgbd_pose": _pose(i),
        "rig/rgbd/camera_info": CameraInfo(h, 32, 24, "pinhole", K),
        "rig/rgb": Image(h, rng.integers(0, 256, (24, 32, 3), dtype=np.uint8), "rgb8"),
        "rig/depth": DepthImage(h, rng.integers(500, 3000, (24, 32), dtype=np.uint16), 1000.0),
        "slam/model/points": PointCloud(Header(h.stamp_ns, "world"), rng.random((50, 3), dtype=np.float32),
                                        rng.integers(0, 256, (50, 3), dtype=np.uint8)),
        "envmap/envmaps": Cubemap(Header(h.stamp_ns, "world"), "ball", np.array([1.0, 1.0, 0.5]),
                                  rng.random((6, 8, 8, 3)).astype(np.float16)),
        "slam/diagnostics": NodeStatus(Header(h.stamp_ns, ""), "slam", "running", float(i),
                                       (StageTiming("track", 1, i + 1, 10.0 + i, 10, 10, 10),), rss_bytes=2**30),
        "timer/tick": Tick(h, DT),
    }
    if i >= 2:  # the estimate starts late: the camera follows ground truth until then
        out["slam/pose"] = _pose(i)
    return out


@pytest.fixture
def recording(tmp_path):
    path = tmp_path / "run.mcap"
    with BagWriter(path, chunk_size=20_000) as w:
        for i in range(N):
            for topic, msg in _messages(i).items():
                w.write_frames(wire.encode(topic, msg, "p", T0 + i * DT), log_time_ns=T0 + i * DT)
    return path


def test_export_rerun_reads_back_with_the_dataframe_api(recording, tmp_path):
    out = tmp_path / "run.rrd"
    summary = export_rerun(recording, out)
    all_stamps = [T0 + i * DT for i in range(N)]
    expected = {  # path -> (archetypes, stamps of its rows)
        "/world/rig/gt/rgbd_pose": ({"Transform3D", "TransformAxes3D"}, all_stamps),
        "/world/slam/pose": ({"Transform3D", "TransformAxes3D"}, all_stamps[2:]),
        "/world/camera/rgbd": ({"Transform3D"}, all_stamps),                 # gt for 0, 1; the estimate from 2
        "/world/camera/rgbd/image": ({"Pinhole"}, all_stamps[:1]),           # unchanged calibration: logged once
        "/world/camera/rgbd/image/rig/rgb": ({"Image"}, all_stamps),
        "/world/camera/rgbd/image/rig/depth": ({"DepthImage"}, all_stamps),
        "/world/slam/model/points": ({"Points3D"}, all_stamps),
        "/envmap/envmaps/ball": ({"Image"}, all_stamps),
        "/world/objects/ball": ({"Points3D"}, all_stamps),
        "/timings/slam/track": ({"Scalars"}, all_stamps),
        "/memory/slam": ({"Scalars"}, all_stamps),
    }
    rrd = Rrd(out)
    for path, (archetypes, stamps) in expected.items():
        assert rrd.archetypes.get(path) == archetypes, path
        assert rrd.stamps[path] == stamps, path
    assert rrd.archetypes["/world"] == {"ViewCoordinates"}
    assert set(rrd.archetypes) == set(expected) | {"/world"}
    assert summary.skipped == {"timer/tick": N} and "no Rerun mapping" in summary.schemas["timer/tick"]
    assert summary.written == {t: N - (2 if t == "slam/pose" else 0) for t in _messages(N - 1) if t != "timer/tick"}
    assert summary.schemas["rig/rgb"] == "rerun Image"
    with pytest.raises(BagError, match=f"{out} already exists"):
        export_rerun(recording, out)
    assert export_rerun(recording, out, force=True, topics=["rig/rgb"]).written == {"rig/rgb": N}
    assert Rrd(out).archetypes.keys() == {"/world", "/rig/rgb"}  # no camera info: a 2D image


def test_bag_export_format_rerun_on_the_command_line(recording, tmp_path, capsys):
    from probeless.cli import main

    out = tmp_path / "cli.rrd"
    assert main(["bag", "export", str(recording), "--format", "rerun", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert f"wrote {out}" in text and "rig/rgb:" in text and "-> rerun Image" in text
    assert Rrd(out).stamps["/world/camera/rgbd/image/rig/rgb"] == [T0 + i * DT for i in range(N)]
    assert main(["bag", "export", str(recording), "--format", "rerun", "-o", str(out)]) == 2   # no overwrite
    assert "already exists; pass --force" in capsys.readouterr().err


def test_export_rerun_skips_a_corrupt_chunk_with_a_warning(recording, tmp_path):
    with BagReader(recording) as r:
        chunk = r._chunks[1]
    data = bytearray(recording.read_bytes())
    data[chunk.offset + 200] ^= 0xFF
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(bytes(data))
    summary = export_rerun(bad, tmp_path / "bad.rrd")
    assert len(summary.warnings) == 1 and "corrupt" in summary.warnings[0]
    assert 0 < sum(summary.written.values()) < sum(export_rerun(recording, tmp_path / "ok.rrd").written.values())


def test_export_rerun_names_foreign_channels_not_decodable(tmp_path):
    path = tmp_path / "foreign.mcap"
    with open(path, "wb") as f:
        w = Writer(f)
        w.start(profile="ros2", library="test")
        cid = w.register_channel("/chatter", "cdr", w.register_schema("std_msgs/msg/String", "ros2msg", b"string d"))
        for i in range(4):
            w.add_message(cid, log_time=T0 + i, data=b"\x00\x01\x00\x00", publish_time=T0 + i, sequence=i)
        w.finish()
    summary = export_rerun(path, tmp_path / "f.rrd")
    assert summary.skipped == {"/chatter": 4} and summary.schemas["/chatter"] == "not decodable: cdr"
    assert not summary.written


GRAPH = """
description: rerun_sink writing an .rrd
nodes:
  - id: camera
    node: pattern_source
    inputs:
      tick: timer/hz/20
    outputs: [image]
    params: {{width: 48, height: 32, count: {count}}}
  - id: viewer
    node: rerun_sink
    inputs:
      all: {{source: "*", policy: block, queue_size: 32}}
    params: {{rrd: {rrd}}}
"""


@pytest.mark.graph
def test_rerun_sink_graph_writes_what_it_received(tmp_path):
    count, rrd, mcap = 12, tmp_path / "sink.rrd", tmp_path / "rec.mcap"
    graph = write_graph(tmp_path, GRAPH.format(count=count, rrd=rrd))
    rc, out = launch_graph(graph, "--record", str(mcap), timeout_s=90)
    assert rc == 0, out
    line = re.search(r"(\d+) messages logged on \d+ topics \{(.*?)\}", out)
    assert line, out
    logged = {t: int(n) for t, n in re.findall(r"([\w/]+): (\d+)", line.group(2))}
    assert logged["camera/image"] == count
    with BagReader(mcap) as r:
        recorded = [r.decode(m).header.stamp_ns for m in r.messages("camera/image")]
    got = Rrd(rrd)
    assert got.archetypes["/camera/image"] == {"Image"}
    assert got.stamps["/camera/image"] == recorded and len(recorded) == count
    n_status = logged["camera/diagnostics"]
    timings = [p for p in got.archetypes if p.startswith("/timings/camera/")]
    assert n_status >= 1 and timings and all(0 < len(got.stamps[p]) <= n_status for p in timings)
    assert len(got.stamps["/memory/camera"]) == n_status


def _sink(tmp_path, **params):
    ctx = RecordingContext("viewer", RerunSink)
    ctx.plan = {"nodes": {"viewer": {"inputs": [{"name": "in0", "topic": "cam/image"}]}}}
    node = RerunSink(ctx, load_params(RerunSink.Params, params, node_id="viewer"))
    return ctx, node


def _raw(topic: str, msg) -> RawMessage:
    """A message as the sink receives it: wire frames, envelope peeked (the sink takes raw inputs)."""
    return peek_raw(topic, wire.encode(topic, msg, "p", T0), T0)


def test_rerun_sink_needs_a_sink(tmp_path):
    with pytest.raises(ParamError, match="key 'serve': no sink chosen: set serve: true, spawn: true or rrd"):
        _sink(tmp_path)                     # when the graph is loaded
    node = RerunSink(RecordingContext("viewer", RerunSink), RerunSink.Params())
    with pytest.raises(ParamError, match="no sink chosen"):
        node.setup()                        # and by the node itself


def test_rerun_sink_max_hz_drops_per_topic_and_names_topics_from_the_plan(tmp_path, caplog):
    rrd = tmp_path / "s.rrd"
    ctx, node = _sink(tmp_path, rrd=str(rrd), max_hz=0.5)
    node.setup()
    img = np.zeros((4, 6, 3), np.uint8)
    for i in range(20):     # far faster than 0.5 Hz: only the first of each topic is logged
        node.on_input("in0", _raw("cam/image", Image(Header(T0 + i, "cam"), img, "rgb8")))
        node.on_input("other/image", _raw("other/image", Image(Header(T0 + i, "cam"), img, "rgb8")))
    with caplog.at_level("INFO", logger="viewer"):
        node.close()
    assert "2 messages logged on 2 topics {cam/image: 1, other/image: 1}" in caplog.text
    assert "38 dropped by max_hz" in caplog.text
    got = Rrd(rrd)
    assert got.stamps["/cam/image"] == [T0] and got.stamps["/other/image"] == [T0]


@pytest.mark.parametrize("param", ["grpc_port", "web_port"])
def test_rerun_sink_names_a_busy_port(tmp_path, param):
    with socket.socket() as s, socket.socket() as f:
        s.bind(("127.0.0.1", 0))
        s.listen()
        f.bind(("127.0.0.1", 0))
        busy, free = s.getsockname()[1], f.getsockname()[1]
        f.close()
        other = "web_port" if param == "grpc_port" else "grpc_port"
        _, node = _sink(tmp_path, serve=True, **{param: busy, other: free})
        with pytest.raises(TransportError, match=f"{param} {busy}"):
            node.setup()


def test_rerun_sink_survives_a_message_it_cannot_log(tmp_path, monkeypatch, caplog):
    _, node = _sink(tmp_path, rrd=str(tmp_path / "e.rrd"))
    node.setup()
    monkeypatch.setattr(node.logger, "log", lambda topic, msg: 1 / 0)
    with caplog.at_level("WARNING", logger="viewer"):
        for _ in range(3):
            node.on_input("in0", _raw("cam/image", Image(Header(T0, "cam"), np.zeros((2, 2, 3), np.uint8), "rgb8")))
    node.close()
    assert node.logger.skipped == {"cam/image": 3} and "division by zero" in node.logger.reasons["cam/image"]
    assert caplog.text.count("cam/image: cannot log Image") == 1


def test_rerun_sink_spawn_without_a_display_says_so(tmp_path, monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr("sys.platform", "linux")
    _, node = _sink(tmp_path, spawn=True)
    with pytest.raises(ParamError, match="spawn: true needs a display"):
        node.setup()
