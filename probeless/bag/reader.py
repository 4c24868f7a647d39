"""Read probeless MCAP recordings, including ones whose recorder was killed before it finished.

A complete file is read through its summary (chunk, message and metadata indexes): opening it and
listing its topics decompresses nothing. A file without a readable summary (the recorder was
SIGKILLed, the disk filled up) is scanned record by record up to the end of its last complete
chunk; :attr:`BagReader.truncated` and :attr:`BagReader.truncation_note` say what was skipped.
A chunk that fails its CRC stops the scan there (or, in an indexed file, raises BagError when
:meth:`BagReader.messages` reaches it).
"""

from __future__ import annotations

import heapq
import io
import os
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Iterator

from mcap.data_stream import ReadDataStream, RecordBuilder
from mcap.opcode import Opcode
from mcap.reader import SeekingReader
from mcap.records import Channel, Chunk, Header, Message, MessageIndex, Metadata, Schema
from mcap.stream_reader import breakup_chunk

from probeless import wire
from probeless.bag.format import MESSAGE_ENCODING, unpack_payload
from probeless.errors import BagError, SchemaError
from probeless.messages.base import Message as ProbelessMessage

MAGIC = b"\x89MCAP0\r\n"
_PREFIX = 9                     # opcode (1) + record length (8)
_MESSAGE_OVERHEAD = 31          # prefix, channel id, sequence, log time, publish time


@dataclass(frozen=True)
class TopicInfo:
    """What a recording holds on one topic. ``bytes`` counts message payloads (before compression)."""

    topic: str
    type_name: str
    version: int
    count: int
    first_ns: int | None        # log time of the first message [ns]
    last_ns: int | None         # log time of the last message [ns]
    bytes: int

    @property
    def rate_hz(self) -> float | None:
        """Mean message rate from the log times, None with fewer than two messages [Hz]."""
        if self.count < 2 or not self.last_ns or self.last_ns <= self.first_ns:
            return None
        return (self.count - 1) * 1e9 / (self.last_ns - self.first_ns)


@dataclass(frozen=True)
class BagMessage:
    """One recorded message; ``frames`` = ``(topic, meta, buf0, ...)``, ready for :func:`wire.decode`."""

    topic: str
    type_name: str
    version: int
    log_time_ns: int
    publish_time_ns: int
    sequence: int
    frames: tuple


@dataclass(frozen=True)
class _Chunk:
    offset: int                 # file offset of the chunk record
    start_ns: int
    end_ns: int
    compression: str
    uncompressed_size: int
    channels: frozenset | None  # channel ids in the chunk, None = unknown
    index_offsets: tuple = ()   # (offset, length) of its message index block, () = none


def _record_size(record: Any) -> int:
    rb = RecordBuilder()
    record.write(rb)
    return rb.count


def _parse(data: bytes, opcode: int) -> Any:
    stream = ReadDataStream(io.BytesIO(data))
    cls = {Opcode.CHUNK: Chunk, Opcode.SCHEMA: Schema, Opcode.CHANNEL: Channel, Opcode.METADATA: Metadata,
           Opcode.HEADER: Header, Opcode.MESSAGE_INDEX: MessageIndex}[opcode]
    return cls.read(stream)


class BagReader:
    """Read one MCAP file written by :class:`~probeless.bag.writer.BagWriter` (or a truncated copy)."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        try:
            self._f = open(self.path, "rb")
        except FileNotFoundError:
            raise BagError(f"{self.path}: no such file") from None
        except OSError as exc:
            raise BagError(f"{self.path}: cannot open: {exc.strerror or exc}") from None
        self._size = os.fstat(self._f.fileno()).st_size
        if self._f.read(8) != MAGIC:
            self._f.close()
            raise BagError(f"{self.path} is not an MCAP file" + (" (it is empty)" if self._size == 0 else ""))
        self.truncated = False
        self.truncation_note = ""
        self.profile = self.library = ""
        self._schemas: dict[int, Schema] = {}
        self._channels: dict[int, Channel] = {}
        self._chunks: list[_Chunk] = []
        self._metadata: dict[str, dict[str, str]] = {}
        self._stats: dict[int, list] | None = None  # channel id -> [count, first, last, bytes]
        self._time_range: tuple[int, int] | None = None
        self._summary_damaged = False
        header = self._record_at(8)
        if header and header[0] == Opcode.HEADER:
            h = _parse(header[1], Opcode.HEADER)
            self.profile, self.library = h.profile, h.library
        if not self._load_summary():
            self._scan()

    # -- opening ---------------------------------------------------------------------------

    def _record_at(self, offset: int) -> tuple[int, bytes] | None:
        """(opcode, body) of the record at ``offset``, None if it does not fit in the file."""
        self._f.seek(offset)
        head = self._f.read(_PREFIX)
        if len(head) < _PREFIX:
            return None
        opcode, length = struct.unpack("<BQ", head)
        if offset + _PREFIX + length > self._size:
            return None
        return opcode, self._f.read(length)

    def _load_summary(self) -> bool:
        try:
            self._f.seek(0)
            summary = SeekingReader(self._f).get_summary()
        except Exception:  # no footer, garbage footer, ... -> scan
            self._summary_damaged = True
            return False
        if summary is None or (not summary.chunk_indexes and (summary.statistics is None
                                                              or summary.statistics.message_count)):
            return False
        self._schemas, self._channels = dict(summary.schemas), dict(summary.channels)
        for ci in sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset):
            offs = ci.message_index_offsets
            self._chunks.append(_Chunk(
                ci.chunk_start_offset, ci.message_start_time, ci.message_end_time, ci.compression,
                ci.uncompressed_size, frozenset(offs) if offs else None,
                (min(offs.values()), ci.message_index_length) if offs else ()))
        for mi in summary.metadata_indexes:
            rec = self._record_at(mi.offset)
            if rec is None or rec[0] != Opcode.METADATA:
                raise BagError(f"{self.path}: metadata record at byte {mi.offset} is missing")
            meta = _parse(rec[1], Opcode.METADATA)
            self._metadata[meta.name] = dict(meta.metadata)
        if summary.statistics is not None and summary.statistics.message_count:
            self._time_range = (summary.statistics.message_start_time, summary.statistics.message_end_time)
        return True

    def _scan(self) -> None:
        """Read records from the start up to the last complete one (file without summary)."""
        pos, stats, clean_end = 8, {}, False
        self._f.seek(pos)
        while True:
            head = self._f.read(_PREFIX)
            if len(head) == 0:
                break
            if len(head) < _PREFIX:
                self._truncate(f"a partial record at byte {pos} was skipped")
                break
            opcode, length = struct.unpack("<BQ", head)
            if pos + _PREFIX + length > self._size:
                what = "chunk" if opcode == Opcode.CHUNK else "record"
                self._truncate(f"the last partial {what} ({self._size - pos} of {_PREFIX + length} bytes)"
                               " was skipped")
                break
            body = self._f.read(length)
            try:
                if opcode in (Opcode.DATA_END, Opcode.FOOTER):
                    clean_end = True
                    break
                if opcode == Opcode.MESSAGE:
                    raise BagError(f"{self.path}: messages outside chunks are not supported "
                                   "(probeless recordings are always chunked)")
                if opcode == Opcode.CHUNK:
                    chunk = _parse(body, opcode)
                    ids = self._take_records(breakup_chunk(chunk, validate_crc=True), stats)
                    self._chunks.append(_Chunk(pos, chunk.message_start_time, chunk.message_end_time,
                                               chunk.compression, chunk.uncompressed_size, frozenset(ids)))
                elif opcode in (Opcode.SCHEMA, Opcode.CHANNEL):
                    self._take_records([_parse(body, opcode)], stats)
                elif opcode == Opcode.METADATA:
                    meta = _parse(body, opcode)
                    self._metadata[meta.name] = dict(meta.metadata)
            except BagError:
                raise
            except Exception as exc:
                self._truncate(f"the record at byte {pos} is corrupt ({type(exc).__name__}: {exc}); "
                               f"reading stopped there, {self._size - pos} bytes were skipped")
                break
            pos += _PREFIX + length
        if not clean_end and not self.truncated:
            self._truncate("the file has no summary (the recorder did not finish it)")
        elif clean_end and self._summary_damaged:
            self._truncate("the data is complete, only the summary at the end is missing or damaged")
        self._stats = stats

    def _truncate(self, why: str) -> None:
        self.truncated = True
        self.truncation_note = f"file ends after {len(self._chunks)} complete chunk(s); {why}"

    def _take_records(self, records: Iterable[Any], stats: dict[int, list]) -> set[int]:
        ids = set()
        for r in records:
            if isinstance(r, Schema):
                self._schemas[r.id] = r
            elif isinstance(r, Channel):
                self._channels[r.id] = r
            elif isinstance(r, Message):
                ids.add(r.channel_id)
                s = stats.setdefault(r.channel_id, [0, r.log_time, r.log_time, 0])
                s[0] += 1
                s[1], s[2] = min(s[1], r.log_time), max(s[2], r.log_time)
                s[3] += len(r.data)
        return ids

    # -- statistics ------------------------------------------------------------------------

    def _index_stats(self) -> dict[int, list] | None:
        """Per-channel stats from the message indexes; payload sizes from the offsets between
        messages, minus the schema/channel records the writer puts right before a channel's
        first message. None when a chunk has no index."""
        entries = []   # (chunk number, offset in chunk, channel id, log time)
        for k, c in enumerate(self._chunks):
            if not c.index_offsets:
                return None
            self._f.seek(c.index_offsets[0])
            block, p = self._f.read(c.index_offsets[1]), 0
            while p + _PREFIX <= len(block):
                opcode, length = struct.unpack_from("<BQ", block, p)
                if opcode == Opcode.MESSAGE_INDEX:
                    mi = _parse(block[p + _PREFIX:p + _PREFIX + length], opcode)
                    entries.extend((k, off, mi.channel_id, t) for t, off in mi.records)
                p += _PREFIX + length
        entries.sort()
        stats: dict[int, list] = {}
        sizes = [0] * len(entries)
        seen_schemas: set[int] = set()
        for i, (k, off, cid, t) in enumerate(entries):
            nxt = entries[i + 1] if i + 1 < len(entries) else None
            end = nxt[1] if nxt is not None and nxt[0] == k else self._chunks[k].uncompressed_size
            sizes[i] = end - off - _MESSAGE_OVERHEAD
            if cid not in stats:
                stats[cid] = [0, t, t, 0]
                ch = self._channels.get(cid)
                reg = _record_size(ch) if ch is not None else 0
                if ch is not None and ch.schema_id in self._schemas and ch.schema_id not in seen_schemas:
                    seen_schemas.add(ch.schema_id)
                    reg += _record_size(self._schemas[ch.schema_id])
                first_in_chunk = i == 0 or entries[i - 1][0] != k
                excess = reg - (off if first_in_chunk else 0)
                if i > 0 and excess > 0:
                    sizes[i - 1] -= excess
        for (_, _, cid, t), size in zip(entries, sizes):
            s = stats[cid]
            s[0] += 1
            s[1], s[2] = min(s[1], t), max(s[2], t)
            s[3] += max(size, 0)
        return stats

    def _channel_stats(self) -> dict[int, list]:
        if self._stats is None:
            self._stats = self._index_stats()
        if self._stats is None:  # no message index: read every chunk once
            self._stats = {}
            for c in self._chunks:
                self._take_records(self._chunk_records(c), self._stats)
        return self._stats

    def _type_of(self, ch: Channel) -> tuple[str, int]:
        schema = self._schemas.get(ch.schema_id)
        type_name = ch.metadata.get("type") or (schema.name if schema else "")
        try:
            version = int(ch.metadata.get("version", "0"))
        except ValueError:
            version = 0
        return type_name, version

    def topics(self) -> dict[str, TopicInfo]:
        """Every topic with its type, message count, log time range and payload bytes, by name."""
        out: dict[str, TopicInfo] = {}
        stats = self._channel_stats()
        for cid, ch in sorted(self._channels.items()):
            count, first, last, size = stats.get(cid, [0, None, None, 0])
            type_name, version = self._type_of(ch)
            prev = out.get(ch.topic)
            if prev is not None and prev.count:
                count, size = count + prev.count, size + prev.bytes
                first = prev.first_ns if first is None else min(first, prev.first_ns)
                last = prev.last_ns if last is None else max(last, prev.last_ns)
            out[ch.topic] = TopicInfo(ch.topic, type_name, version, count, first, last, size)
        return out

    def metadata(self) -> dict[str, dict[str, str]]:
        """Metadata records by name (a later record of the same name wins)."""
        return {name: dict(data) for name, data in self._metadata.items()}

    @property
    def compression(self) -> set[str]:
        """Compressions of the chunks read: ``{"lz4"}``, ``{"zstd"}``, ``{"none"}``, ..."""
        return {c.compression or "none" for c in self._chunks}

    @property
    def start_ns(self) -> int | None:
        """Log time of the first message [ns], None when there is none."""
        return self._range()[0]

    @property
    def end_ns(self) -> int | None:
        """Log time of the last message [ns], None when there is none."""
        return self._range()[1]

    def _range(self) -> tuple[int | None, int | None]:
        if self._time_range is None:
            stats = [s for s in self._channel_stats().values() if s[0]]
            if not stats:
                return None, None
            self._time_range = (min(s[1] for s in stats), max(s[2] for s in stats))
        return self._time_range

    # -- messages --------------------------------------------------------------------------

    def _chunk_records(self, c: _Chunk) -> list[Any]:
        rec = self._record_at(c.offset)
        try:
            if rec is None or rec[0] != Opcode.CHUNK:
                raise ValueError("no chunk record there")
            return breakup_chunk(_parse(rec[1], Opcode.CHUNK), validate_crc=True)
        except Exception as exc:
            raise BagError(f"{self.path}: chunk at byte {c.offset} is corrupt "
                           f"({type(exc).__name__}: {exc})") from None

    def messages(self, topics: str | Iterable[str] | None = None, start_ns: int | None = None,
                 end_ns: int | None = None, *, in_file_order: bool = False) -> Iterator[BagMessage]:
        """Messages in log-time order (file order among equal times), optionally only the given
        topics and log times in ``[start_ns, end_ns)``; ``in_file_order`` yields them in the order
        they were written instead (one chunk in memory at a time)."""
        wanted = None if topics is None else {topics} if isinstance(topics, str) else set(topics)
        ids = None if wanted is None else {cid for cid, ch in self._channels.items() if ch.topic in wanted}
        chunks = [(c.start_ns, 0, k, 0, None) for k, c in enumerate(self._chunks)
                  if (ids is None or c.channels is None or c.channels & ids)
                  and (start_ns is None or c.end_ns >= start_ns) and (end_ns is None or c.start_ns < end_ns)]

        def selected(k: int) -> Iterator[tuple[int, Message]]:
            for i, r in enumerate(self._chunk_records(self._chunks[k])):
                if (isinstance(r, Message) and (ids is None or r.channel_id in ids)
                        and (start_ns is None or r.log_time >= start_ns)
                        and (end_ns is None or r.log_time < end_ns)):
                    yield i, r

        if in_file_order:
            for _, _, k, _, _ in sorted(chunks, key=lambda c: self._chunks[c[2]].offset):
                for _, r in selected(k):
                    yield self._message(r)
            return
        heapq.heapify(chunks)
        while chunks:
            t, kind, k, i, rec = heapq.heappop(chunks)
            if kind == 1:
                yield self._message(rec)
                continue
            for i, r in selected(k):
                heapq.heappush(chunks, (r.log_time, 1, k, i, r))

    def _message(self, r: Message) -> BagMessage:
        ch = self._channels.get(r.channel_id)
        if ch is None:
            raise BagError(f"{self.path}: message on unknown channel {r.channel_id}")
        if ch.message_encoding != MESSAGE_ENCODING:
            raise BagError(f"{self.path}: topic {ch.topic!r} is encoded as {ch.message_encoding!r}, "
                           f"not as a probeless recording ({MESSAGE_ENCODING!r})")
        try:
            parts = unpack_payload(r.data)
        except BagError as exc:
            raise BagError(f"{self.path}: topic {ch.topic!r}: {exc}") from None
        type_name, version = self._type_of(ch)
        return BagMessage(ch.topic, type_name, version, r.log_time, r.publish_time, r.sequence,
                          (ch.topic.encode(), *parts))

    def decode(self, msg: BagMessage) -> ProbelessMessage:
        """The typed message of a recorded one; BagError naming topic and file if it does not fit
        this build (unknown type, other schema version, malformed)."""
        try:
            return wire.decode(msg.frames)[2]
        except SchemaError as exc:
            raise BagError(f"{self.path}: topic {msg.topic!r}: {exc}") from None

    def close(self) -> None:
        """Close the file."""
        self._f.close()

    def __enter__(self) -> BagReader:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
