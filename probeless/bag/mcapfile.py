"""A chunked MCAP file whose chunks are compressed and written by a background thread.

Records, indexes, statistics, summary, summary offsets, footer and CRCs are those of the ``mcap``
package's Writer with its defaults (all indexes, repeated schemas and channels, chunk CRCs, summary
CRC, no data-section CRC): a finished file is byte for byte what that Writer makes of the same
messages. What differs is the path of a message: :class:`~probeless.bag.chunks.ChunkBuffer` builds
the chunk in place, and a full chunk goes to a writer thread that computes its CRC, compresses it
and writes it (:class:`~probeless.bag.directio.AppendFile`); all three release the GIL, so the
recording thread keeps copying messages meanwhile. ``buffers`` chunk buffers circulate (one
filling, the others queued or being written): when all are busy, :meth:`McapFile.add_message`
waits, which is the backpressure. A chunk is in the file once written; :meth:`McapFile.flush`
waits for that.
"""

from __future__ import annotations

import queue
import threading
import zlib
from collections import defaultdict
from typing import Any, BinaryIO, Mapping, Sequence

from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (
    Channel,
    DataEnd,
    Footer,
    Header,
    McapRecord,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)
from mcap.writer import MCAP0_MAGIC

from probeless.bag.chunks import COMPRESSIONS, ChunkBuffer, encode_chunk
from probeless.bag.directio import AppendFile


def record_bytes(*records: McapRecord) -> bytes:
    """The serialized records, back to back."""
    builder = RecordBuilder()
    for r in records:
        r.write(builder)
    return builder.end()


class McapFile:
    """Writes one MCAP file on the empty file ``file`` (not closed here), bypassing the page cache where
    the file system allows and ``direct_io`` (:mod:`probeless.bag.directio`)."""

    def __init__(self, file: BinaryIO, *, compression: str, chunk_size: int, profile: str, library: str,
                 buffers: int = 3, direct_io: bool = True):
        if compression not in COMPRESSIONS:
            raise ValueError(f"compression {compression!r} not in {COMPRESSIONS}")
        self._compression, self._chunk_size = compression, int(chunk_size)
        capacity = min(self._chunk_size + (1 << 16), 1 << 20)  # buffers grow to what the chunks need
        self._out = AppendFile(file.fileno(), direct=direct_io, capacity=capacity)
        self._free: queue.Queue[ChunkBuffer] = queue.Queue()
        for _ in range(max(2, buffers)):
            self._free.put(ChunkBuffer(capacity))
        self._todo: queue.Queue[Any] = queue.Queue()
        self._chunk = self._free.get()
        self.schemas: dict[int, Schema] = {}
        self.channels: dict[int, Channel] = {}
        self.stats = Statistics(message_count=0, schema_count=0, channel_count=0, attachment_count=0,
                                metadata_count=0, chunk_count=0, message_start_time=0, message_end_time=0,
                                channel_message_counts=defaultdict(int))
        # written by the writer thread only
        self.written_raw = 0  # uncompressed bytes of the chunks written
        self._chunk_indexes: list = []
        self._metadata_indexes: list[MetadataIndex] = []
        self._error: Exception | None = None
        self.submitted_raw = 0  # uncompressed bytes of the chunks handed to the thread (node thread only)
        self._out.write([MCAP0_MAGIC, record_bytes(Header(profile=profile, library=library))])
        self._thread = threading.Thread(target=self._run, name="probeless-bag-writer", daemon=True)
        self._thread.start()

    # -- writer thread ---------------------------------------------------------------------------

    def _run(self) -> None:
        while True:
            item = self._todo.get()
            try:
                if item is None:
                    return
                if self._error is None:
                    self._write_item(item)
            except Exception as exc:  # kept for the recording thread, which raises it
                self._error = exc.with_traceback(None)  # the frames would pin views of a reused buffer
            finally:
                if isinstance(item, ChunkBuffer):
                    self.written_raw += item.size
                    item.reset()
                    self._free.put(item)
                self._todo.task_done()

    def _write_item(self, item: Any) -> None:
        if isinstance(item, ChunkBuffer):
            parts, entry = encode_chunk(item, self._compression, self._out.pos)
            self._out.write(parts)
            del parts  # no view of the buffer may outlive the write: it is reused
            self._chunk_indexes.append(entry)
        else:
            name, data = item
            self._metadata_indexes.append(MetadataIndex(offset=self._out.pos, length=len(data), name=name))
            self._out.write([data])

    # -- recording thread ------------------------------------------------------------------------

    def _check(self) -> None:
        if self._error is not None:
            raise self._error

    @property
    def direct_io(self) -> bool:
        """Whether the file is written without the page cache."""
        return self._out.direct

    @property
    def written(self) -> int:
        """Bytes in the file."""
        return self._out.pos

    @property
    def pending(self) -> int:
        """Uncompressed bytes recorded but not yet written: the chunk in progress and queued chunks."""
        return self.submitted_raw - self.written_raw + self._chunk.size

    def register(self, schema: Schema | None, channel: Channel) -> None:
        """Add a channel (and its schema when new); both go into the chunk in progress, like mcap's Writer."""
        if schema is not None:
            self.schemas[schema.id] = schema
            self.stats.schema_count += 1
            self._add_record(schema)
        self.channels[channel.id] = channel
        self.stats.channel_count += 1
        self._add_record(channel)

    def _add_record(self, record: McapRecord) -> None:
        self._chunk.add_record(record_bytes(record))
        if self._chunk.size > self._chunk_size:
            self._submit()  # as mcap's Writer does: a chunk may end with a schema or channel record

    def add_message(self, channel_id: int, log_time: int, publish_time: int, sequence: int,
                    frames: Sequence[Any]) -> int:
        """Record one message (payload = the msgpack framing of ``frames``); returns the payload size.
        Raises the writer thread's OSError, if it had one."""
        self._check()
        st = self.stats
        payload = self._chunk.add_message(channel_id, sequence, log_time, publish_time, frames)
        if st.message_count == 0:
            st.message_start_time = st.message_end_time = log_time
        else:
            st.message_start_time = min(st.message_start_time, log_time)
            st.message_end_time = max(st.message_end_time, log_time)
        st.message_count += 1
        st.channel_message_counts[channel_id] += 1
        if self._chunk.size > self._chunk_size:
            self._submit()
        return payload

    def _submit(self) -> None:
        if self._chunk.messages:
            self.stats.chunk_count += 1
            self.submitted_raw += self._chunk.size
            self._todo.put(self._chunk)
            self._chunk = self._free.get()

    def add_metadata(self, name: str, data: Mapping[str, str]) -> None:
        """Write a metadata record after everything recorded so far (the chunk in progress stays open)."""
        self._check()
        self.stats.metadata_count += 1
        self._todo.put((name, record_bytes(Metadata(name=name, metadata=dict(data)))))

    def drain(self) -> None:
        """Wait until everything handed to the writer thread is written (the chunk in progress stays open)."""
        self._todo.join()
        self._check()

    def flush(self) -> None:
        """Finish the chunk in progress and wait until everything is written to the file."""
        self._submit()
        self.drain()

    def finish(self) -> None:
        """Write the last chunk, the summary and the footer. Stops the writer thread, also on error."""
        try:
            self.flush()
        finally:
            self._todo.put(None)
            self._thread.join()
        self._out.write([record_bytes(DataEnd(data_section_crc=0))])
        summary_start = self._out.pos
        groups = [(Opcode.SCHEMA, list(self.schemas.values())), (Opcode.CHANNEL, list(self.channels.values())),
                  (Opcode.STATISTICS, [self.stats]), (Opcode.CHUNK_INDEX, self._chunk_indexes),
                  (Opcode.ATTACHMENT_INDEX, []), (Opcode.METADATA_INDEX, self._metadata_indexes)]
        summary, offsets = bytearray(), []
        for opcode, records in groups:
            data = record_bytes(*records)
            offsets.append(SummaryOffset(group_opcode=opcode, group_start=summary_start + len(summary),
                                         group_length=len(data)))
            summary += data
        offsets_start = summary_start + len(summary)
        summary += record_bytes(*offsets)
        footer = Footer(summary_start=summary_start, summary_offset_start=offsets_start, summary_crc=0)
        head = record_bytes(footer)[:-4]  # the footer up to its CRC field, which the CRC covers
        footer.summary_crc = zlib.crc32(head, zlib.crc32(summary))
        self._out.write([summary, record_bytes(footer), MCAP0_MAGIC])
        self._out.close()
