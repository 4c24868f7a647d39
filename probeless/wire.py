"""Wire format: ``[topic, msgpack(envelope + fields), buffer0, buffer1, ...]``.

Array fields are replaced in the msgpack document by ``[buffer_index, dtype, shape]`` and travel
as their own frames, so large images are never copied into the metadata. Decoding is driven by
the declared schema of the message type named in the envelope: every field must be present with
the declared kind, every buffer must be used exactly once and have exactly the declared size.
Nothing in a frame is ever executed; any mismatch raises :class:`SchemaError`.

An end-of-stream marker is ``[topic, b""]``: the publisher's output will send nothing more.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import msgpack
import numpy as np

from probeless.errors import SchemaError
from probeless.messages.base import WIRE_DTYPES, FieldSpec, Message, Struct, lookup, schema_of

MAX_MESSAGE_BYTES = 512 * 1024 * 1024   # default cap on one message, all frames together
ZERO_COPY_BYTES = 64 * 1024             # frames at least this large are sent without copying
MAX_RANK = 16
MAX_DIM = 1 << 32                       # largest array dimension on the wire
EOS = b""
_DTYPES = {s: np.dtype(s) for s in WIRE_DTYPES}  # parsed once: dtype parsing is slow on a cold path


@dataclass(frozen=True)
class Envelope:
    """What the bus adds around a message: its type, schema version, publisher and publish time."""

    type_name: str      # registered message type name, e.g. "sensor/Image"
    version: int        # schema version of that type
    publisher: str      # id of the publishing node
    publish_ns: int     # wall-clock time of publishing [ns since the Unix epoch]


def encode(topic: str, msg: Message, publisher: str, publish_ns: int, seq: int | None = None) -> list[Any]:
    """Frames for one message: topic, msgpack metadata, then one frame per array (zero-copy).

    ``seq``, when given, replaces ``header.seq`` on the wire (the publisher's per-topic counter).
    """
    if not isinstance(msg, Message) or not msg.TYPE_NAME:
        raise SchemaError(f"topic {topic!r}: cannot publish {type(msg).__name__}, not a registered Message")
    buffers: list[np.ndarray] = []
    fields = _to_wire(msg, buffers)
    if seq is not None:
        fields["header"]["seq"] = seq
    meta = {"type": msg.TYPE_NAME, "version": msg.VERSION, "publisher": publisher,
            "publish_ns": int(publish_ns), "fields": fields}
    return [topic.encode(), msgpack.packb(meta, use_bin_type=True), *buffers]


def is_eos(frames: Sequence[Any]) -> bool:
    """True for an end-of-stream marker ``[topic, b""]``."""
    return len(frames) == 2 and len(_view(frames[1])) == 0


def decode(frames: Sequence[Any], *, expected: str | None = None,
           max_bytes: int = MAX_MESSAGE_BYTES) -> tuple[str, Envelope, Message]:
    """Decode frames into (topic, envelope, message); raise SchemaError on anything malformed.

    ``expected`` is the type name the subscriber declared; ``None`` accepts any registered type.
    """
    try:
        return _decode(frames, expected, max_bytes)
    except SchemaError as exc:
        if str(exc).startswith("topic "):
            raise
        raise SchemaError(f"{_where(frames)}{exc}") from None
    except (ValueError, TypeError, KeyError, IndexError, OverflowError, UnicodeDecodeError,
            msgpack.exceptions.ExtraData, RecursionError, MemoryError) as exc:
        raise SchemaError(f"{_where(frames)}malformed message: {type(exc).__name__}: {exc}") from None


def _where(frames: Sequence[Any]) -> str:
    """``topic 'name': `` for error messages, when the topic frame is readable."""
    try:
        return f"topic {bytes(_view(frames[0])[:200]).decode('utf-8')!r}: "
    except (IndexError, TypeError, ValueError):
        return ""


def _decode(frames: Sequence[Any], expected: str | None, max_bytes: int):
    if len(frames) < 2:
        raise SchemaError(f"message has {len(frames)} frame(s), need at least topic and metadata")
    views = [_view(f) for f in frames]
    total = sum(v.nbytes for v in views)
    if total > max_bytes:
        raise SchemaError(f"message of {total} bytes exceeds the limit of {max_bytes} bytes")
    topic = bytes(views[0]).decode("utf-8")
    meta = msgpack.unpackb(views[1], raw=False, strict_map_key=True, use_list=True)
    if not isinstance(meta, dict) or set(meta) != {"type", "version", "publisher", "publish_ns", "fields"}:
        raise SchemaError(f"topic {topic!r}: metadata is not a message envelope")
    type_name, version = meta["type"], meta["version"]
    if not isinstance(type_name, str) or type(version) is not int:
        raise SchemaError(f"topic {topic!r}: envelope type/version malformed")
    if expected is not None and type_name != expected:
        raise SchemaError(f"topic {topic!r}: got {type_name}, expected {expected}")
    cls = lookup(type_name)
    if version != cls.VERSION:
        raise SchemaError(f"topic {topic!r}: {type_name} schema version {version}, this build has {cls.VERSION}")
    publisher, publish_ns = meta["publisher"], meta["publish_ns"]
    if not isinstance(publisher, str) or type(publish_ns) is not int:
        raise SchemaError(f"topic {topic!r}: envelope publisher/publish_ns malformed")
    buffers = views[2:]
    used: set[int] = set()
    msg = _from_wire(cls, meta["fields"], buffers, used, type_name)
    if len(used) != len(buffers):
        raise SchemaError(f"topic {topic!r}: {len(buffers) - len(used)} buffer frame(s) not referenced")
    return topic, Envelope(type_name, version, publisher, publish_ns), msg


def _view(frame: Any) -> memoryview:
    buf = getattr(frame, "buffer", frame)  # zmq.Frame exposes .buffer
    return buf if isinstance(buf, memoryview) else memoryview(buf)


def _to_wire(obj: Struct, buffers: list[np.ndarray]) -> dict:
    out = {}
    for spec in schema_of(type(obj)):
        out[spec.name] = _value_to_wire(spec, getattr(obj, spec.name), buffers)
    return out


def _value_to_wire(spec: FieldSpec, value: Any, buffers: list[np.ndarray]) -> Any:
    if spec.kind == "array":
        buffers.append(value)
        return [len(buffers) - 1, value.dtype.str, list(value.shape)]
    if spec.kind == "struct":
        return _to_wire(value, buffers)
    if spec.kind == "tuple":
        return [_value_to_wire(spec.item, v, buffers) for v in value]
    return value


def _from_wire(cls: type, doc: Any, buffers: list[memoryview], used: set[int], where: str) -> Any:
    """Build ``cls`` from its wire document, checking every field against the declared schema.

    The field checks of ``Struct.__post_init__`` are done here on the wire values, so the object
    is assembled directly and only the class's semantic :meth:`~Struct.validate` runs again.
    """
    specs = schema_of(cls)
    if not isinstance(doc, dict) or len(doc) != len(specs) or any(s.name not in doc for s in specs):
        got = sorted(map(str, doc)) if isinstance(doc, dict) else type(doc).__name__
        raise SchemaError(f"{where}: fields {got} do not match {[s.name for s in specs]}")
    obj = object.__new__(cls)
    dims: dict[str, int] = {}
    for s in specs:
        path = f"{where}.{s.name}"
        value = doc[s.name]
        if s.kind == "array":
            value = _array_from_wire(s.array, value, buffers, used, path, dims)
        else:
            value = _value_from_wire(s, value, buffers, used, path)
        object.__setattr__(obj, s.name, value)
    obj.validate()
    return obj


_SCALAR_TYPES = {"int": int, "str": str, "bool": bool, "float": float}


def _value_from_wire(spec: FieldSpec, value: Any, buffers, used, where: str) -> Any:
    if spec.kind == "array":
        return _array_from_wire(spec.array, value, buffers, used, where, {})
    if spec.kind == "struct":
        return _from_wire(spec.struct, value, buffers, used, where)
    if spec.kind == "tuple":
        if not isinstance(value, list):
            raise SchemaError(f"{where}: expected a list")
        return tuple(_value_from_wire(spec.item, v, buffers, used, f"{where}[{i}]") for i, v in enumerate(value))
    if spec.kind == "float" and type(value) in (int, float):
        return float(value)
    if type(value) is not _SCALAR_TYPES[spec.kind]:
        raise SchemaError(f"{where}: expected {spec.kind}, got {type(value).__name__}")
    return value


def _array_from_wire(spec, desc: Any, buffers, used, where: str, dims: dict[str, int]) -> np.ndarray:
    if not (isinstance(desc, list) and len(desc) == 3):
        raise SchemaError(f"{where}: array descriptor must be [index, dtype, shape]")
    index, dtype, shape = desc
    if type(index) is not int or not 0 <= index < len(buffers) or index in used:
        raise SchemaError(f"{where}: buffer index {index!r} invalid or reused")
    dt = _DTYPES.get(dtype) if isinstance(dtype, str) else None
    if dt is None:
        raise SchemaError(f"{where}: dtype {dtype!r} not allowed on the wire")
    if not (isinstance(shape, list) and len(shape) <= MAX_RANK
            and all(type(d) is int and 0 <= d <= MAX_DIM for d in shape)):
        raise SchemaError(f"{where}: shape {shape!r} malformed")
    if dt not in spec.dtype_set:
        raise SchemaError(f"{where}: dtype {dt.name} not in {spec.describe()}")
    if len(shape) != len(spec.shape):
        raise SchemaError(f"{where}: shape {shape} has rank {len(shape)}, expected {spec.describe()}")
    for size, want in zip(shape, spec.shape):
        if (isinstance(want, int) and size != want) or (isinstance(want, str) and dims.setdefault(want, size) != size):
            raise SchemaError(f"{where}: shape {shape} does not match {spec.describe()}")
    buf = buffers[index]
    if math.prod(shape) * dt.itemsize != buf.nbytes:
        raise SchemaError(f"{where}: buffer has {buf.nbytes} bytes, shape {shape} of {dt.name} needs "
                          f"{math.prod(shape) * dt.itemsize}")
    used.add(index)
    try:
        return np.frombuffer(buf, dtype=dt).reshape(shape)
    except ValueError as exc:  # e.g. an empty array whose other dimensions overflow numpy's size
        raise SchemaError(f"{where}: shape {shape} not representable: {exc}") from None
