"""Read MCAP recordings: probeless ones, ones whose recorder was killed, and valid files of other writers.

A complete file is read through its summary (chunk, message and metadata indexes): opening it and
listing its topics decompresses nothing (:mod:`probeless.bag.layout`). A file without a usable
summary (the recorder was SIGKILLed, the disk filled up, another writer left indexes out, messages
sit outside chunks) is scanned record by record up to the last complete record
(:mod:`probeless.bag.scan`); :attr:`BagReader.truncated` and :attr:`BagReader.truncation_note` say
what was skipped. Records are read as the MCAP specification says (:mod:`probeless.bag.records`):
padding after known fields and unknown records are skipped. A chunk that fails its CRC stops the
scan there; in an indexed file :meth:`BagReader.messages` raises BagError when it reaches it, or
skips it and reports the messages lost through ``on_corrupt``.

Channels of other encodings than probeless' ``msgpack`` (cdr, ros1, json, protobuf, ...) are listed
by :meth:`BagReader.topics` with their counts; :meth:`BagReader.records` yields their raw messages.
"""

from __future__ import annotations

import heapq
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator

from mcap.opcode import Opcode
from mcap.records import Channel, Message, Schema

from probeless import wire
from probeless.bag.format import MESSAGE_ENCODING, PROFILE, unpack_payload
from probeless.bag.layout import Block, Layout, load_summary, read_at
from probeless.bag.records import COMPRESSIONS, MAGIC, RecordError, chunk_records, parse, split
from probeless.bag.scan import scan, take
from probeless.bag.stats import block_counts, index_stats
from probeless.errors import BagError, SchemaError
from probeless.messages.base import Message as ProbelessMessage


@dataclass(frozen=True)
class TopicInfo:
    """What a recording holds on one topic. ``bytes`` counts message payloads (before compression).

    ``message_encoding`` is the MCAP channel's (``msgpack`` for probeless topics); for a channel
    of another encoding ``type_name`` is its schema name and ``version`` 0."""

    topic: str
    type_name: str
    version: int
    count: int
    first_ns: int | None        # log time of the first message [ns]
    last_ns: int | None         # log time of the last message [ns]
    bytes: int
    message_encoding: str = MESSAGE_ENCODING
    schema_encoding: str = ""

    @property
    def rate_hz(self) -> float | None:
        """Mean message rate from the log times, None with fewer than two messages [Hz]."""
        if self.count < 2 or not self.last_ns or self.last_ns <= self.first_ns:
            return None
        return (self.count - 1) * 1e9 / (self.last_ns - self.first_ns)

    @property
    def foreign(self) -> bool:
        """True when the topic is not a probeless (msgpack) channel."""
        return self.message_encoding != MESSAGE_ENCODING


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


class BagReader:
    """Read one MCAP file: a probeless recording, a truncated copy of one, or any valid MCAP file."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        try:
            self._f = open(self.path, "rb")
        except FileNotFoundError:
            raise BagError(f"{self.path}: no such file") from None
        except OSError as exc:
            raise BagError(f"{self.path}: cannot open: {exc.strerror or exc}") from None
        try:
            self._open()
        except BaseException:
            self._f.close()
            raise

    def _open(self) -> None:
        self._size = os.fstat(self._f.fileno()).st_size
        if self._f.read(8) != MAGIC:
            raise BagError(f"{self.path} is not an MCAP file" + (" (it is empty)" if self._size == 0 else ""))
        self.profile = self.library = ""
        header = read_at(self._f, self._size, 8)
        if header is not None and header[0] == Opcode.HEADER:
            try:
                h = parse(*header, 8)
                self.profile, self.library = h.profile, h.library
            except RecordError:
                pass  # the scan reports the damage
        try:
            layout, problem = load_summary(self._f, self._size)
            if layout is None:
                layout = scan(self._f, self._size, problem)
        except RecordError as exc:
            raise BagError(f"{self.path}: {exc}") from None
        self._schemas, self._channels = layout.schemas, layout.channels
        self._chunks: list[Block] = layout.blocks
        self._metadata, self._stats, self._time_range = layout.metadata, layout.stats, layout.time_range
        self.truncation_note = layout.truncation_note
        self.truncated = bool(self.truncation_note)
        self.problems: list[str] = []  # chunks found corrupt while counting (a file without usable indexes)
        odd = sorted({b.compression for b in self._chunks} - set(COMPRESSIONS))
        if odd:
            at = next(b.offset for b in self._chunks if b.compression == odd[0])
            raise BagError(f"{self.path}: chunk compression {odd[0]!r} (chunk at byte {at}) is not supported "
                           f"(supported: {', '.join(COMPRESSIONS)})")

    # -- statistics ------------------------------------------------------------------------

    def _channel_stats(self) -> dict[int, list]:
        if self._stats is None and self.profile == PROFILE:  # the layout whose payload sizes the index gives
            self._stats = index_stats(self._f, self._chunks, self._channels, self._schemas)
        if self._stats is None:  # another writer or no message index: read every block once
            self._stats = {}
            found = Layout()
            for k in range(len(self._chunks)):
                try:
                    take(found, self._block_records(k), self._stats)
                except BagError as exc:
                    self.problems.append(f"{exc}: its messages are not counted")
            for sid, schema in found.schemas.items():
                self._schemas.setdefault(sid, schema)
            for cid, ch in found.channels.items():
                self._channels.setdefault(cid, ch)
        return self._stats

    def _type_of(self, ch: Channel) -> tuple[str, int]:
        schema = self._schemas.get(ch.schema_id)
        if ch.message_encoding != MESSAGE_ENCODING:
            return (schema.name if schema else ""), 0
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
        orphans = {cid: s[0] for cid, s in stats.items() if s[0] and cid not in self._channels}
        if orphans:
            what = ", ".join(f"{n} on channel id {cid}" for cid, n in sorted(orphans.items()))
            raise BagError(f"{self.path}: cannot count the messages per topic: {what}, whose channel record is "
                           "in neither the summary nor the chunks (the file is damaged or cut short)")
        for cid, ch in sorted(self._channels.items()):
            count, first, last, size = stats.get(cid, [0, None, None, 0])
            type_name, version = self._type_of(ch)
            prev = out.get(ch.topic)
            if prev is not None and prev.count:
                count, size = count + prev.count, size + prev.bytes
                first = prev.first_ns if first is None else min(first, prev.first_ns)
                last = prev.last_ns if last is None else max(last, prev.last_ns)
            schema = self._schemas.get(ch.schema_id)
            out[ch.topic] = TopicInfo(ch.topic, type_name, version, count, first, last, size,
                                      ch.message_encoding, schema.encoding if schema else "")
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

    def _block_records(self, k: int) -> list[Any]:
        """Schema, channel and message records of block ``k``; BagError naming file and offset."""
        b = self._chunks[k]
        try:
            if b.chunked:
                rec = read_at(self._f, self._size, b.offset)
                if rec is None or rec[0] != Opcode.CHUNK:
                    raise RecordError(b.offset, "no chunk record there")
                return chunk_records(parse(*rec, b.offset), b.offset)
            self._f.seek(b.offset)
            data = self._f.read(b.length)
            return [parse(op, body, pos) for pos, op, body in split(data, b.offset)
                    if op in (Opcode.SCHEMA, Opcode.CHANNEL, Opcode.MESSAGE)]
        except RecordError as exc:
            what = "chunk" if b.chunked else "record"
            raise BagError(f"{self.path}: {what} at byte {exc.offset} is corrupt ({exc.why})") from None

    def _lost(self, k: int, ids: set[int] | None) -> str:
        """How many of the wanted messages block ``k`` holds, from its message index if it has one."""
        counts = block_counts(self._f, self._chunks[k])
        if counts is None:
            return "an unknown number of messages"
        return f"{sum(n for cid, n in counts.items() if ids is None or cid in ids)} message(s)"

    def records(self, topics: str | Iterable[str] | None = None, start_ns: int | None = None,
                end_ns: int | None = None, *, in_file_order: bool = False,
                on_corrupt: Callable[[str], None] | None = None) -> Iterator[tuple[Channel, Message]]:
        """``(channel, message)`` of every MCAP message, any encoding, selected and ordered as in
        :meth:`messages`. A corrupt chunk raises BagError, or with ``on_corrupt`` is skipped and
        reported to it (one line naming the file, the offset and the messages lost)."""
        wanted = None if topics is None else {topics} if isinstance(topics, str) else set(topics)
        ids = None if wanted is None else {cid for cid, ch in self._channels.items() if ch.topic in wanted}
        blocks = [(c.start_ns, 0, k, 0, None) for k, c in enumerate(self._chunks)
                  if (ids is None or c.channels is None or c.channels & ids)
                  and (start_ns is None or c.end_ns >= start_ns) and (end_ns is None or c.start_ns < end_ns)]

        def selected(k: int) -> Iterator[tuple[int, Message]]:
            try:
                records = self._block_records(k)
            except BagError as exc:
                if on_corrupt is None:
                    raise
                on_corrupt(f"{exc}: skipped it and its {self._lost(k, ids)}")
                return
            for r in records:
                if isinstance(r, Channel):
                    self._channels.setdefault(r.id, r)
            for i, r in enumerate(records):
                if (isinstance(r, Message) and (ids is None or r.channel_id in ids)
                        and (start_ns is None or r.log_time >= start_ns)
                        and (end_ns is None or r.log_time < end_ns)):
                    yield i, r

        if in_file_order:
            for _, _, k, _, _ in sorted(blocks, key=lambda c: self._chunks[c[2]].offset):
                for _, r in selected(k):
                    yield self._channel(r), r
            return
        heapq.heapify(blocks)
        while blocks:
            t, kind, k, i, rec = heapq.heappop(blocks)
            if kind == 1:
                yield self._channel(rec), rec
                continue
            for i, r in selected(k):
                heapq.heappush(blocks, (r.log_time, 1, k, i, r))

    def messages(self, topics: str | Iterable[str] | None = None, start_ns: int | None = None,
                 end_ns: int | None = None, *, in_file_order: bool = False,
                 on_corrupt: Callable[[str], None] | None = None) -> Iterator[BagMessage]:
        """Messages in log-time order (file order among equal times), optionally only the given
        topics and log times in ``[start_ns, end_ns)``; ``in_file_order`` yields them in the order
        they were written instead (one chunk in memory at a time). BagError on reaching a message
        of another encoding than probeless' (see :meth:`records`); ``on_corrupt`` as there."""
        for ch, r in self.records(topics, start_ns, end_ns, in_file_order=in_file_order, on_corrupt=on_corrupt):
            yield self.message_of(ch, r)

    def _channel(self, r: Message) -> Channel:
        ch = self._channels.get(r.channel_id)
        if ch is None:
            raise BagError(f"{self.path}: message on unknown channel {r.channel_id}")
        return ch

    def schema_of(self, ch: Channel) -> Schema | None:
        """The schema record of a channel, None when it has none (schema id 0) or it is unknown."""
        return self._schemas.get(ch.schema_id)

    def message_of(self, ch: Channel, r: Message) -> BagMessage:
        """The BagMessage of a raw MCAP message on probeless channel ``ch``; BagError for another
        encoding or a malformed payload, naming file and topic."""
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
