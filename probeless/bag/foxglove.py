"""Probeless messages as Foxglove well-known schemas, JSON-encoded (schema encoding ``jsonschema``).

One mapping for every Foxglove consumer: ``probeless bag export --format foxglove`` (an MCAP file)
and the ``foxglove_bridge`` node (a live WebSocket server).

* Image, DepthImage -> ``foxglove.RawImage``. Float colour images are linear, which RawImage cannot
  show: they become rgb8/rgba8 through the sRGB transfer curve; rgb16 becomes rgb8 (high byte).
* PoseStamped -> ``foxglove.PoseInFrame`` (frame_id = header.frame_id; the child frame is not representable).
* PointCloud -> ``foxglove.PointCloud`` (x, y, z float32 + red, green, blue, alpha uint8); HdrPointCloud
  too, its unbounded radiance tone-mapped for display (:func:`reinhard`, then sRGB 8-bit).
* TriangleMesh -> ``foxglove.SceneUpdate`` with one TriangleListPrimitive.

Other types have no Foxglove equivalent (:func:`to_foxglove` returns None).
"""

from __future__ import annotations

import base64
import json
from typing import Any, Callable, Protocol

import numpy as np

from probeless.color import reinhard, to_srgb8


class Notes(Protocol):
    """Where a conversion reports a lossy step (once per topic and kind is enough)."""

    def note(self, text: str) -> None: ...


def _display_image(msg: Any, topic: str, summary: Notes) -> tuple[np.ndarray, str]:
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


# type name -> converter (msg, topic, notes) -> (schema name, JSON document)
FOXGLOVE: dict[str, Callable[[Any, str, Notes], tuple[str, dict]]] = {
    "sensor/Image": _fox_image, "sensor/DepthImage": _fox_depth, "geometry/PoseStamped": _fox_pose,
    "mesh/PointCloud": _fox_cloud, "mesh/HdrPointCloud": _fox_hdr_cloud, "mesh/TriangleMesh": _fox_mesh,
}

# type name -> the schema its converter emits (known before the first message: live channels advertise early)
SCHEMA_OF_TYPE: dict[str, str] = {
    "sensor/Image": "foxglove.RawImage", "sensor/DepthImage": "foxglove.RawImage",
    "geometry/PoseStamped": "foxglove.PoseInFrame", "mesh/PointCloud": "foxglove.PointCloud",
    "mesh/HdrPointCloud": "foxglove.PointCloud", "mesh/TriangleMesh": "foxglove.SceneUpdate",
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


# -- public API ----------------------------------------------------------------------------------

def to_foxglove(type_name: str, msg: Any, topic: str, notes: Notes) -> tuple[str, dict[str, Any]] | None:
    """(schema name, JSON document) of a decoded message, or None when its type has no Foxglove equivalent."""
    convert = FOXGLOVE.get(type_name)
    return None if convert is None else convert(msg, topic, notes)


def schema_json(schema_name: str) -> bytes:
    """The JSON schema (``jsonschema`` encoding) of one emitted schema, as stored in files and advertised."""
    return json.dumps(SCHEMAS[schema_name]).encode()


def encode(doc: dict[str, Any]) -> bytes:
    """A converted document as the compact JSON bytes of one message (``json`` message encoding)."""
    return json.dumps(doc, separators=(",", ":")).encode()
