"""The in-place chunk writer against the ``mcap`` package: byte-identical files, its reader, errors."""

from __future__ import annotations

import errno
import io
import json

import msgpack
import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer
from message_examples import examples

from probeless import wire
from probeless.bag import directio
from probeless.bag.chunks import ChunkBuffer, payload_size
from probeless.bag.format import MESSAGE_ENCODING, PROFILE, SCHEMA_ENCODING, pack_payload, peek
from probeless.bag.reader import BagReader
from probeless.bag.schema import json_schema
from probeless.bag.writer import BagWriter, split_paths
from probeless.errors import BagError
from probeless.messages import Header, Image
from probeless.messages.base import lookup

T0 = 1_700_000_000_000_000_000
MCAP_COMPRESSION = {"none": CompressionType.NONE, "lz4": CompressionType.LZ4, "zstd": CompressionType.ZSTD}


def image(i: int, size=(48, 64)) -> Image:
    data = np.random.default_rng(i).integers(0, 256, (*size, 3), dtype=np.uint8)
    return Image(Header(T0 + i, "cam", i), data, "rgb8")


def stream():
    """Wire frames of every example type, 4 rounds, plus images of 9 KB .. 2.3 MB (chunk buffers grow)."""
    ex, items, t = examples(), [], T0
    for i in range(4):
        for name, msg in ex.items():
            items.append((wire.encode(f"rec/{name}", msg, "p", t - 5, seq=i), t))
            t += 1000
        items.append((wire.encode("cam", image(i, (48 << i, 64 << i)), "p", t, seq=i), t - 3))  # log times not sorted
    return items


def mcap_reference(items, compression: str, chunk_size: int, library: str) -> bytes:
    """The same recording made by the mcap package's own Writer from pack_payload bytes."""
    buf = io.BytesIO()
    w = Writer(buf, chunk_size=chunk_size, compression=MCAP_COMPRESSION[compression], enable_crcs=True)
    w.start(profile=PROFILE, library=library)
    w.add_metadata("site", {"room": "lab"})
    channels, schemas = {}, {}
    for frames, t in items:
        topic = bytes(frames[0]).decode()
        type_name, version, _, publish_ns, _, seq = peek(frames[1])
        if topic not in channels:
            if type_name not in schemas:
                data = json.dumps(json_schema(lookup(type_name)), separators=(",", ":")).encode()
                schemas[type_name] = w.register_schema(type_name, SCHEMA_ENCODING, data)
            channels[topic] = w.register_channel(topic, MESSAGE_ENCODING, schemas[type_name],
                                                 {"type": type_name, "version": str(version)})
        w.add_message(channels[topic], log_time=t, data=pack_payload(frames[1:]), publish_time=publish_ns,
                      sequence=seq)
    w.add_metadata("late", {"note": "after the messages"})
    w.finish()
    return buf.getvalue()


def ours(path, items, compression: str, chunk_size: int) -> bytes:
    with BagWriter(path, compression=compression, chunk_size=chunk_size, metadata={"site": {"room": "lab"}}) as w:
        for frames, t in items:
            w.write_frames(frames, log_time_ns=t)
        w.add_metadata("late", {"note": "after the messages"})
    return path.read_bytes()


@pytest.mark.parametrize("compression", ["none", "lz4", "zstd"])
@pytest.mark.parametrize("chunk_size", [300, 4096, 1 << 20])
def test_files_are_byte_identical_to_the_mcap_writer(tmp_path, compression, chunk_size):
    items = stream()
    got = ours(tmp_path / "ours.mcap", items, compression, chunk_size)
    library = BagReader(tmp_path / "ours.mcap").library
    assert library.startswith("probeless")
    assert got == mcap_reference(items, compression, chunk_size, library)


@pytest.mark.parametrize("compression", ["none", "lz4"])
def test_mcap_reader_reads_messages_summary_and_indexes(tmp_path, compression):
    items = stream()
    path = tmp_path / "r.mcap"
    ours(path, items, compression, 5_000)
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        summary = reader.get_summary()
        got = [(c.topic, m.log_time, m.publish_time, m.sequence, m.data)
               for _, c, m in reader.iter_messages(log_time_order=False)]
    want = [(bytes(fr[0]).decode(), t, peek(fr[1])[3], peek(fr[1])[5], pack_payload(fr[1:])) for fr, t in items]
    assert got == want
    st = summary.statistics
    assert st.message_count == len(items) and st.chunk_count == len(summary.chunk_indexes) > 5
    assert (st.message_start_time, st.message_end_time) == (min(t for _, t in items), max(t for _, t in items))
    assert st.channel_count == len(summary.channels) == len(examples()) + 1 and st.metadata_count == 2
    assert sum(st.channel_message_counts.values()) == len(items)
    for ci in summary.chunk_indexes:  # every message index offset points at a message index record
        for cid, off in ci.message_index_offsets.items():
            with open(path, "rb") as f:
                f.seek(off)
                head = f.read(11)
            assert head[0] == 0x07 and int.from_bytes(head[9:11], "little") == cid


def test_payload_size_and_chunk_buffer_layout():
    frames = [b"m", b"", bytes(300), bytes(70_000), np.arange(12, dtype=np.uint16).reshape(3, 4)]
    frames += [bytes([i]) for i in range(20)]  # 25 frames: msgpack array16
    payload = pack_payload(frames)
    assert payload_size(frames) == len(payload)
    buf = ChunkBuffer(64)  # grows to fit
    assert buf.add_message(3, 7, 11, 13, frames) == len(payload)
    assert buf.add_message(3, 8, 9, 10, [b"meta"]) == len(pack_payload([b"meta"]))
    data = bytes(buf.view[:buf.size])
    assert data[0] == 0x05 and int.from_bytes(data[1:9], "little") == 22 + len(payload)
    assert msgpack.unpackb(data[31:31 + len(payload)]) == [bytes(memoryview(f).cast("B")) for f in frames]
    assert (buf.messages, buf.start_ns, buf.end_ns) == (2, 9, 11)
    assert buf.index == {3: [11, 0, 9, 31 + len(payload)]}
    with pytest.raises(BagError, match="metadata frame"):
        buf.add_message(1, 0, 0, 0, [])


def test_short_writes_are_completed(tmp_path, monkeypatch):
    real = directio.os.pwritev
    monkeypatch.setattr(directio.os, "pwritev", lambda fd, bufs, off: real(fd, [bytes(b"".join(bufs)[:1000])], off))
    parts = [bytes(range(256)) * 10, memoryview(bytearray(5000)), b"", b"tail"]
    with open(tmp_path / "w.bin", "wb", buffering=0) as f:
        directio._write_at(f.fileno(), parts, 0)
    assert (tmp_path / "w.bin").read_bytes() == b"".join(bytes(p) for p in parts)


@pytest.mark.timeout(30)
def test_a_failing_write_in_the_writer_thread_surfaces_as_bag_error(tmp_path, monkeypatch):
    real, calls = directio._write_at, []

    def failing(fd, parts, offset):
        calls.append(1)
        if len(calls) > 3:  # the header, the metadata and the first chunk are written, then the disk is full
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(fd, parts, offset)

    monkeypatch.setattr(directio, "_write_at", failing)
    path = tmp_path / "full.mcap"
    w = BagWriter(path, chunk_size=10_000, metadata={"site": {"room": "lab"}})
    with pytest.raises(BagError, match=f"cannot write {path}: No space left on device"):
        for i in range(200):  # never blocks: the thread keeps recycling chunk buffers after the error
            w.write_frames(wire.encode("cam", image(i), "p", T0, seq=i), log_time_ns=T0 + i)
    with pytest.raises(BagError, match="No space left"):
        w.close()
    r = BagReader(path)  # what was written before the error is a readable prefix: the first chunk
    seqs = [m.sequence for m in r.messages()]
    assert r.truncated and len(r._chunks) == 1 and seqs == list(range(len(seqs))) and len(seqs) >= 1
    assert r.metadata() == {"site": {"room": "lab"}}


def test_split_by_size_with_compression_keeps_parts_full_and_under_the_limit(tmp_path):
    """Queued chunks count uncompressed until written; parts must still fill up to the limit."""
    path = tmp_path / "run.mcap"
    rng = np.random.default_rng(0)
    with BagWriter(path, compression="lz4", chunk_size=30_000, max_size=120_000) as w:
        for i in range(120):
            data = np.zeros((48, 64, 3), np.uint8)
            data[:24] = rng.integers(0, 256, (24, 64, 3))  # compresses to about half
            w.write_frames(wire.encode("cam", Image(Header(T0 + i, "cam", i), data, "rgb8"), "p", T0 + i, seq=i),
                           log_time_ns=T0 + i)
    parts = split_paths(path)
    assert len(parts) >= 3
    seqs = []
    for p in parts:
        assert p.stat().st_size <= 120_000
        assert p.stat().st_size > 100_000 or p == parts[-1]
        seqs += [m.sequence for m in BagReader(p).messages()]
    assert seqs == list(range(120))


# -- direct I/O -----------------------------------------------------------------------------------

def records(sizes, opcode=0x42):
    """Complete MCAP-style records (opcode, u64 length, body) of the given total sizes."""
    return [bytes([opcode]) + (n - 9).to_bytes(8, "little") + bytes([i % 251]) * (n - 9) for i, n in enumerate(sizes)]


def parse(data: bytes):
    """[(opcode, total size)] of a sequence of records; AssertionError unless they fill ``data`` exactly."""
    out, pos = [], 0
    while pos < len(data):
        assert pos + 9 <= len(data)
        n = 9 + int.from_bytes(data[pos + 1:pos + 9], "little")
        out.append((data[pos], n))
        pos += n
    assert pos == len(data)
    return out


def test_append_file_leaves_complete_records_after_every_write_and_no_padding_at_the_end(tmp_path):
    # sizes that end a write exactly on a block, 1 and 8 bytes short of one (no room for the padding
    # header: it takes the next block too), span several blocks, or are tiny
    sizes = [4096, 4095, 9, 4088, 12, 20_000, 4087, 9, 9, 70_000, 4100, 8188, 4096 * 3]
    path = tmp_path / "a.bin"
    written = b""
    with open(path, "wb", buffering=0) as f:
        out = directio.AppendFile(f.fileno(), capacity=8192)  # grows on the way
        assert out.direct  # /tmp is ext4 on the machines the tests run on
        for rec in records(sizes):
            assert out.write([rec[:5], memoryview(rec)[5:]]) == len(rec)
            written += rec
            data = path.read_bytes()
            assert len(data) % directio.BLOCK == 0 and data[:len(written)] == written
            tail = parse(data[len(written):])  # nothing, or one padding record up to the block end
            assert tail == [] or (len(tail) == 1 and tail[0][0] == directio.PADDING_OPCODE)
            assert out.pos == len(written)
        out.close()
    assert path.read_bytes() == written and [n for _, n in parse(written)] == sizes


def test_unfinished_direct_file_is_read_by_mcap_and_bag_reader(tmp_path):
    from mcap.exceptions import EndOfFile
    from mcap.stream_reader import StreamReader

    path = tmp_path / "open.mcap"
    w = BagWriter(path, chunk_size=20_000)
    assert w.direct_io
    for i in range(12):
        w.write_frames(wire.encode("cam", image(i), "p", T0, seq=i), log_time_ns=T0 + i)
    w.flush()
    assert path.stat().st_size % directio.BLOCK == 0  # padded while the recording is open
    with open(path, "rb") as f:
        got = []
        with pytest.raises(EndOfFile):  # the stream ends without a footer
            for rec in StreamReader(f, skip_magic=False).records:
                got.append(rec)
    assert [r.sequence for r in got if type(r).__name__ == "Message"] == list(range(12))
    r = BagReader(path)
    assert r.truncated and [m.sequence for m in r.messages()] == list(range(12))
    w.close()
    assert not BagReader(path).truncated


def test_direct_and_page_cache_writes_give_the_same_file(tmp_path, monkeypatch):
    items = stream()
    direct = ours(tmp_path / "direct.mcap", items, "lz4", 4096)
    with BagWriter(tmp_path / "cached.mcap", direct_io=False) as w:
        assert not w.direct_io
    cached = tmp_path / "cached2.mcap"
    with BagWriter(cached, compression="lz4", chunk_size=4096, metadata={"site": {"room": "lab"}},
                   direct_io=False) as w:
        for frames, t in items:
            w.write_frames(frames, log_time_ns=t)
        w.add_metadata("late", {"note": "after the messages"})
    assert cached.read_bytes() == direct
    # a file system that accepts O_DIRECT on open but refuses the writes: fall back mid-recording
    real, refused = directio._write_at, []

    def picky(fd, parts, offset):
        if directio.fcntl.fcntl(fd, directio.fcntl.F_GETFL) & directio.os.O_DIRECT and len(refused) < 1 \
                and offset > 0:
            refused.append(offset)
            raise OSError(errno.EINVAL, "Invalid argument")
        return real(fd, parts, offset)

    monkeypatch.setattr(directio, "_write_at", picky)
    assert ours(tmp_path / "fallback.mcap", items, "lz4", 4096) == direct and refused
