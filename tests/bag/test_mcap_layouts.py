"""Other writers' valid MCAP layouts: every combination of chunk index, message index, summary channels,
summary schemas, statistics and record padding reads back exactly the records written.

Two independent builders: the ``mcap`` package's Writer with its options (index types, repeated
channels/schemas, statistics, chunking, compression), and a byte-level builder (:mod:`mcap_raw`'s
records) that can also pad every record and leave any summary part out. The reference is the list of
messages each file was written from; the ``mcap`` package's own reader is no reference here (it raises
KeyError when the summary lacks the channels its chunk indexes point to).
"""

from __future__ import annotations

import itertools
import struct
import zlib

import pytest
from mcap.opcode import Opcode
from mcap.records import ChunkIndex, DataEnd, Footer, Header, MessageIndex, Statistics
from mcap.writer import CompressionType, IndexType, Writer
from mcap_raw import CHANNELS, MAGIC, SCHEMA, body, frame, message_record, sample_messages

from probeless.bag.info import info_report
from probeless.bag.reader import BagReader
from probeless.errors import BagError

TOPIC = {ch.id: ch.topic for ch in CHANNELS}


def _expected(messages):
    out = {}
    for cid, t, data in messages:
        out.setdefault(TOPIC[cid], []).append((t, data))
    return out


def _check(path, messages):
    want = _expected(messages)
    with BagReader(path) as r:   # one topic, before anything else is asked: channels known from the start
        assert [(m.log_time, bytes(m.data)) for _, m in r.records("/b")] == want["/b"]
    with BagReader(path) as r:
        topics = r.topics()
        assert {t: i.count for t, i in topics.items()} == {t: len(v) for t, v in want.items()}
        for topic, got in topics.items():
            assert (got.first_ns, got.last_ns) == (want[topic][0][0], want[topic][-1][0])
            assert got.type_name == SCHEMA.name and got.message_encoding == "json"
        read = {}
        for ch, m in r.records():
            read.setdefault(ch.topic, []).append((m.log_time, bytes(m.data)))
        assert read == want
        assert (r.start_ns, r.end_ns) == (messages[0][1], messages[-1][1])
    assert info_report([path])["message_count"] == len(messages)


MCAP_OPTIONS = list(itertools.product(
    [IndexType.ALL, IndexType.CHUNK, IndexType.MESSAGE, IndexType.NONE],  # chunk and/or message indexes
    [True, False],     # repeat_channels: channels in the summary
    [True, False],     # repeat_schemas: schemas in the summary
    [True, False],     # statistics
    [CompressionType.NONE, CompressionType.ZSTD, CompressionType.LZ4]))


@pytest.mark.parametrize("index,rch,rsch,stats,comp", MCAP_OPTIONS)
def test_mcap_writer_layouts_read_back_exactly(tmp_path, index, rch, rsch, stats, comp):
    messages = sample_messages(30)
    path = tmp_path / "x.mcap"
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=150, compression=comp, index_types=index, repeat_channels=rch,
                   repeat_schemas=rsch, use_statistics=stats)
        w.start(profile="", library="other writer")
        sid = w.register_schema(SCHEMA.name, SCHEMA.encoding, SCHEMA.data)
        for ch in CHANNELS:
            w.register_channel(ch.topic, ch.message_encoding, sid, ch.metadata)
        for seq, (cid, t, data) in enumerate(messages):
            w.add_message(cid, log_time=t, data=data, publish_time=t, sequence=seq)
        w.finish()
    _check(path, messages)


def raw_file(path, messages, *, chunk_index: bool, message_index: bool, channels: bool, schemas: bool,
             statistics: bool, pad: int, per_chunk: int = 4) -> None:
    """Chunks of ``per_chunk`` messages, schema and channels in the first chunk; each summary part optional;
    every record but messages and the footer padded by ``pad`` bytes."""
    out = bytearray(MAGIC + frame(Opcode.HEADER, body(Header(profile="", library="raw")), pad))
    indexes = []
    for k in range(0, len(messages), per_chunk):
        part = messages[k:k + per_chunk]
        inner = bytearray()
        if k == 0:
            inner += frame(Opcode.SCHEMA, body(SCHEMA), pad)
            inner += b"".join(frame(Opcode.CHANNEL, body(ch), pad) for ch in CHANNELS)
        index: dict[int, list] = {}
        for i, (cid, t, data) in enumerate(part):
            index.setdefault(cid, []).append((t, len(inner)))
            inner += message_record(cid, k + i, t, data)
        start, end = part[0][1], part[-1][1]
        chunk = (struct.pack("<QQQI", start, end, len(inner), zlib.crc32(inner)) + struct.pack("<I", 0)
                 + struct.pack("<Q", len(inner)) + bytes(inner))
        at = len(out)
        out += frame(Opcode.CHUNK, chunk, pad)
        length, offsets, index_at = len(out) - at, {}, len(out)
        if message_index:
            for cid, recs in index.items():
                offsets[cid] = len(out)
                out += frame(Opcode.MESSAGE_INDEX, body(MessageIndex(channel_id=cid, records=recs)), pad)
        indexes.append(ChunkIndex(message_start_time=start, message_end_time=end, chunk_start_offset=at,
                                  chunk_length=length, message_index_offsets=offsets,
                                  message_index_length=len(out) - index_at, compression="",
                                  compressed_size=len(inner), uncompressed_size=len(inner)))
    out += frame(Opcode.DATA_END, body(DataEnd(data_section_crc=0)), pad)
    summary = bytearray()
    if schemas:
        summary += frame(Opcode.SCHEMA, body(SCHEMA), pad)
    if channels:
        summary += b"".join(frame(Opcode.CHANNEL, body(ch), pad) for ch in CHANNELS)
    if statistics:
        counts: dict[int, int] = {}
        for cid, _, _ in messages:
            counts[cid] = counts.get(cid, 0) + 1
        summary += frame(Opcode.STATISTICS, body(Statistics(
            message_count=len(messages), schema_count=1, channel_count=len(CHANNELS), attachment_count=0,
            metadata_count=0, chunk_count=len(indexes), message_start_time=messages[0][1],
            message_end_time=messages[-1][1], channel_message_counts=counts)), pad)
    if chunk_index:
        summary += b"".join(frame(Opcode.CHUNK_INDEX, body(ci), pad) for ci in indexes)
    summary_start = len(out) if summary else 0
    out += summary
    out += frame(Opcode.FOOTER, body(Footer(summary_start=summary_start, summary_offset_start=0, summary_crc=0)))
    out += MAGIC
    path.write_bytes(bytes(out))


RAW_OPTIONS = list(itertools.product([True, False], repeat=5))


@pytest.mark.parametrize("pad", [0, 5])
@pytest.mark.parametrize("chunk_index,message_index,channels,schemas,statistics", RAW_OPTIONS)
def test_raw_layouts_read_back_exactly(tmp_path, chunk_index, message_index, channels, schemas, statistics, pad):
    messages = sample_messages(14)
    path = tmp_path / "raw.mcap"
    raw_file(path, messages, chunk_index=chunk_index, message_index=message_index, channels=channels,
             schemas=schemas, statistics=statistics, pad=pad)
    _check(path, messages)


def test_messages_without_any_channel_record_are_an_error_not_zero(tmp_path):
    """A chunk index and message index name channel 1 and 2, but no channel record exists anywhere."""
    messages = sample_messages(8)
    path = tmp_path / "orphan.mcap"
    raw_file(path, messages, chunk_index=True, message_index=True, channels=False, schemas=False,
             statistics=True, pad=0)
    data = bytearray(path.read_bytes())
    # turn the channel records inside the first chunk into unknown records (0x80): same sizes, CRC redone
    for ch in CHANNELS:
        at = data.index(frame(Opcode.CHANNEL, body(ch)))
        data[at:at + 1] = b"\x80"
    start = 8 + 9 + struct.unpack_from("<Q", data, 9)[0]    # the first chunk: after magic and header
    assert data[start] == Opcode.CHUNK
    length = struct.unpack_from("<Q", data, start + 9 + 16)[0]        # uncompressed size
    crc_at = start + 9 + 24
    records_at = crc_at + 4 + 4 + 8                                   # crc, compression "", records length
    struct.pack_into("<I", data, crc_at, zlib.crc32(bytes(data[records_at:records_at + length])))
    path.write_bytes(bytes(data))
    with BagReader(path) as r, pytest.raises(BagError, match="channel id 1.*neither the summary nor the chunks"):
        r.topics()
    with pytest.raises(BagError, match="cannot count"):
        info_report([path])
