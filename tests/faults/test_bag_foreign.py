"""Recordings made by other tools: any valid MCAP file reads as the ``mcap`` package reads it.

The reference is the ``mcap`` package's own reader. Padded records and unknown records (which
that reader's chunk parser does not skip) are compared with the same messages written plainly.
"""

from __future__ import annotations

import json

import pytest
from bag.mcap_raw import padded_file, plain_file, sample_messages
from mcap.reader import make_reader
from mcap.writer import CompressionType, IndexType, Writer

from probeless.bag.export import export_foxglove
from probeless.bag.reader import BagReader
from probeless.cli import main
from probeless.errors import BagError


def reference(path) -> list[tuple[str, int, bytes]]:
    """(topic, log time, payload) in log-time order, as the mcap package reads the file."""
    with open(path, "rb") as f:
        return [(c.topic, m.log_time, bytes(m.data)) for _, c, m in make_reader(f).iter_messages(log_time_order=True)]


def ours(path) -> tuple[list[tuple[str, int, bytes]], dict]:
    with BagReader(path) as r:
        got = [(c.topic, m.log_time, bytes(m.data)) for c, m in r.records()]
        return got, {t: (i.count, i.bytes) for t, i in r.topics().items()}, r.truncated


def counts(msgs) -> dict:
    out: dict = {}
    for topic, _, data in msgs:
        n, b = out.get(topic, (0, 0))
        out[topic] = (n + 1, b + len(data))
    return out


WRITER_VARIANTS = {
    "chunked-zstd": dict(compression=CompressionType.ZSTD),
    "chunked-lz4": dict(compression=CompressionType.LZ4),
    "chunked-none": dict(compression=CompressionType.NONE),
    "unchunked": dict(use_chunking=False),
    "no-statistics": dict(use_statistics=False, use_summary_offsets=False),
    "no-indexes": dict(index_types=IndexType.NONE, use_statistics=False),
    "unchunked-no-statistics": dict(use_chunking=False, use_statistics=False, use_summary_offsets=False),
}


@pytest.mark.parametrize("variant", sorted(WRITER_VARIANTS))
def test_files_of_the_mcap_writer_read_as_its_reader_reads_them(tmp_path, variant):
    path = tmp_path / f"{variant}.mcap"
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=300, **WRITER_VARIANTS[variant])
        w.start(profile="", library="other tool")
        sid = w.register_schema("demo.Thing", "jsonschema", b"{}")
        a, b = w.register_channel("/a", "json", sid), w.register_channel("/b", "cdr", 0)
        for seq, (cid, t, data) in enumerate(sample_messages(40)):
            w.add_message(a if cid == 1 else b, log_time=t, data=data, publish_time=t, sequence=seq)
        w.finish()
    want = reference(path)
    got, topics, truncated = ours(path)
    assert len(want) == 40 and got == want and topics == counts(want) and not truncated


@pytest.mark.parametrize("summary", [True, False])
def test_padded_and_unknown_records_are_skipped(tmp_path, summary):
    msgs = sample_messages(14)
    plain, padded = tmp_path / "plain.mcap", tmp_path / "padded.mcap"
    plain_file(plain, msgs)
    padded_file(padded, msgs, summary=summary)
    want = reference(plain)
    got, topics, truncated = ours(padded)
    assert len(want) == 14 and got == want and topics == counts(want) and not truncated


def test_unknown_compression_is_refused_by_name(tmp_path):
    path = tmp_path / "brotli.mcap"
    padded_file(path, sample_messages(6), compression="brotli")
    with pytest.raises(BagError, match=r"brotli.*not supported") as exc:
        BagReader(path)
    assert str(path) in str(exc.value)
    padded_file(path, sample_messages(6), compression="brotli", summary=False)  # found by the scan
    with pytest.raises(BagError, match=r"brotli.*not supported"):
        BagReader(path)


ENCODINGS = [("/chatter", "cdr", "std_msgs/msg/String", "ros2msg", b"string data"),
             ("/json", "json", "demo.Json", "jsonschema", b"{}"),
             ("/proto", "protobuf", "demo.Proto", "protobuf", b"\x0a\x00"),
             ("/ros1", "ros1", "std_msgs/String", "ros1msg", b"string data"),
             ("/odd", "cbor", "demo.Cbor", "cbor-schema", b"")]


@pytest.fixture
def ros_bag(tmp_path):
    """A ROS 2 style bag plus json, protobuf, ros1 and an encoding Foxglove does not read (cbor)."""
    path = tmp_path / "ros.mcap"
    sent = []
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=256)
        w.start(profile="ros2", library="rosbag2")
        ids = []
        for topic, enc, name, schema_enc, schema in ENCODINGS:
            sid = w.register_schema(name, schema_enc, schema)
            ids.append(w.register_channel(topic, enc, sid, {"offered_qos_profiles": ""}))
        for i in range(25):
            k = i % len(ENCODINGS)
            data = bytes([k, i]) * (3 + i)
            w.add_message(ids[k], log_time=1_000 + i, data=data, publish_time=1_000 + i, sequence=i)
            sent.append((ENCODINGS[k][0], 1_000 + i, data))
        w.finish()
    return path, sent


def test_info_lists_foreign_channels_with_encoding_schema_and_counts(ros_bag, capsys):
    path, sent = ros_bag
    assert reference(path) == sent
    assert main(["bag", "info", str(path), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    want = counts(sent)
    assert report["message_count"] == len(sent)
    for topic, enc, name, schema_enc, _ in ENCODINGS:
        d = report["topics"][topic]
        assert (d["count"], d["bytes"]) == want[topic]
        assert (d["encoding"], d["type"], d["schema_encoding"]) == (enc, name, schema_enc)
    assert main(["bag", "info", str(path)]) == 0
    text = capsys.readouterr().out
    assert "std_msgs/msg/String [cdr]" in text and "demo.Cbor [cbor]" in text


def test_export_passes_through_what_foxglove_reads_and_names_the_rest(ros_bag, tmp_path, capsys):
    path, sent = ros_bag
    out = tmp_path / "fox.mcap"
    summary = export_foxglove(path, out)
    exported = reference(out)
    readable = [s for s in sent if s[0] != "/odd"]
    assert exported == readable                                   # byte for byte, same times
    assert summary.skipped == {"/odd": sum(1 for s in sent if s[0] == "/odd")}
    assert summary.schemas["/odd"] == "not decodable: cbor"
    with open(out, "rb") as f:
        s = make_reader(f).get_summary()
    kept = {c.topic: (c.message_encoding, s.schemas[c.schema_id].encoding) for c in s.channels.values()}
    assert kept == {t: (e, se) for t, e, _, se, _ in ENCODINGS if t != "/odd"}
    assert main(["bag", "export", str(path), "-o", str(tmp_path / "again.mcap")]) == 0
    assert "/odd: 5 message(s) not decodable: cbor" in capsys.readouterr().out


def test_play_and_replay_refuse_a_recording_of_foreign_encodings_clearly(ros_bag, tmp_path, capsys):
    path, _ = ros_bag
    graph = tmp_path / "g.yaml"
    graph.write_text("nodes:\n  - id: src\n    node: nodes_for_tests:Ticker\n    inputs: {tick: timer/hz/50}\n")
    for argv in (["bag", "play", str(path), "--rate", "0"], ["launch", str(graph), "--replay", str(path)]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.startswith("error: ") and err.count("\n") == 1 and str(path) in err, err
        assert "/chatter (cdr)" in err and "/odd (cbor)" in err and "other encodings" in err, err


def test_a_corrupt_chunk_of_another_writer_is_reported_not_counted(ros_bag, tmp_path, capsys):
    path, sent = ros_bag
    with open(path, "rb") as f:
        chunks = sorted(make_reader(f).get_summary().chunk_indexes, key=lambda c: c.chunk_start_offset)
    c = chunks[1]
    data = bytearray(path.read_bytes())
    data[c.chunk_start_offset + c.chunk_length - 5] ^= 0x04
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(bytes(data))
    kept = [s for s in sent if not c.message_start_time <= s[1] <= c.message_end_time]
    assert main(["bag", "info", str(bad), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["message_count"] == len(kept) < len(sent)
    assert any(f"chunk at byte {c.chunk_start_offset} is corrupt" in w for w in report["warnings"])
    summary = export_foxglove(bad, tmp_path / "out.mcap")
    assert reference(tmp_path / "out.mcap") == [s for s in kept if s[0] != "/odd"]
    assert len(summary.warnings) == 1 and f"its {len(sent) - len(kept)} message(s)" in summary.warnings[0]
