"""Hand-built MCAP files for reader tests: records padded with extra trailing bytes, unknown records.

The specification lets a record's length exceed the fields a reader knows (readers skip the rest)
and lets files hold records of opcodes a reader does not know. The ``mcap`` package's Writer
makes neither, so :func:`padded_file` lays the records out itself; :func:`plain_file` writes the
same messages through the ``mcap`` Writer, the reference an independent reader can read.
"""

from __future__ import annotations

import struct
import zlib

from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (
    Channel,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    MessageIndex,
    Schema,
    Statistics,
)
from mcap.writer import CompressionType, Writer

MAGIC = b"\x89MCAP0\r\n"
UNKNOWN_OPCODE = 0x80  # the spec reserves 0x80-0xFF for user records


def body(record) -> bytes:
    """The body of a record as the mcap package serializes it (without opcode and length)."""
    rb = RecordBuilder()
    record.write(rb)
    return rb.end()[9:]


def frame(opcode: int, data: bytes, pad: int = 0) -> bytes:
    """One record whose length covers ``pad`` extra trailing bytes."""
    return struct.pack("<BQ", opcode, len(data) + pad) + data + b"\xa5" * pad


def message_record(channel_id: int, seq: int, log_time: int, data: bytes) -> bytes:
    return frame(Opcode.MESSAGE, struct.pack("<HIQQ", channel_id, seq, log_time, log_time) + data)


def sample_messages(n: int = 12) -> list[tuple[int, int, bytes]]:
    """(channel id 1 or 2, log time, payload) of a small two-topic recording."""
    return [(1 + i % 2, 1_000 + 10 * i, bytes([i]) * (5 + i)) for i in range(n)]


SCHEMA = Schema(id=1, name="demo.Thing", encoding="jsonschema", data=b'{"type": "object"}')
CHANNELS = [Channel(id=1, schema_id=1, topic="/a", message_encoding="json", metadata={}),
            Channel(id=2, schema_id=1, topic="/b", message_encoding="json", metadata={"k": "v"})]


def plain_file(path, messages, chunk_size: int = 200) -> None:
    """The messages through the mcap Writer (uncompressed chunks of about ``chunk_size`` bytes)."""
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=chunk_size, compression=CompressionType.NONE)
        w.start(profile="", library="test")
        sid = w.register_schema(SCHEMA.name, SCHEMA.encoding, SCHEMA.data)
        for ch in CHANNELS:
            w.register_channel(ch.topic, ch.message_encoding, sid, ch.metadata)
        for seq, (cid, t, data) in enumerate(messages):
            w.add_message(cid, log_time=t, data=data, publish_time=t, sequence=seq)
        w.finish()


def padded_file(path, messages, per_chunk: int = 4, pad: int = 7, summary: bool = True,
                compression: str = "") -> None:
    """The same messages with every record but messages and the footer padded by ``pad`` bytes, an
    unknown record in the data section and inside each chunk, uncompressed chunks of ``per_chunk``
    (``compression`` only names a compression, to test refusals)
    messages with message indexes, and (``summary``) a summary with chunk indexes and statistics."""
    out = bytearray(MAGIC + frame(Opcode.HEADER, body(Header(profile="", library="test")), pad))
    out += frame(UNKNOWN_OPCODE, b"user record", 0)
    chunk_indexes = []
    for k in range(0, len(messages), per_chunk):
        part = messages[k:k + per_chunk]
        inner = bytearray()
        if k == 0:
            inner += frame(Opcode.SCHEMA, body(SCHEMA), pad)
            inner += b"".join(frame(Opcode.CHANNEL, body(ch), pad) for ch in CHANNELS)
        inner += frame(UNKNOWN_OPCODE, b"inside a chunk", pad)
        index: dict[int, list] = {}
        for i, (cid, t, data) in enumerate(part):
            index.setdefault(cid, []).append((t, len(inner)))
            inner += message_record(cid, k + i, t, data)
        start, end = min(t for _, t, _ in part), max(t for _, t, _ in part)
        chunk = (struct.pack("<QQQI", start, end, len(inner), zlib.crc32(inner)) + struct.pack("<I", len(compression))
                 + compression.encode() + struct.pack("<Q", len(inner)) + bytes(inner))
        chunk_at = len(out)
        out += frame(Opcode.CHUNK, chunk, pad)
        chunk_len = len(out) - chunk_at
        offsets, index_at = {}, len(out)
        for cid, records in index.items():
            offsets[cid] = len(out)
            out += frame(Opcode.MESSAGE_INDEX, body(MessageIndex(channel_id=cid, records=records)), pad)
        chunk_indexes.append(ChunkIndex(message_start_time=start, message_end_time=end, chunk_start_offset=chunk_at,
                                        chunk_length=chunk_len, message_index_offsets=offsets,
                                        message_index_length=len(out) - index_at, compression=compression,
                                        compressed_size=len(inner), uncompressed_size=len(inner)))
    out += frame(Opcode.DATA_END, body(DataEnd(data_section_crc=0)), pad)
    summary_start = 0
    if summary:
        summary_start = len(out)
        counts: dict[int, int] = {}
        for cid, _, _ in messages:
            counts[cid] = counts.get(cid, 0) + 1
        stats = Statistics(message_count=len(messages), schema_count=1, channel_count=len(CHANNELS),
                           attachment_count=0, metadata_count=0, chunk_count=len(chunk_indexes),
                           message_start_time=min(t for _, t, _ in messages),
                           message_end_time=max(t for _, t, _ in messages), channel_message_counts=counts)
        out += frame(Opcode.SCHEMA, body(SCHEMA), pad)
        out += b"".join(frame(Opcode.CHANNEL, body(ch), pad) for ch in CHANNELS)
        out += frame(Opcode.STATISTICS, body(stats), pad)
        out += b"".join(frame(Opcode.CHUNK_INDEX, body(ci), pad) for ci in chunk_indexes)
        out += frame(UNKNOWN_OPCODE, b"unknown summary record", pad)
    out += frame(Opcode.FOOTER, body(Footer(summary_start=summary_start, summary_offset_start=0, summary_crc=0)))
    out += MAGIC
    with open(path, "wb") as f:
        f.write(bytes(out))
