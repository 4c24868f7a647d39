"""Where the messages of an MCAP file are: read from its summary section when that has what is needed.

The summary (schemas, channels, chunk indexes, statistics, metadata indexes) is used when its CRC
(if not 0) matches, every record in it parses, and it indexes every chunk (a file whose statistics
count messages but that has no chunk index, e.g. one written without chunks, has to be scanned).
Otherwise :func:`load_summary` returns None with the reason (empty when the file simply has no
usable summary, which is no damage) and :mod:`probeless.bag.scan` reads the data section.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass, field
from typing import Any, BinaryIO

from mcap.opcode import Opcode
from mcap.records import Channel, ChunkIndex, Metadata, MetadataIndex, Schema, Statistics

from probeless.bag.records import FOOTER_SIZE, MAGIC, PREFIX, RecordError, chunk_records, parse, split


@dataclass(frozen=True)
class Block:
    """A part of the data section that holds messages: one chunk record, or a run of records outside
    chunks (``chunked`` False: schemas, channels and messages written straight into the data section)."""

    offset: int                 # file offset of the first record
    length: int                 # bytes from offset (the chunk record, or the run of records)
    start_ns: int
    end_ns: int
    compression: str            # "none", "zstd", "lz4", ... ("none" outside chunks)
    chunked: bool = True
    channels: frozenset | None = None   # channel ids in the block, None = unknown
    index_offsets: tuple = ()           # (offset, length) of a chunk's message index block, () = none
    uncompressed_size: int = 0


@dataclass
class Layout:
    """What opening a file found: records that describe the messages, and where the messages are."""

    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    blocks: list[Block] = field(default_factory=list)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    stats: dict[int, list] | None = None          # channel id -> [count, first ns, last ns, payload bytes]
    time_range: tuple[int, int] | None = None
    truncation_note: str = ""                     # empty: the file is complete

    def register(self, record: Any) -> bool:
        """Keep ``record`` when it is a schema or a channel; False for any other record."""
        if isinstance(record, Schema):
            self.schemas[record.id] = record
        elif isinstance(record, Channel):
            self.channels[record.id] = record
        else:
            return False
        return True


def read_at(f: BinaryIO, size: int, offset: int) -> tuple[int, memoryview] | None:
    """(opcode, body) of the record at ``offset``, None when it does not fit in the file."""
    if offset < 0 or offset + PREFIX.size > size:
        return None
    f.seek(offset)
    opcode, length = PREFIX.unpack(f.read(PREFIX.size))
    if offset + PREFIX.size + length > size:
        return None
    return opcode, memoryview(f.read(length))


def load_summary(f: BinaryIO, size: int) -> tuple[Layout | None, str]:
    """The layout from the summary section, or (None, why it cannot be used; "" = the file has none)."""
    if size < len(MAGIC) * 2 + FOOTER_SIZE:
        return None, "the file has no footer"
    f.seek(size - len(MAGIC) - FOOTER_SIZE)
    tail = f.read(FOOTER_SIZE + len(MAGIC))
    opcode, length = PREFIX.unpack_from(tail, 0)
    if tail[-len(MAGIC):] != MAGIC or opcode != Opcode.FOOTER or length != FOOTER_SIZE - PREFIX.size:
        return None, "the footer at the end of the file is missing or damaged"
    footer = parse(opcode, tail[PREFIX.size:FOOTER_SIZE])
    footer_at = size - len(MAGIC) - FOOTER_SIZE
    if footer.summary_start == 0:
        return None, ""
    if not len(MAGIC) <= footer.summary_start <= footer_at:
        return None, f"the footer points to a summary at byte {footer.summary_start}, outside the file"
    f.seek(footer.summary_start)
    data = f.read(footer_at - footer.summary_start)
    if footer.summary_crc != 0:
        crc = zlib.crc32(tail[:FOOTER_SIZE - 4], zlib.crc32(data))
        if crc != footer.summary_crc:
            return None, f"the summary at byte {footer.summary_start} fails its CRC"
    try:
        records = [parse(op, body, pos) for pos, op, body in split(data, footer.summary_start)]
    except RecordError as exc:
        return None, f"the summary is damaged ({exc})"
    return _from_summary(f, size, footer.summary_start, [r for r in records if r is not None])


def _from_summary(f: BinaryIO, size: int, summary_start: int, records: list[Any]) -> tuple[Layout | None, str]:
    out = Layout()
    indexes: list[ChunkIndex] = []
    stats: Statistics | None = None
    for r in records:
        if out.register(r):
            continue
        if isinstance(r, ChunkIndex):
            indexes.append(r)
        elif isinstance(r, Statistics):
            stats = r
        elif isinstance(r, MetadataIndex):
            rec = read_at(f, size, r.offset)
            if rec is None or rec[0] != Opcode.METADATA:
                return None, f"the summary's metadata index points to byte {r.offset}, where no metadata is"
            try:
                meta: Metadata = parse(*rec, r.offset)
            except RecordError as exc:
                return None, f"the metadata the summary points to is damaged ({exc})"
            out.metadata[meta.name] = dict(meta.metadata)
    if stats is None and not indexes:
        return None, ""   # nothing to locate messages with: scan (not a damage)
    if stats is not None and stats.message_count and (not indexes or stats.chunk_count != len(indexes)):
        return None, ""   # messages outside chunks, or chunk indexes left out: scan
    for ci in sorted(indexes, key=lambda c: c.chunk_start_offset):
        if ci.chunk_start_offset + ci.chunk_length > summary_start:
            return None, f"the summary indexes a chunk at byte {ci.chunk_start_offset} beyond the data section"
        offs = ci.message_index_offsets
        out.blocks.append(Block(ci.chunk_start_offset, ci.chunk_length, ci.message_start_time,
                                ci.message_end_time, ci.compression or "none", True,
                                frozenset(offs) if offs else None,
                                (min(offs.values()), ci.message_index_length) if offs else (),
                                ci.uncompressed_size))
    if stats is not None and stats.message_count:
        out.time_range = (stats.message_start_time, stats.message_end_time)
    if _incomplete(out, stats):
        problem = _records_from_chunks(f, size, out, stats)
        if problem:
            return None, problem
    return out, ""


def _missing(out: Layout, stats: Statistics | None) -> set[int]:
    """Channel ids the chunk indexes or the statistics point to that the layout has no channel for."""
    wanted = set(stats.channel_message_counts) if stats is not None else set()
    for b in out.blocks:
        wanted |= b.channels or set()
    return wanted - set(out.channels)


def _incomplete(out: Layout, stats: Statistics | None) -> bool:
    """Whether channels or schemas the messages need may be only inside the chunks: a channel id
    indexed but not in the summary, a channel's schema missing, or chunks that do not say which
    channels they hold while the summary lists none (or fewer than its statistics count)."""
    if _missing(out, stats):
        return True
    if any(ch.schema_id and ch.schema_id not in out.schemas for ch in out.channels.values()):
        return True
    unindexed = any(b.channels is None for b in out.blocks)
    if not unindexed:
        return False
    return stats is None or not stats.channel_message_counts or stats.channel_count > len(out.channels)


def _records_from_chunks(f: BinaryIO, size: int, out: Layout, stats: Statistics | None) -> str:
    """Register the schema and channel records written inside the chunks (other writers may keep
    them out of the summary), reading only as many chunks as needed; "" or why the chunks cannot be read."""
    need_all = any(b.channels is None for b in out.blocks)
    for b in out.blocks:
        missing = _missing(out, stats)
        schemas_ok = all(not ch.schema_id or ch.schema_id in out.schemas for ch in out.channels.values())
        if not need_all and not missing and schemas_ok:
            break
        if not need_all and b.channels is not None and not (b.channels & missing) and schemas_ok:
            continue
        rec = read_at(f, size, b.offset)
        if rec is None or rec[0] != Opcode.CHUNK:
            return f"the summary indexes a chunk at byte {b.offset}, where no chunk is"
        try:
            for r in chunk_records(parse(*rec, b.offset), b.offset):
                if isinstance(r, (Schema, Channel)) and _new(out, r):
                    out.register(r)
        except RecordError as exc:
            return f"the chunk at byte {b.offset} that holds channel records is damaged ({exc.why})"
    return ""


def _new(out: Layout, r: Any) -> bool:
    """True when ``r`` (a schema or channel) is not registered yet; the summary's records win."""
    return r.id not in (out.schemas if isinstance(r, Schema) else out.channels)
