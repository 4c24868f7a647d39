"""``probeless bag export``: recordings into formats other tools read.

* ``foxglove``: an MCAP file with Foxglove well-known schemas, JSON-encoded (schema encoding
  ``jsonschema``, message encoding ``json``): Image and DepthImage -> ``foxglove.RawImage``,
  PoseStamped -> ``foxglove.PoseInFrame`` (frame_id = header.frame_id; the child frame is not
  representable), PointCloud -> ``foxglove.PointCloud`` (x, y, z float32 + red, green, blue, alpha
  uint8), HdrPointCloud -> ``foxglove.PointCloud`` too, its unbounded radiance tone-mapped for display
  (Reinhard ``x / (1 + x)`` per channel, then sRGB 8-bit through :func:`probeless.color.to_srgb8`),
  TriangleMesh -> ``foxglove.SceneUpdate`` with one TriangleListPrimitive. Other types have no
  Foxglove equivalent and are skipped (counted per topic). Channels of other writers whose
  encoding Foxglove decodes itself (:data:`probeless.bag.foreign.PASSTHROUGH`: json, protobuf,
  ros1, cdr with ros2msg/ros2idl/omgidl schemas, flatbuffer) are copied with their schemas byte
  for byte; any other is skipped and named "not decodable: <encoding>" per topic. Float colour images are linear, which
  RawImage cannot show: they become rgb8/rgba8 through the sRGB transfer curve; rgb16 becomes rgb8.
* ``png-dir``: every image topic as numbered PNGs ``DIR/<topic, "/" -> "__">/000000.png`` plus a
  ``timestamps.csv``; 16-bit images and uint16 depth stay 16-bit, float32 depth becomes uint16 mm.
  Channels of other encodings are "not decodable" here.

Both skip a chunk that fails its CRC with a warning counting the messages it held.
"""

from __future__ import annotations

import base64
import json
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator, Sequence

import numpy as np
from mcap.records import Channel, Message

from probeless.bag.foreign import Passthrough, not_decodable
from probeless.bag.format import MESSAGE_ENCODING
from probeless.bag.reader import BagMessage, BagReader
from probeless.bag.writer import recording_paths
from probeless.color import to_srgb8
from probeless.errors import BagError
from probeless.progress import progress as progress_bar

FORMATS = ("foxglove", "png-dir")


@dataclass
class ExportSummary:
    """Messages written and skipped per topic, and notes on lossy conversions (one per topic and kind)."""

    written: dict[str, int] = field(default_factory=dict)
    skipped: dict[str, int] = field(default_factory=dict)
    schemas: dict[str, str] = field(default_factory=dict)   # topic -> what it was written as
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)

    def note(self, text: str) -> None:
        if text not in self.notes:
            self.notes.append(text)


# -- conversions ---------------------------------------------------------------------------------

def _display_image(msg: Any, topic: str, summary: ExportSummary) -> tuple[np.ndarray, str]:
    """(pixels, encoding) of an Image in an encoding both Foxglove and PNG can hold."""
    data, enc = msg.data, msg.encoding
    if data.dtype.kind == "f":
        if data.shape[2] == 1:
            return data.astype("<f4"), "32FC1"
        summary.note(f"{topic}: {enc} (linear float) written as {'rgba8' if data.shape[2] == 4 else 'rgb8'}"
                     " through the sRGB curve")
        return to_srgb8(data), "rgba8" if data.shape[2] == 4 else "rgb8"
    if enc == "rgb16":
        summary.note(f"{topic}: rgb16 written as rgb8 (high byte)")
        return (data >> 8).astype(np.uint8), "rgb8"
    return data.astype(data.dtype.newbyteorder("<")), enc


def _time(ns: int) -> dict[str, int]:
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def _b64(a: np.ndarray) -> str:
    return base64.b64encode(np.ascontiguousarray(a).tobytes()).decode("ascii")


def _raw_image(pixels: np.ndarray, encoding: str, header: Any) -> dict[str, Any]:
    h, w = pixels.shape[:2]
    return {"timestamp": _time(header.stamp_ns), "frame_id": header.frame_id, "width": w, "height": h,
            "encoding": encoding, "step": pixels[0].nbytes if h else 0, "data": _b64(pixels)}


_IDENTITY = {"position": {"x": 0.0, "y": 0.0, "z": 0.0}, "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}


def _fox_image(msg, topic, s):
    return "foxglove.RawImage", _raw_image(*_display_image(msg, topic, s), msg.header)


def _fox_depth(msg, topic, s):
    return "foxglove.RawImage", _raw_image(msg.data.astype(msg.data.dtype.newbyteorder("<")),
                                           "16UC1" if msg.data.dtype == np.uint16 else "32FC1", msg.header)


def _fox_pose(msg, topic, s):
    (x, y, z), (qx, qy, qz, qw) = msg.translation.tolist(), msg.quaternion.tolist()
    return "foxglove.PoseInFrame", {"timestamp": _time(msg.header.stamp_ns), "frame_id": msg.header.frame_id,
                                    "pose": {"position": {"x": x, "y": y, "z": z},
                                             "orientation": {"x": qx, "y": qy, "z": qz, "w": qw}}}


def _colors8(colors: np.ndarray) -> np.ndarray:
    return colors if colors.dtype == np.uint8 else to_srgb8(colors)


def reinhard(radiance: np.ndarray) -> np.ndarray:
    """Reinhard tone map per channel, ``x / (1 + x)``: linear radiance >= 0 (unbounded) -> linear 0..1."""
    r = np.maximum(np.asarray(radiance, np.float32), 0.0)
    return r / (1.0 + r)


def _fox_cloud(msg, topic, s):
    return _fox_points(msg, msg.colors)


def _fox_hdr_cloud(msg, topic, s):
    return _fox_points(msg, reinhard(msg.radiance))


def _fox_points(msg, colors):
    dt = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"),
                   ("red", "u1"), ("green", "u1"), ("blue", "u1"), ("alpha", "u1")])
    pts = np.zeros(len(msg.points), dt)
    c = _colors8(colors)
    pts["x"], pts["y"], pts["z"] = msg.points.T
    pts["red"], pts["green"], pts["blue"], pts["alpha"] = c[:, 0], c[:, 1], c[:, 2], 255
    fields = [{"name": n, "offset": dt.fields[n][1], "type": 7 if n in ("x", "y", "z") else 1} for n in dt.names]
    return "foxglove.PointCloud", {"timestamp": _time(msg.header.stamp_ns), "frame_id": msg.header.frame_id,
                                   "pose": _IDENTITY, "point_stride": dt.itemsize, "fields": fields,
                                   "data": _b64(pts)}


def _fox_mesh(msg, topic, s):
    prim = {"pose": _IDENTITY, "points": [{"x": x, "y": y, "z": z} for x, y, z in msg.vertices.tolist()],
            "color": {"r": 0.7, "g": 0.7, "b": 0.7, "a": 1.0}, "colors": [],
            "indices": msg.triangles.reshape(-1).tolist()}
    if len(msg.vertex_colors):
        prim["colors"] = [{"r": r / 255, "g": g / 255, "b": b / 255, "a": 1.0}
                          for r, g, b in _colors8(msg.vertex_colors).tolist()]
    entity = {"timestamp": _time(msg.header.stamp_ns), "frame_id": msg.header.frame_id, "id": topic,
              "lifetime": {"sec": 0, "nsec": 0}, "frame_locked": False, "metadata": [],
              "arrows": [], "cubes": [], "spheres": [], "cylinders": [], "lines": [],
              "triangles": [prim], "texts": [], "models": []}
    return "foxglove.SceneUpdate", {"deletions": [], "entities": [entity]}


FOXGLOVE: dict[str, Callable[[Any, str, ExportSummary], tuple[str, dict]]] = {
    "sensor/Image": _fox_image, "sensor/DepthImage": _fox_depth, "geometry/PoseStamped": _fox_pose,
    "mesh/PointCloud": _fox_cloud, "mesh/HdrPointCloud": _fox_hdr_cloud, "mesh/TriangleMesh": _fox_mesh,
}

# -- minimal JSON schemas of what is emitted -----------------------------------------------------

_NUM, _INT, _STR = {"type": "number"}, {"type": "integer"}, {"type": "string"}


def _obj(title: str | None = None, **props: Any) -> dict[str, Any]:
    out: dict[str, Any] = {"type": "object", "properties": props}
    if title:
        out["title"] = title
    return out


_TIME = _obj("time", sec={"type": "integer", "minimum": 0},
             nsec={"type": "integer", "minimum": 0, "maximum": 999999999})
_VEC3 = _obj("foxglove.Vector3", x=_NUM, y=_NUM, z=_NUM)
_POSE = _obj("foxglove.Pose", position=_VEC3, orientation=_obj("foxglove.Quaternion", x=_NUM, y=_NUM, z=_NUM, w=_NUM))
_COLOR = _obj("foxglove.Color", r=_NUM, g=_NUM, b=_NUM, a=_NUM)
_BYTES = {"type": "string", "contentEncoding": "base64"}
_LIST = {"type": "array"}

SCHEMAS: dict[str, dict[str, Any]] = {
    "foxglove.RawImage": _obj("foxglove.RawImage", timestamp=_TIME, frame_id=_STR, width=_INT, height=_INT,
                              encoding=_STR, step=_INT, data=_BYTES),
    "foxglove.PoseInFrame": _obj("foxglove.PoseInFrame", timestamp=_TIME, frame_id=_STR, pose=_POSE),
    "foxglove.PointCloud": _obj("foxglove.PointCloud", timestamp=_TIME, frame_id=_STR, pose=_POSE, point_stride=_INT,
                                fields={"type": "array", "items": _obj("foxglove.PackedElementField", name=_STR,
                                                                       offset=_INT, type=_INT)},
                                data=_BYTES),
    "foxglove.SceneUpdate": _obj("foxglove.SceneUpdate", deletions=_LIST, entities={"type": "array", "items": _obj(
        "foxglove.SceneEntity", timestamp=_TIME, frame_id=_STR, id=_STR, lifetime=_TIME,
        frame_locked={"type": "boolean"},
        metadata=_LIST, arrows=_LIST, cubes=_LIST, spheres=_LIST, cylinders=_LIST, lines=_LIST, texts=_LIST,
        models=_LIST, triangles={"type": "array", "items": _obj(
            "foxglove.TriangleListPrimitive", pose=_POSE, points={"type": "array", "items": _VEC3}, color=_COLOR,
            colors={"type": "array", "items": _COLOR}, indices={"type": "array", "items": _INT})})}),
}

# -- driving -------------------------------------------------------------------------------------


def _messages(sources: Sequence[Path], topics: Sequence[str] | None,
              summary: ExportSummary) -> tuple[list[BagReader], int]:
    readers = []
    try:
        for p in sources:
            readers.append(BagReader(p))
    except BagError:
        for r in readers:
            r.close()
        raise
    total = 0
    for r in readers:
        if r.truncated:
            summary.warnings.append(f"{r.path}: {r.truncation_note}")
        total += sum(t.count for t in r.topics().values() if topics is None or t.topic in topics)
    return readers, total


def _iter(readers: list[BagReader], topics, tick,
          summary: ExportSummary) -> Iterator[tuple[BagReader, Channel, BagMessage | Message]]:
    """(reader, channel, message) in log-time order per file: a BagMessage on probeless channels, the
    raw MCAP message on others; a corrupt chunk is skipped with a warning counting what it held."""
    for r in readers:
        for ch, rec in r.records(topics=topics, on_corrupt=summary.warnings.append):
            yield r, ch, (rec if ch.message_encoding != MESSAGE_ENCODING else r.message_of(ch, rec))
            tick()


def export_foxglove(src: str | Path | Sequence[str | Path], out: str | Path, *, force: bool = False,
                    topics: Sequence[str] | None = None, progress: bool = False) -> ExportSummary:
    """Rewrite a recording (file, parts, or split set) into ``out`` with Foxglove JSON schemas."""
    from mcap.writer import CompressionType, Writer

    sources, out = recording_paths(src), Path(out)
    if any(out.resolve() == p.resolve() for p in sources if out.exists()):
        raise BagError(f"{out}: output would overwrite the recording being exported")
    if out.exists() and not force:
        raise BagError(f"{out} already exists; pass --force to overwrite it")
    summary = ExportSummary()
    readers, total = _messages(sources, topics, summary)
    try:
        with open(out, "wb") as f, progress_bar(total, f"export {out.name}", progress) as tick:
            writer = Writer(f, compression=CompressionType.ZSTD)
            writer.start(profile="", library="probeless bag export")
            schema_ids: dict[str, int] = {}
            channel_ids: dict[str, int] = {}
            for r in readers:
                for name, data in r.metadata().items():
                    writer.add_metadata(name, data)
            passthrough = Passthrough(writer)
            for r, ch, m in _iter(readers, topics, tick, summary):
                if ch.message_encoding != MESSAGE_ENCODING:
                    passthrough.add(r, ch, m, summary)
                    continue
                convert = FOXGLOVE.get(m.type_name)
                if convert is None:
                    summary.skipped[m.topic] = summary.skipped.get(m.topic, 0) + 1
                    summary.schemas.setdefault(m.topic, f"skipped: {m.type_name} has no Foxglove equivalent")
                    continue
                schema, doc = convert(r.decode(m), m.topic, summary)
                if m.topic not in channel_ids:
                    if schema not in schema_ids:
                        schema_ids[schema] = writer.register_schema(
                            name=schema, encoding="jsonschema", data=json.dumps(SCHEMAS[schema]).encode())
                    channel_ids[m.topic] = writer.register_channel(m.topic, "json", schema_ids[schema])
                    summary.schemas[m.topic] = schema
                writer.add_message(channel_ids[m.topic], log_time=m.log_time_ns, publish_time=m.publish_time_ns,
                                   sequence=m.sequence, data=json.dumps(doc, separators=(",", ":")).encode())
                summary.written[m.topic] = summary.written.get(m.topic, 0) + 1
            writer.finish()
    except OSError as exc:
        raise BagError(f"cannot write {out}: {exc.strerror or exc}") from None
    finally:
        for r in readers:
            r.close()
    return summary


def _png_pixels(msg: Any, type_name: str, topic: str, summary: ExportSummary) -> np.ndarray:
    """BGR(A)/mono uint8 or uint16 pixels for cv2.imwrite."""
    if type_name == "sensor/DepthImage":
        if msg.data.dtype == np.uint16:
            return msg.data
        summary.note(f"{topic}: float depth written as uint16 millimetres (0 = invalid)")
        return np.clip(np.round(msg.metres() * 1000.0), 0, 65535).astype(np.uint16)
    pixels, enc = _display_image(msg, topic, summary)
    if enc == "32FC1":
        summary.note(f"{topic}: mono float written as 8-bit through the sRGB curve")
        pixels, enc = to_srgb8(pixels), "mono8"
    if enc in ("rgb8", "rgb16"):
        return pixels[..., ::-1]
    if enc == "rgba8":
        return pixels[..., [2, 1, 0, 3]]
    return pixels[..., 0] if pixels.shape[2] == 1 else pixels


def export_png_dir(src: str | Path | Sequence[str | Path], out_dir: str | Path, *, force: bool = False,
                   topics: Sequence[str] | None = None, progress: bool = False) -> ExportSummary:
    """Write every Image/DepthImage topic of a recording as numbered PNGs under ``out_dir``."""
    import cv2

    sources, out_dir = recording_paths(src), Path(out_dir)
    if out_dir.exists() and (not out_dir.is_dir() or any(out_dir.iterdir())):
        if not force:
            raise BagError(f"{out_dir} already exists and is not empty; pass --force to overwrite it")
        if out_dir.is_dir():
            shutil.rmtree(out_dir)
        else:
            out_dir.unlink()
    summary = ExportSummary()
    readers, total = _messages(sources, topics, summary)
    csvs: dict[str, Any] = {}
    try:
        with progress_bar(total, f"export {out_dir.name}/", progress) as tick:
            for r, ch, m in _iter(readers, topics, tick, summary):
                if ch.message_encoding != MESSAGE_ENCODING:
                    not_decodable(ch, summary)
                    continue
                if m.type_name not in ("sensor/Image", "sensor/DepthImage"):
                    summary.skipped[m.topic] = summary.skipped.get(m.topic, 0) + 1
                    summary.schemas.setdefault(m.topic, f"skipped: {m.type_name} is not an image")
                    continue
                msg = r.decode(m)
                topic_dir = out_dir / m.topic.replace("/", "__")
                if m.topic not in csvs:
                    topic_dir.mkdir(parents=True, exist_ok=True)
                    csvs[m.topic] = open(topic_dir / "timestamps.csv", "w")
                    csvs[m.topic].write("index,log_time_ns,stamp_ns,seq\n")
                    summary.schemas[m.topic] = f"PNG in {topic_dir}"
                n = summary.written.get(m.topic, 0)
                name = topic_dir / f"{n:06d}.png"
                if not cv2.imwrite(str(name), np.ascontiguousarray(_png_pixels(msg, m.type_name, m.topic, summary))):
                    raise BagError(f"cannot write {name}")
                csvs[m.topic].write(f"{n},{m.log_time_ns},{msg.header.stamp_ns},{msg.header.seq}\n")
                summary.written[m.topic] = n + 1
    except OSError as exc:
        raise BagError(f"cannot write under {out_dir}: {exc.strerror or exc}") from None
    finally:
        for f in csvs.values():
            f.close()
        for r in readers:
            r.close()
    return summary
