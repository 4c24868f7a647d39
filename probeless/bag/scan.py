"""Linear scan of an MCAP data section: for files without a usable summary, cut or damaged files.

Records are read from the start: chunks are decompressed once (their messages counted), messages
outside chunks are read too (grouped into blocks of consecutive records that
:meth:`~probeless.bag.reader.BagReader.messages` reads again), unknown records are skipped. The
scan stops at the data end record, at the end of the file, or at the first record that is cut
short or corrupt (a chunk failing its CRC included); what was valid before it stays readable and
``Layout.truncation_note`` says what was skipped, with the number of valid bytes.
"""

from __future__ import annotations

from typing import Any, BinaryIO

from mcap.opcode import Opcode
from mcap.records import Message

from probeless.bag.layout import Block, Layout
from probeless.bag.records import (
    PREFIX,
    RecordError,
    Unsupported,
    chunk_records,
    compression_name,
    message,
    parse,
)

LOOSE_BLOCK = 4 << 20   # bytes of records outside chunks read back at once


def take(out: Layout, records: list[Any], stats: dict[int, list]) -> set[int]:
    """Register schemas and channels, count messages into ``stats``; the channel ids of the messages."""
    ids = set()
    for r in records:
        if out.register(r):
            continue
        if isinstance(r, Message):
            ids.add(r.channel_id)
            s = stats.setdefault(r.channel_id, [0, r.log_time, r.log_time, 0])
            s[0] += 1
            s[1], s[2] = min(s[1], r.log_time), max(s[2], r.log_time)
            s[3] += len(r.data)
    return ids


class _Loose:
    """A run of records outside chunks that holds messages."""

    def __init__(self, offset: int):
        self.offset, self.end, self.ids = offset, offset, set()
        self.start_ns = self.end_ns = None

    def add(self, m: Message, end: int) -> None:
        self.end = end
        self.ids.add(m.channel_id)
        self.start_ns = m.log_time if self.start_ns is None else min(self.start_ns, m.log_time)
        self.end_ns = m.log_time if self.end_ns is None else max(self.end_ns, m.log_time)

    def block(self) -> Block:
        return Block(self.offset, self.end - self.offset, self.start_ns, self.end_ns, "none", False,
                     frozenset(self.ids))


def scan(f: BinaryIO, size: int, summary_problem: str = "") -> Layout:
    """The layout of the file ``f`` of ``size`` bytes, read record by record after the magic."""
    out, stats = Layout(), {}
    pos, why, clean = 8, "", False
    loose: _Loose | None = None
    f.seek(pos)
    while True:
        head = f.read(PREFIX.size)
        if not head:
            break
        if len(head) < PREFIX.size:
            why = f"a partial record at byte {pos} ({len(head)} bytes) was skipped"
            break
        opcode, length = PREFIX.unpack(head)
        end = pos + PREFIX.size + length
        if end > size:
            what = "chunk" if opcode == Opcode.CHUNK else "record"
            why = (f"the last partial {what} at byte {pos} ({size - pos} of {PREFIX.size + length} bytes) "
                   "was skipped (the file is cut short, or the record's length is corrupt)")
            break
        body = memoryview(f.read(length))
        if opcode in (Opcode.DATA_END, Opcode.FOOTER):
            clean = True
            break
        try:
            if opcode == Opcode.CHUNK:
                if loose is not None:
                    out.blocks.append(loose.block())
                    loose = None
                chunk = parse(opcode, body, pos)
                ids = take(out, chunk_records(chunk, pos), stats)
                out.blocks.append(Block(pos, end - pos, chunk.message_start_time, chunk.message_end_time,
                                        compression_name(chunk), True, frozenset(ids), (), chunk.uncompressed_size))
            elif opcode == Opcode.MESSAGE:
                m = message(body, pos)
                take(out, [m], stats)
                if loose is None or end - loose.offset > LOOSE_BLOCK:
                    if loose is not None:
                        out.blocks.append(loose.block())
                    loose = _Loose(pos)
                loose.add(m, end)
            elif opcode in (Opcode.SCHEMA, Opcode.CHANNEL):
                take(out, [parse(opcode, body, pos)], stats)
            elif opcode == Opcode.METADATA:
                meta = parse(opcode, body, pos)
                out.metadata[meta.name] = dict(meta.metadata)
        except Unsupported:
            raise
        except RecordError as exc:
            why = f"the record at byte {pos} is corrupt ({exc.why}); reading stopped there"
            break
        pos = end
    if loose is not None:
        out.blocks.append(loose.block())
    out.stats = stats
    out.truncation_note = _note(out, pos, size, why, clean, summary_problem)
    return out


def _note(out: Layout, pos: int, size: int, why: str, clean: bool, summary_problem: str) -> str:
    chunks = sum(1 for b in out.blocks if b.chunked)
    if clean and not why:
        if not summary_problem:
            return ""
        return (f"file ends after {chunks} complete chunk(s); the data is complete, only the summary at "
                f"the end is missing or damaged ({summary_problem})")
    if not why:
        why = "the file has no summary (the recorder did not finish it)"
    return f"file ends after {chunks} complete chunk(s) ({pos} of {size} bytes valid); {why}"
