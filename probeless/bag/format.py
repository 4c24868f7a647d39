"""How one bus message is stored in an MCAP record.

The payload of an MCAP message is exactly what crossed the wire after the topic frame: a msgpack
array of ``bin`` items ``[meta, buf0, buf1, ...]`` where ``meta`` is the msgpack envelope document
of :mod:`probeless.wire` and ``bufN`` are the array frames, bit for bit. The topic lives in the
MCAP channel. Nothing is re-encoded on record or replay, so a replayed message is byte-identical to
the recorded one and is validated by the ordinary :func:`probeless.wire.decode`.
"""

from __future__ import annotations

import struct
from typing import Any, Sequence

import msgpack

from probeless.errors import BagError

MESSAGE_ENCODING = "msgpack"    # MCAP channel message_encoding of probeless recordings
SCHEMA_ENCODING = "jsonschema"  # MCAP schema encoding: JSON Schema of the wire document
PROFILE = "probeless"           # MCAP header profile

_MAX_BIN = 0xFFFFFFFF


def _view(frame: Any) -> memoryview:
    buf = getattr(frame, "buffer", frame)  # zmq.Frame exposes .buffer
    view = buf if isinstance(buf, memoryview) else memoryview(buf)
    if view.nbytes == 0:  # an empty array of any shape (e.g. a (0, 0, 0) mask): memoryview.cast refuses zeros
        return memoryview(b"")
    if view.ndim != 1 or view.itemsize != 1:
        view = view.cast("B") if view.c_contiguous else memoryview(bytes(view))
    return view


def _array_header(n: int) -> bytes:
    if n < 16:
        return bytes((0x90 | n,))
    if n <= 0xFFFF:
        return struct.pack(">BH", 0xDC, n)
    return struct.pack(">BI", 0xDD, n)


def _bin_header(n: int) -> bytes:
    if n <= 0xFF:
        return struct.pack(">BB", 0xC4, n)
    if n <= 0xFFFF:
        return struct.pack(">BH", 0xC5, n)
    if n <= _MAX_BIN:
        return struct.pack(">BI", 0xC6, n)
    raise BagError(f"frame of {n} bytes is too large to record (limit {_MAX_BIN} bytes)")


def pack_payload(frames: Sequence[Any]) -> bytes:
    """The MCAP payload of the frames after the topic, ``[meta, buf0, ...]``: a msgpack array of bin.

    Accepts bytes, bytearray, memoryview, zmq.Frame and contiguous numpy arrays; copies each once.
    """
    if len(frames) < 1:
        raise BagError("cannot record a message without its metadata frame")
    parts: list[Any] = [_array_header(len(frames))]
    for frame in frames:
        view = _view(frame)
        parts.append(_bin_header(view.nbytes))
        parts.append(view)
    return b"".join(parts)


def unpack_payload(data: Any) -> list[memoryview]:
    """Split a payload written by :func:`pack_payload` into ``[meta, buf0, ...]`` without copying.

    Raises BagError when ``data`` is not a msgpack array of bin items that fills it exactly.
    """
    view = _view(data)
    size = view.nbytes
    try:
        tag = view[0]
        if 0x90 <= tag <= 0x9F:
            count, pos = tag & 0x0F, 1
        elif tag == 0xDC:
            count, pos = struct.unpack_from(">H", view, 1)[0], 3
        elif tag == 0xDD:
            count, pos = struct.unpack_from(">I", view, 1)[0], 5
        else:
            raise BagError(f"message payload is not a msgpack array (first byte 0x{tag:02x})")
        out = []
        for i in range(count):
            tag = view[pos]
            if tag == 0xC4:
                n, pos = view[pos + 1], pos + 2
            elif tag == 0xC5:
                n, pos = struct.unpack_from(">H", view, pos + 1)[0], pos + 3
            elif tag == 0xC6:
                n, pos = struct.unpack_from(">I", view, pos + 1)[0], pos + 5
            else:
                raise BagError(f"message payload item {i} is not msgpack bin (byte 0x{tag:02x})")
            if pos + n > size:
                raise BagError(f"message payload item {i} runs past the end of the payload")
            out.append(view[pos:pos + n])
            pos += n
    except (IndexError, struct.error):
        raise BagError("message payload is cut short") from None
    if pos != size:
        raise BagError(f"message payload has {size - pos} trailing byte(s)")
    if not out:
        raise BagError("message payload holds no metadata frame")
    return out


def peek(meta: Any) -> tuple[str, int, str, int, int, int]:
    """``(type_name, version, publisher, publish_ns, header_stamp_ns, header_seq)`` of a metadata frame.

    Unpacks only the msgpack metadata, never the array frames; does not validate the fields against
    the schema (that is :func:`probeless.wire.decode`'s job). Raises BagError when malformed.
    """
    try:
        doc = msgpack.unpackb(_view(meta), raw=False, strict_map_key=True)
        header = doc["fields"]["header"]
        out = (doc["type"], doc["version"], doc["publisher"], doc["publish_ns"],
               header["stamp_ns"], header["seq"])
    except BagError:
        raise
    except Exception as exc:  # msgpack raises a zoo of exception types on garbage
        raise BagError(f"metadata frame is not a message envelope ({type(exc).__name__}: {exc})") from None
    if not (isinstance(out[0], str) and isinstance(out[2], str)
            and all(type(v) is int for v in (out[1], out[3], out[4], out[5]))):
        raise BagError("metadata frame: envelope fields have the wrong types")
    return out
