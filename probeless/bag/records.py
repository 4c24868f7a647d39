"""MCAP records as the specification defines them, read leniently where it says readers must be lenient.

https://mcap.dev/spec: every record is ``opcode (uint8) | length (uint64) | body``. A record may be
longer than the fields a reader knows (padding, or fields added by a later version): the body is
cut at ``length`` and the fields are parsed from its start, so the extra bytes are skipped. Records
of an unknown opcode are skipped whole, in the data section and inside chunks. Chunk records are
decompressed (``""``/none, ``zstd``, ``lz4``; any other compression is refused by name) and their
CRC, when not 0, is checked against the uncompressed records.

Errors are :class:`RecordError`, which carries the offset of the record at fault (relative to
what was parsed: the file, or the chunk's uncompressed records); callers add the file name.
"""

from __future__ import annotations

import io
import struct
import zlib
from typing import Any, Iterator

import lz4.frame
import zstandard
from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import (
    Channel,
    Chunk,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    Message,
    MessageIndex,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)

from probeless.errors import BagError

MAGIC = b"\x89MCAP0\r\n"
PREFIX = struct.Struct("<BQ")            # opcode, record length
MESSAGE = struct.Struct("<HIQQ")         # channel id, sequence, log time, publish time
FOOTER_SIZE = PREFIX.size + 8 + 8 + 4    # a footer record without padding
COMPRESSIONS = ("none", "zstd", "lz4")   # "" in a file means none
_CLASSES = {Opcode.HEADER: Header, Opcode.FOOTER: Footer, Opcode.SCHEMA: Schema, Opcode.CHANNEL: Channel,
            Opcode.CHUNK: Chunk, Opcode.MESSAGE_INDEX: MessageIndex, Opcode.CHUNK_INDEX: ChunkIndex,
            Opcode.STATISTICS: Statistics, Opcode.METADATA: Metadata, Opcode.METADATA_INDEX: MetadataIndex,
            Opcode.SUMMARY_OFFSET: SummaryOffset, Opcode.DATA_END: DataEnd}


class RecordError(BagError):
    """A record that cannot be read; ``offset`` is where it starts, ``why`` what is wrong with it."""

    def __init__(self, offset: int, why: str):
        self.offset, self.why = offset, why
        super().__init__(f"record at byte {offset}: {why}")


class Unsupported(RecordError):
    """A valid record using a feature this reader refuses (a chunk compression it does not know)."""


def parse(opcode: int, body: Any, offset: int = 0) -> Any:
    """The record of ``opcode`` whose body is ``body``, fields read from its start (trailing bytes
    skipped), or None for an opcode this reader does not know. RecordError if the body is too short
    or malformed."""
    if opcode == Opcode.MESSAGE:
        return message(body, offset)
    cls = _CLASSES.get(opcode)
    if cls is None:
        return None
    try:
        return cls.read(ReadDataStream(io.BytesIO(body)))
    except Exception as exc:  # EndOfFile, UnicodeDecodeError, struct.error: a damaged body
        raise RecordError(offset, f"malformed {cls.__name__} record ({type(exc).__name__}: {exc})") from None


def message(body: Any, offset: int = 0) -> Message:
    """A message record from its body; ``data`` is a view of ``body`` (no copy)."""
    view = memoryview(body)
    if view.nbytes < MESSAGE.size:
        raise RecordError(offset, f"message record of {view.nbytes} bytes is shorter than its header")
    channel_id, sequence, log_time, publish_time = MESSAGE.unpack_from(view, 0)
    return Message(channel_id=channel_id, sequence=sequence, log_time=log_time, publish_time=publish_time,
                   data=view[MESSAGE.size:])


def split(data: Any, base: int = 0) -> Iterator[tuple[int, int, memoryview]]:
    """``(offset, opcode, body)`` of the records packed in ``data``; ``offset`` counts from ``base``.
    RecordError when a record runs past the end of ``data``."""
    view, pos = memoryview(data), 0
    size = view.nbytes
    while pos < size:
        if size - pos < PREFIX.size:
            raise RecordError(base + pos, f"{size - pos} byte(s) left, too few for a record")
        opcode, length = PREFIX.unpack_from(view, pos)
        end = pos + PREFIX.size + length
        if end > size:
            raise RecordError(base + pos, f"its length ({length} bytes) runs {end - size} byte(s) past the end")
        yield base + pos, opcode, view[pos + PREFIX.size:end]
        pos = end


def compression_name(chunk: Chunk) -> str:
    """The chunk's compression, ``"none"`` for the empty string."""
    return chunk.compression or "none"


def chunk_data(chunk: Chunk, offset: int = 0) -> bytes:
    """The uncompressed records of a chunk, CRC-checked; RecordError naming what is wrong."""
    name = compression_name(chunk)
    try:
        if name == "zstd":
            data = zstandard.ZstdDecompressor().decompress(chunk.data, max_output_size=chunk.uncompressed_size)
        elif name == "lz4":
            data = lz4.frame.decompress(chunk.data)
        elif name == "none":
            data = chunk.data
        else:
            raise Unsupported(offset, f"chunk compression {chunk.compression!r} is not supported "
                                      f"(supported: {', '.join(COMPRESSIONS)})")
    except RecordError:
        raise
    except Exception as exc:  # zstd/lz4 errors on damaged data
        raise RecordError(offset, f"chunk does not decompress ({name}: {exc})") from None
    if len(data) != chunk.uncompressed_size:
        raise RecordError(offset, f"chunk holds {len(data)} bytes uncompressed, its header says "
                                  f"{chunk.uncompressed_size}")
    if chunk.uncompressed_crc != 0:
        crc = zlib.crc32(data)
        if crc != chunk.uncompressed_crc:
            raise RecordError(offset, f"chunk CRC mismatch (stored 0x{chunk.uncompressed_crc:08x}, "
                                      f"computed 0x{crc:08x})")
    return data


def chunk_records(chunk: Chunk, offset: int = 0) -> list[Any]:
    """The schema, channel and message records of a chunk in order (other records skipped)."""
    data = chunk_data(chunk, offset)
    out = []
    try:
        for pos, opcode, body in split(data):
            if opcode in (Opcode.SCHEMA, Opcode.CHANNEL, Opcode.MESSAGE):
                out.append(parse(opcode, body, pos))
    except RecordError as exc:
        raise RecordError(offset, f"inside the chunk, {exc}") from None
    return out
