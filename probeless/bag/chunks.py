"""MCAP chunks built in place: message records go straight into a reusable buffer, then one encode.

The ``mcap`` package's Writer copies each payload four times before the file write (joined into
one bytes, into the chunk's BytesIO, out with ``getvalue``, into the chunk record's BytesIO and
out again). :class:`ChunkBuffer` writes each message record, header and msgpack framing included
(:mod:`probeless.bag.format`), into a bytearray that is reused chunk after chunk, so every frame is
copied once, straight from the receive buffer. :func:`encode_chunk` then turns a full buffer into
the chunk record and its message index records exactly as the ``mcap`` Writer lays them out
(same compressors with the same settings, same CRC over the uncompressed records, message indexes
per channel in order of first appearance), so readers cannot tell the files apart.
"""

from __future__ import annotations

import struct
import zlib
from typing import Any, Sequence

import lz4.frame
import zstandard
from mcap.opcode import Opcode
from mcap.records import ChunkIndex

from probeless.bag.format import _array_header, _bin_header, _view  # same package: the payload framing
from probeless.errors import BagError

MESSAGE_HEADER = struct.Struct("<BQHIQQ")  # opcode, record length, channel id, sequence, log time, publish time
COMPRESSIONS = ("none", "lz4", "zstd")
MIN_CAPACITY = 1 << 20


def compress(data: memoryview, compression: str) -> Any:
    """The chunk's ``records`` field: ``data`` compressed as the mcap Writer does it (or ``data`` itself)."""
    if compression == "lz4":
        return lz4.frame.compress(data)
    if compression == "zstd":
        return zstandard.compress(data)
    return data


def _layout(frames: Sequence[Any]) -> tuple[bytes, list[bytes], list[memoryview], int]:
    """msgpack array header, bin headers, byte views of ``frames`` and the payload size."""
    if len(frames) < 1:
        raise BagError("cannot record a message without its metadata frame")
    views = [_view(f) for f in frames]
    heads = [_bin_header(v.nbytes) for v in views]
    head = _array_header(len(views))
    return head, heads, views, len(head) + sum(map(len, heads)) + sum(v.nbytes for v in views)


def payload_size(frames: Sequence[Any]) -> int:
    """Bytes of the message payload :meth:`ChunkBuffer.add_message` stores for ``frames``."""
    return _layout(frames)[3]


class ChunkBuffer:
    """The records of one chunk in progress, with what its chunk record and message indexes need."""

    def __init__(self, capacity: int = MIN_CAPACITY):
        self.data = bytearray(max(int(capacity), 64))
        self.view = memoryview(self.data)
        self.reset()

    def reset(self) -> None:
        """Empty the chunk, keeping the memory."""
        self.size = 0
        self.messages = 0
        self.start_ns = 0
        self.end_ns = 0
        self.index: dict[int, list[int]] = {}  # channel id -> [log_time, offset, log_time, offset, ...]

    def _reserve(self, n: int) -> None:
        need = self.size + n
        if need > len(self.data):
            self.view.release()
            self.data.extend(bytes(max(need, 2 * len(self.data)) - len(self.data)))
            self.view = memoryview(self.data)

    def add_record(self, record: bytes) -> None:
        """Append a complete record (a schema or channel that precedes its first message)."""
        self._reserve(len(record))
        self.view[self.size:self.size + len(record)] = record
        self.size += len(record)

    def add_message(self, channel_id: int, sequence: int, log_time: int, publish_time: int,
                    frames: Sequence[Any]) -> int:
        """Append a message record whose data is :func:`~probeless.bag.format.pack_payload` of
        ``frames``, copying each frame once; returns the payload size in bytes."""
        head, heads, views, payload = _layout(frames)
        self._reserve(MESSAGE_HEADER.size + payload)
        start = self.size
        MESSAGE_HEADER.pack_into(self.data, start, Opcode.MESSAGE, MESSAGE_HEADER.size - 9 + payload,
                                 channel_id, sequence, log_time, publish_time)
        dst, pos = self.view, start + MESSAGE_HEADER.size
        dst[pos:pos + len(head)] = head
        pos += len(head)
        for h, v in zip(heads, views):
            dst[pos:pos + len(h)] = h
            pos += len(h)
            dst[pos:pos + v.nbytes] = v
            pos += v.nbytes
        self.size = pos
        if self.messages == 0:
            self.start_ns = self.end_ns = log_time
        else:
            self.start_ns, self.end_ns = min(self.start_ns, log_time), max(self.end_ns, log_time)
        self.messages += 1
        entries = self.index.get(channel_id)
        if entries is None:
            entries = self.index[channel_id] = []
        entries += (log_time, start)
        return payload


def message_indexes(index: dict[int, list[int]], first_offset: int) -> tuple[bytes, dict[int, int]]:
    """The message index records of a chunk and each one's file offset, given where they start."""
    parts, offsets, pos = [], {}, first_offset
    for cid, entries in index.items():
        n = len(entries)
        record = struct.pack(f"<BQHI{n}Q", Opcode.MESSAGE_INDEX, 6 + 8 * n, cid, 8 * n, *entries)
        offsets[cid] = pos
        pos += len(record)
        parts.append(record)
    return b"".join(parts), offsets


def encode_chunk(chunk: ChunkBuffer, compression: str, offset: int) -> tuple[list[Any], ChunkIndex]:
    """The bytes to write at file ``offset`` for ``chunk`` (chunk record, then its message indexes)
    as a list of buffers, and the chunk's index entry. Releases the GIL for the CRC and compression."""
    records = chunk.view[:chunk.size]
    crc = zlib.crc32(records)
    data = compress(records, compression)
    name = b"" if compression == "none" else compression.encode()
    nbytes = len(data) if not isinstance(data, memoryview) else data.nbytes
    head = struct.pack(f"<BQQQQII{len(name)}sQ", Opcode.CHUNK, 8 * 3 + 4 + 4 + len(name) + 8 + nbytes,
                       chunk.start_ns, chunk.end_ns, chunk.size, crc, len(name), name, nbytes)
    chunk_length = len(head) + nbytes
    indexes, offsets = message_indexes(chunk.index, offset + chunk_length)
    entry = ChunkIndex(message_start_time=chunk.start_ns, message_end_time=chunk.end_ns,
                       chunk_start_offset=offset, chunk_length=chunk_length, message_index_offsets=offsets,
                       message_index_length=len(indexes), compression=name.decode(),
                       compressed_size=nbytes, uncompressed_size=chunk.size)
    return [head, data, indexes], entry
