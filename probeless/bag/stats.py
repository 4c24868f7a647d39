"""Per-channel message statistics from the message indexes that follow each chunk (nothing decompressed).

Counts and log times are exact. Payload sizes come from the offsets between messages in the
chunk minus the record overhead and the schema/channel records a writer puts right before a
channel's first message: exact for probeless' and the ``mcap`` package's layout, approximate for
files whose chunks hold other records between messages (padding, attachments of other writers).
"""

from __future__ import annotations

from typing import Any, BinaryIO

from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import Channel, MessageIndex, Schema

from probeless.bag.layout import Block
from probeless.bag.records import RecordError, parse, split

MESSAGE_OVERHEAD = 31          # record prefix, channel id, sequence, log time, publish time


def _record_size(record: Any) -> int:
    rb = RecordBuilder()
    record.write(rb)
    return rb.count


def message_indexes(f: BinaryIO, block: Block) -> list[MessageIndex] | None:
    """The message index records of a chunk, None when it has none or they are damaged."""
    if not block.index_offsets:
        return None
    f.seek(block.index_offsets[0])
    data = f.read(block.index_offsets[1])
    if len(data) != block.index_offsets[1]:
        return None
    try:
        return [parse(op, body, pos) for pos, op, body in split(data, block.index_offsets[0])
                if op == Opcode.MESSAGE_INDEX]
    except RecordError:
        return None


def block_counts(f: BinaryIO, block: Block) -> dict[int, int] | None:
    """Messages per channel id in a chunk according to its message index (None without one)."""
    indexes = message_indexes(f, block)
    if indexes is None:
        return None
    out: dict[int, int] = {}
    for mi in indexes:
        out[mi.channel_id] = out.get(mi.channel_id, 0) + len(mi.records)
    return out


def index_stats(f: BinaryIO, blocks: list[Block], channels: dict[int, Channel],
                schemas: dict[int, Schema]) -> dict[int, list] | None:
    """channel id -> [count, first log time, last log time, payload bytes]; None when a block has
    no usable message index (the caller then reads the blocks)."""
    entries = []   # (block number, offset in chunk, channel id, log time)
    for k, b in enumerate(blocks):
        indexes = message_indexes(f, b) if b.chunked else None
        if indexes is None:
            return None
        entries.extend((k, off, mi.channel_id, t) for mi in indexes for t, off in mi.records)
    entries.sort()
    stats: dict[int, list] = {}
    sizes = [0] * len(entries)
    seen_schemas: set[int] = set()
    for i, (k, off, cid, t) in enumerate(entries):
        nxt = entries[i + 1] if i + 1 < len(entries) else None
        end = nxt[1] if nxt is not None and nxt[0] == k else blocks[k].uncompressed_size
        sizes[i] = end - off - MESSAGE_OVERHEAD
        if cid not in stats:
            stats[cid] = [0, t, t, 0]
            ch = channels.get(cid)
            reg = _record_size(ch) if ch is not None else 0
            if ch is not None and ch.schema_id in schemas and ch.schema_id not in seen_schemas:
                seen_schemas.add(ch.schema_id)
                reg += _record_size(schemas[ch.schema_id])
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
