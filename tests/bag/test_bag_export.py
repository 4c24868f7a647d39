"""bag export (Foxglove MCAP, PNG directory) and bag info."""

from __future__ import annotations

import argparse
import base64
import json
import os
import shutil

import cv2
import numpy as np
import pytest
from mcap.reader import make_reader
from message_examples import examples

from probeless import wire
from probeless.bag.cli import add_export_parser, add_info_parser
from probeless.bag.export import export_foxglove, export_png_dir
from probeless.bag.writer import BagWriter
from probeless.messages import DepthImage, Header, Image

T0 = 1_700_000_000_000_000_000
N = 3


def rgb(i):
    return Image(Header(T0 + i, "cam", i), np.random.default_rng(i).integers(0, 256, (6, 8, 3), dtype=np.uint8))


def depth(i):
    return DepthImage(Header(T0 + i, "cam", i),
                      np.random.default_rng(i).integers(0, 60000, (6, 8), dtype=np.uint16), 1000.0)


def mono16(i):
    return Image(Header(T0 + i, "cam", i),
                 np.random.default_rng(i).integers(0, 65536, (5, 7, 1), dtype=np.uint16), "mono16")


@pytest.fixture
def recording(tmp_path):
    ex = examples()
    path = tmp_path / "run.mcap"
    plan = {"file": "launch/demo.yaml", "args": {"fps": 30},
            "nodes": {"camera": {"node": "demo.Camera", "params": {"fps": 30}},
                      "relight": {"node": "demo.Relight", "params": {"bands": 3}}}}
    w = BagWriter(path, chunk_size=2000, metadata={"probeless.graph": {
        "plan": json.dumps(plan), "version": "0.1.0", "git_revision": "abc1234", "command": "probeless launch x"}})
    msgs = {"camera/rgb": [rgb(i) for i in range(N)], "camera/depth": [depth(i) for i in range(N)],
            "camera/mono": [mono16(i) for i in range(N)], "slam/pose": [ex["geometry/PoseStamped"]] * N,
            "scan/cloud": [ex["mesh/PointCloud"]] * N, "scan/mesh": [ex["mesh/TriangleMesh"]] * N,
            "timer/tick": [ex["core/Tick"]] * N}
    for i in range(N):
        for topic, seq in msgs.items():
            w.write_frames(wire.encode(topic, seq[i], "p", T0), log_time_ns=T0 + i * 33_000_000)
    w.close(extra_metadata={"probeless.incomplete": {"camera/rgb": "2 messages missing (seq gaps)"}})
    return path, msgs


def read_json_mcap(path):
    """{topic: (schema name, [json documents])}, each document checked against its JSON schema."""
    import jsonschema

    with open(path, "rb") as f:
        reader = make_reader(f)
        out = {}
        for schema, channel, message in reader.iter_messages(log_time_order=True):
            assert (schema.encoding, channel.message_encoding) == ("jsonschema", "json")
            doc = json.loads(message.data)
            jsonschema.validate(doc, json.loads(schema.data))
            out.setdefault(channel.topic, (schema.name, []))[1].append(doc)
        return out


def test_export_foxglove(recording, tmp_path):
    path, msgs = recording
    out = tmp_path / "fox.mcap"
    summary = export_foxglove(path, out)
    assert summary.skipped == {"timer/tick": N}
    got = read_json_mcap(out)
    assert {t: s for t, (s, _) in got.items()} == {
        "camera/rgb": "foxglove.RawImage", "camera/depth": "foxglove.RawImage", "camera/mono": "foxglove.RawImage",
        "slam/pose": "foxglove.PoseInFrame", "scan/cloud": "foxglove.PointCloud", "scan/mesh": "foxglove.SceneUpdate"}
    for topic, enc in (("camera/rgb", "rgb8"), ("camera/depth", "16UC1"), ("camera/mono", "mono16")):
        docs = got[topic][1]
        assert len(docs) == N
        for doc, src in zip(docs, msgs[topic]):
            assert doc["encoding"] == enc and (doc["height"], doc["width"]) == src.data.shape[:2]
            assert doc["step"] == src.data.shape[1] * src.data[0, 0].nbytes
            assert base64.b64decode(doc["data"]) == src.data.tobytes()
            assert doc["timestamp"] == {"sec": src.header.stamp_ns // 10**9, "nsec": src.header.stamp_ns % 10**9}
            assert doc["frame_id"] == "cam"
    pose = msgs["slam/pose"][0]
    p = got["slam/pose"][1][0]
    assert p["frame_id"] == pose.header.frame_id
    assert [p["pose"]["position"][k] for k in "xyz"] == pose.translation.tolist()
    assert np.allclose([p["pose"]["orientation"][k] for k in "xyzw"], pose.quaternion)
    cloud_src, cloud = msgs["scan/cloud"][0], got["scan/cloud"][1][0]
    dt = np.dtype({"names": [f["name"] for f in cloud["fields"]], "offsets": [f["offset"] for f in cloud["fields"]],
                   "formats": ["<f4" if f["type"] == 7 else "u1" for f in cloud["fields"]],
                   "itemsize": cloud["point_stride"]})
    pts = np.frombuffer(base64.b64decode(cloud["data"]), dt)
    assert np.array_equal(np.stack([pts["x"], pts["y"], pts["z"]], 1), cloud_src.points)
    assert np.array_equal(np.stack([pts["red"], pts["green"], pts["blue"]], 1), cloud_src.colors)
    mesh_src, mesh = msgs["scan/mesh"][0], got["scan/mesh"][1][0]
    tri = mesh["entities"][0]["triangles"][0]
    assert tri["indices"] == mesh_src.triangles.reshape(-1).tolist() and len(tri["points"]) == 4
    with open(out, "rb") as f:
        assert "probeless.graph" in {m.name for m in make_reader(f).iter_metadata()}


def test_export_float_image_to_foxglove(tmp_path):
    path = tmp_path / "f.mcap"
    data = np.linspace(0, 1, 4 * 5 * 3, dtype=np.float32).reshape(4, 5, 3)
    with BagWriter(path) as w:
        w.write_frames(wire.encode("hdr", Image(Header(T0), data, "rgbf32"), "p", T0), log_time_ns=T0)
        w.write_frames(wire.encode("m", Image(Header(T0), data[..., :1].copy(), "monof32"), "p", T0), log_time_ns=T0)
    summary = export_foxglove(path, tmp_path / "o.mcap")
    got = read_json_mcap(tmp_path / "o.mcap")
    doc = got["hdr"][1][0]
    assert doc["encoding"] == "rgb8" and any("sRGB" in n for n in summary.notes)
    pix = np.frombuffer(base64.b64decode(doc["data"]), np.uint8).reshape(4, 5, 3)
    assert pix[0, 0, 0] == 0 and pix[-1, -1, -1] == 255 and np.all(np.diff(pix.reshape(-1).astype(int)) >= 0)
    assert got["m"][1][0]["encoding"] == "32FC1"
    assert base64.b64decode(got["m"][1][0]["data"]) == data[..., :1].tobytes()


def test_export_png_dir(recording, tmp_path):
    path, msgs = recording
    out = tmp_path / "pngs"
    summary = export_png_dir(path, out)
    assert summary.written == {"camera/rgb": N, "camera/depth": N, "camera/mono": N}
    assert summary.skipped["scan/cloud"] == N
    for i in range(N):
        color = cv2.imread(str(out / "camera__rgb" / f"{i:06d}.png"), cv2.IMREAD_COLOR)
        assert np.array_equal(color, msgs["camera/rgb"][i].data[..., ::-1])
        d = cv2.imread(str(out / "camera__depth" / f"{i:06d}.png"), cv2.IMREAD_UNCHANGED)
        assert d.dtype == np.uint16 and np.array_equal(d, msgs["camera/depth"][i].data)
        m = cv2.imread(str(out / "camera__mono" / f"{i:06d}.png"), cv2.IMREAD_UNCHANGED)
        assert m.dtype == np.uint16 and np.array_equal(m, msgs["camera/mono"][i].data[..., 0])
    lines = (out / "camera__rgb" / "timestamps.csv").read_text().splitlines()
    assert lines[0] == "index,log_time_ns,stamp_ns,seq" and lines[2] == f"1,{T0 + 33_000_000},{T0 + 1},1"
    assert not (out / "timer__tick").exists()


def bag_parser():
    p = argparse.ArgumentParser(prog="probeless bag")
    sub = p.add_subparsers(dest="bag_command", required=True)
    add_info_parser(sub)
    add_export_parser(sub)
    return p


def run(argv):
    ns = bag_parser().parse_args(argv)
    return ns.func(ns)


def test_cmd_export_and_force(recording, tmp_path, capsys):
    path, _ = recording
    out = tmp_path / "o.mcap"
    assert run(["export", str(path), "--format", "foxglove", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "camera/rgb: 3 message(s) -> foxglove.RawImage" in text and "timer/tick" in text
    assert run(["export", str(path), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and str(out) in err and "--force" in err
    assert run(["export", str(path), "-o", str(out), "--force", "--topic", "slam/pose"]) == 0
    assert set(read_json_mcap(out)) == {"slam/pose"}
    assert run(["export", str(path), "--format", "png-dir", "-o", str(tmp_path / "d")]) == 0
    assert (tmp_path / "d" / "camera__rgb" / "000002.png").exists()


def test_cmd_info_json(recording, capsys):
    path, msgs = recording
    assert run(["info", str(path), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert {t: d["count"] for t, d in report["topics"].items()} == {t: N for t in msgs}
    assert report["topics"]["camera/rgb"]["type"] == "sensor/Image"
    assert report["topics"]["camera/rgb"]["rate_hz"] == pytest.approx(1e9 / 33_000_000)
    assert report["duration_s"] == pytest.approx(2 * 0.033)
    assert report["compression"] == ["lz4"] and report["message_count"] == N * len(msgs)
    assert report["incomplete"] == {"camera/rgb": "2 messages missing (seq gaps)"}
    g = report["graph"]
    assert (g["version"], g["git_revision"], g["file"]) == ("0.1.0", "abc1234", "launch/demo.yaml")
    assert g["nodes"]["camera"] == {"node": "demo.Camera", "params": {"fps": 30}}
    assert report["files"][0]["truncated"] is False


def test_cmd_info_text_truncated_and_errors(recording, tmp_path, capsys):
    path, _ = recording
    assert run(["info", str(path)]) == 0
    text = capsys.readouterr().out
    for want in ("camera/rgb", "sensor/Image v1", "30.30 Hz", "INCOMPLETE:", "2 messages missing",
                 "abc1234", "probeless launch x", "launch/demo.yaml", "relight: demo.Relight", '"bands": 3'):
        assert want in text, want
    cut = tmp_path / "cut.mcap"
    shutil.copy(path, cut)
    os.truncate(cut, path.stat().st_size // 2)
    assert run(["info", str(cut)]) == 0
    text = capsys.readouterr().out
    assert "WARNING:" in text and "complete chunk" in text and "camera/rgb" in text
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"hello")
    assert run(["info", str(junk), "--json"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "is not an MCAP file" in err and str(junk) in err


def test_info_on_split_recording(tmp_path, capsys):
    path = tmp_path / "split.mcap"
    with BagWriter(path, max_duration_s=0.05) as w:
        for i in range(10):
            w.write_frames(wire.encode("cam", rgb(i), "p", T0), log_time_ns=T0 + i * 10_000_000)
    assert len(w.paths) == 2
    assert run(["info", str(path), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert len(report["files"]) == 2 and report["topics"]["cam"]["count"] == 10
