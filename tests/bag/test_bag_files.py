"""BagWriter/BagReader: bit-exact round trips, ordering, splitting, truncation, corruption, schemas."""

from __future__ import annotations

import json
import os
import shutil

import msgpack
import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.writer import Writer
from message_examples import examples

from probeless import wire
from probeless.bag.format import PROFILE, pack_payload, peek, unpack_payload
from probeless.bag.reader import BagReader
from probeless.bag.schema import json_schema
from probeless.bag.writer import BagWriter, recording_paths, split_paths
from probeless.errors import BagError
from probeless.messages import Header, Image, Tick
from probeless.messages.base import lookup, messages_equal

T0 = 1_700_000_000_000_000_000


def as_bytes(frame) -> bytes:
    return frame.tobytes() if isinstance(frame, np.ndarray) else bytes(frame)


def record(path, items, **kw):
    """Write ``items`` = [(topic, msg, log_time_ns)]; return the expected [(topic, log_time, frames bytes)]."""
    sent = []
    with BagWriter(path, **kw) as w:
        for topic, msg, t in items:
            frames = wire.encode(topic, msg, "recorder_test", t - 5)
            w.write_frames(frames, log_time_ns=t)
            sent.append((topic, t, [as_bytes(f) for f in frames]))
    return sent


def all_types(repeat=3):
    ex = examples()
    items, t = [], T0
    for _ in range(repeat):
        for name, msg in ex.items():
            items.append((f"rec/{name}", msg, t))
            t += 1_000_000
    return ex, items


def image(i: int, size=(48, 64)) -> Image:
    data = np.random.default_rng(i).integers(0, 256, (*size, 3), dtype=np.uint8)
    return Image(Header(T0 + i, "cam", i), data, "rgb8")


# -- round trips ----------------------------------------------------------------------------------

@pytest.mark.parametrize("compression", ["lz4", "zstd", "none"])
def test_round_trip_every_type(tmp_path, compression):
    ex, items = all_types()
    path = tmp_path / "run.mcap"
    sent = record(path, items, compression=compression, chunk_size=4096)
    with BagReader(path) as r:
        assert not r.truncated and r.truncation_note == ""
        assert r.profile == PROFILE
        assert r.compression == {compression}
        got = list(r.messages())
        assert len(got) == len(sent)
        for m, (topic, t, frames) in zip(got, sent):
            assert (m.topic, m.log_time_ns, m.publish_time_ns) == (topic, t, t - 5)
            assert [as_bytes(f) for f in m.frames] == frames          # bit-exact
            assert m.type_name == topic[len("rec/"):] and m.version == lookup(m.type_name).VERSION
            assert m.sequence == 7                                     # header.seq of the examples
            assert messages_equal(r.decode(m), ex[m.type_name])
        topics = r.topics()
        assert set(topics) == {f"rec/{n}" for n in ex}
        for name in ex:
            info = topics[f"rec/{name}"]
            assert (info.type_name, info.version, info.count) == (name, lookup(name).VERSION, 3)
            assert info.bytes == sum(len(pack_payload(f[1:])) for tp, _, f in sent if tp == info.topic)
            assert info.rate_hz == pytest.approx(1e9 / (len(ex) * 1_000_000))
        assert (r.start_ns, r.end_ns) == (sent[0][1], sent[-1][1])


def test_log_time_order_across_topics_and_filters(tmp_path):
    path = tmp_path / "order.mcap"
    tick = examples()["core/Tick"]
    items = [("a", tick, T0 + 20 * i) for i in range(20)] + [("b", tick, T0 + 20 * i + 10) for i in range(20)]
    record(path, items, chunk_size=256)  # many chunks, written a-first: order must come from the merge
    with BagReader(path) as r:
        assert len(r._chunks) > 4
        times = [m.log_time_ns for m in r.messages()]
        assert times == sorted(times) and len(times) == 40
        assert [m.topic for m in r.messages()][:4] == ["a", "b", "a", "b"]
        only_b = list(r.messages(topics="b"))
        assert len(only_b) == 20 and {m.topic for m in only_b} == {"b"}
        window = [m.log_time_ns - T0 for m in r.messages(start_ns=T0 + 100, end_ns=T0 + 200)]
        assert window == list(range(100, 200, 10))
        written = [(m.topic, m.log_time_ns) for m in r.messages(in_file_order=True)]
        assert written == [(t, ns) for t, _, ns in items]
        assert [m.log_time_ns for m in r.messages("a", start_ns=T0 + 200, in_file_order=True)] == \
            [T0 + 20 * i for i in range(10, 20)]


def test_metadata_round_trip(tmp_path):
    path = tmp_path / "meta.mcap"
    w = BagWriter(path, metadata={"probeless.graph": {"version": "0.1.0", "plan": "{}"}})
    w.add_metadata("site", {"room": "lab", "operator": "me"})
    w.write_frames(wire.encode("t", examples()["core/Tick"], "p", T0), log_time_ns=T0)
    w.close(extra_metadata={"probeless.incomplete": {"t": "3 messages missing (seq gaps)"}})
    w.close()  # idempotent
    with BagReader(path) as r:
        assert r.metadata() == {"probeless.graph": {"version": "0.1.0", "plan": "{}"},
                                "site": {"room": "lab", "operator": "me"},
                                "probeless.incomplete": {"t": "3 messages missing (seq gaps)"}}
    with pytest.raises(BagError, match="strings"):
        BagWriter(tmp_path / "bad.mcap", metadata={"x": {"n": 1}})


def test_overwrite_refused_without_force(tmp_path):
    path = tmp_path / "run.mcap"
    path.write_bytes(b"precious")
    with pytest.raises(BagError, match="--force") as exc:
        BagWriter(path)
    assert str(path) in str(exc.value)
    assert path.read_bytes() == b"precious"
    with BagWriter(path, force=True) as w:
        w.write_frames(wire.encode("t", examples()["core/Tick"], "p", T0), log_time_ns=T0)
    assert BagReader(path).topics()["t"].count == 1


def test_writer_rejects_unknown_type_version_and_type_change(tmp_path):
    with BagWriter(tmp_path / "w.mcap") as w:
        meta = wire.encode("t", examples()["core/Tick"], "p", T0)[1]
        with pytest.raises(BagError, match="unknown message type 'x/Nope'"):
            w.write("t", "x/Nope", 1, [meta], log_time_ns=T0, publish_time_ns=T0)
        with pytest.raises(BagError, match="version 9"):
            w.write("t", "core/Tick", 9, [meta], log_time_ns=T0, publish_time_ns=T0)
        w.write("t", "core/Tick", 1, [meta], log_time_ns=T0, publish_time_ns=T0)
        with pytest.raises(BagError, match="core/Tick"):
            w.write("t", "core/Clock", 1, [meta], log_time_ns=T0, publish_time_ns=T0)


# -- splitting ------------------------------------------------------------------------------------

def test_split_by_size_gives_complete_files_holding_every_message_once(tmp_path):
    path = tmp_path / "run.mcap"
    items = [("cam", image(i), T0 + i * 33_000_000) for i in range(40)]
    items += [("tick", examples()["core/Tick"], T0 + i * 10_000_000 + 1) for i in range(100)]
    items.sort(key=lambda it: it[2])
    sent = record(path, items, max_size=40_000, chunk_size=16_000, compression="none",
                  metadata={"probeless.graph": {"version": "x"}})
    parts = split_paths(path)
    assert len(parts) >= 3 and not path.exists()
    assert [p.name for p in parts[:2]] == ["run_000.mcap", "run_001.mcap"]
    assert recording_paths(path) == parts
    seen = []
    for p in parts:
        assert p.stat().st_size <= 40_000
        with BagReader(p) as r:
            assert not r.truncated
            assert r.metadata() == {"probeless.graph": {"version": "x"}}
            seen += [(m.topic, m.log_time_ns, [as_bytes(f) for f in m.frames]) for m in r.messages()]
    assert seen == sent  # every message exactly once, in order


def test_split_by_duration_and_force_removes_stale_parts(tmp_path):
    path = tmp_path / "d.mcap"
    tick = examples()["core/Tick"]
    record(path, [("t", tick, T0 + i * 100_000_000) for i in range(50)], max_duration_s=1.0)  # 5 s
    assert len(split_paths(path)) == 5
    with pytest.raises(BagError, match="d_000.mcap.*--force"):
        BagWriter(path, max_duration_s=1.0)
    record(path, [("t", tick, T0 + i * 100_000_000) for i in range(15)], max_duration_s=1.0, force=True)
    parts = split_paths(path)
    assert len(parts) == 2
    assert [BagReader(p).topics()["t"].count for p in parts] == [10, 5]


# -- damaged files --------------------------------------------------------------------------------

@pytest.fixture
def long_recording(tmp_path):
    path = tmp_path / "long.mcap"
    items = [("cam", image(i), T0 + i * 1000) for i in range(30)]
    sent = record(path, items, chunk_size=20_000, metadata={"site": {"room": "lab"}})
    return path, sent


def cut_copy(src, dst, size):
    shutil.copy(src, dst)
    os.truncate(dst, size)
    return dst


def assert_prefix(reader, sent):
    got = [(m.topic, m.log_time_ns, [as_bytes(f) for f in m.frames]) for m in reader.messages()]
    assert got == sent[:len(got)]
    assert sum(t.count for t in reader.topics().values()) == len(got)
    return len(got)


def test_truncated_at_half_and_mid_chunk(long_recording, tmp_path):
    path, sent = long_recording
    half = BagReader(cut_copy(path, tmp_path / "half.mcap", path.stat().st_size // 2))
    assert half.truncated and "complete chunk" in half.truncation_note
    n = assert_prefix(half, sent)
    assert 0 < n < len(sent)
    assert half.metadata() == {"site": {"room": "lab"}}
    with open(path, "rb") as f:
        chunks = make_reader(f).get_summary().chunk_indexes
    c = chunks[2]
    mid = BagReader(cut_copy(path, tmp_path / "mid.mcap", c.chunk_start_offset + c.chunk_length // 2))
    assert mid.truncated
    assert "after 2 complete chunk(s)" in mid.truncation_note and "partial chunk" in mid.truncation_note
    assert assert_prefix(mid, sent) == sum(1 for t in sent if t[1] <= chunks[1].message_end_time)


def test_cut_in_summary_keeps_all_data(long_recording, tmp_path):
    path, sent = long_recording
    r = BagReader(cut_copy(path, tmp_path / "nosummary.mcap", path.stat().st_size - 20))  # footer damaged
    assert r.truncated and "only the summary" in r.truncation_note
    assert assert_prefix(r, sent) == len(sent)


def test_truncated_right_after_header(long_recording, tmp_path):
    path, _ = long_recording
    with open(path, "rb") as f:
        f.seek(8)
        opcode, length = f.read(1)[0], int.from_bytes(f.read(8), "little")
    assert opcode == 1  # header record
    r = BagReader(cut_copy(path, tmp_path / "hdr.mcap", 8 + 9 + length))
    assert r.truncated and "after 0 complete chunk(s)" in r.truncation_note
    assert list(r.messages()) == [] and r.topics() == {} and r.start_ns is None


def test_never_closed_writer_is_readable_up_to_last_flush(tmp_path):
    path = tmp_path / "killed.mcap"
    w = BagWriter(path, chunk_size=1 << 30)
    for i in range(5):
        w.write_frames(wire.encode("cam", image(i), "p", T0), log_time_ns=T0 + i)
    w.flush()
    w.write_frames(wire.encode("cam", image(9), "p", T0), log_time_ns=T0 + 9)  # not flushed: lost
    r = BagReader(path)  # as if the recorder had been SIGKILLed now
    assert r.truncated and "no summary" in r.truncation_note
    assert [m.log_time_ns - T0 for m in r.messages()] == [0, 1, 2, 3, 4]
    assert messages_equal(r.decode(next(r.messages())), image(0))
    w.close()
    assert not BagReader(path).truncated


def test_corrupt_chunk(long_recording, tmp_path):
    path, sent = long_recording
    with open(path, "rb") as f:
        chunks = make_reader(f).get_summary().chunk_indexes
    c = chunks[3]
    bad = tmp_path / "bad.mcap"
    data = bytearray(path.read_bytes())
    data[c.chunk_start_offset + c.chunk_length - 100] ^= 0xFF
    bad.write_bytes(bytes(data))
    r = BagReader(bad)  # indexed file: opening and listing need no chunk
    assert not r.truncated and r.topics()["cam"].count == len(sent)
    got = []
    with pytest.raises(BagError, match=f"{bad}.*chunk at byte {c.chunk_start_offset} is corrupt"):
        for m in r.messages():
            got.append(m)
    assert len(got) > 0
    # without its summary the scan stops at the corrupt chunk and reports it
    bad2 = cut_copy(bad, tmp_path / "bad2.mcap", chunks[-1].chunk_start_offset + 10)
    r2 = BagReader(bad2)
    assert r2.truncated and "after 3 complete chunk(s)" in r2.truncation_note and "corrupt" in r2.truncation_note
    assert assert_prefix(r2, sent) == sum(1 for t in sent if t[1] <= chunks[2].message_end_time)


def test_not_mcap_files(tmp_path):
    import cv2

    rnd = tmp_path / "random.mcap"
    rnd.write_bytes(np.random.default_rng(0).integers(0, 256, 4096, dtype=np.uint8).tobytes())
    empty = tmp_path / "empty.mcap"
    empty.write_bytes(b"")
    png = tmp_path / "picture.png"
    png.write_bytes(cv2.imencode(".png", np.zeros((4, 4, 3), np.uint8))[1].tobytes())
    for p in (rnd, empty, png):
        with pytest.raises(BagError, match="is not an MCAP file") as exc:
            BagReader(p)
        assert str(p) in str(exc.value)
    with pytest.raises(BagError, match="no such file") as exc:
        BagReader(tmp_path / "missing.mcap")
    assert "missing.mcap" in str(exc.value)
    with pytest.raises(BagError, match="cannot open") as exc:
        BagReader(tmp_path)
    assert str(tmp_path) in str(exc.value)


def _foreign(path, type_name, version, meta):
    with open(path, "wb") as f:
        w = Writer(f)
        w.start(profile=PROFILE)
        sid = w.register_schema(type_name, "jsonschema", b"{}")
        cid = w.register_channel("odd/topic", "msgpack", sid, {"type": type_name, "version": str(version)})
        w.add_message(cid, log_time=T0, data=pack_payload([meta]), publish_time=T0)
        w.finish()


def test_unknown_type_and_version_mismatch_name_topic_and_file(tmp_path):
    tick_meta = msgpack.unpackb(wire.encode("t", examples()["core/Tick"], "p", T0)[1])
    for name, doc in [("unknown.mcap", {**tick_meta, "type": "x/Unknown"}),
                      ("version.mcap", {**tick_meta, "version": 99})]:
        path = tmp_path / name
        _foreign(path, doc["type"], doc["version"], msgpack.packb(doc))
        r = BagReader(path)
        (m,) = r.messages()
        assert (m.type_name, m.version) == (doc["type"], doc["version"])
        with pytest.raises(BagError) as exc:
            r.decode(m)
        assert "odd/topic" in str(exc.value) and str(path) in str(exc.value)
        assert ("x/Unknown" if name == "unknown.mcap" else "version 99") in str(exc.value)


# -- format and schema ----------------------------------------------------------------------------

def test_payload_pack_unpack_and_peek():
    frames = [b"m", b"", bytes(300), bytes(70_000)] + [bytes([i]) for i in range(20)]  # array16, bin8/16/32
    payload = pack_payload(frames)
    assert msgpack.unpackb(payload) == frames
    assert [bytes(v) for v in unpack_payload(payload)] == frames
    arr = np.arange(12, dtype=np.uint16).reshape(3, 4)
    assert bytes(unpack_payload(pack_payload([b"m", arr]))[1]) == arr.tobytes()
    for bad in (b"", b"\x01", payload[:-1], payload + b"x", msgpack.packb(["text"]), msgpack.packb([])):
        with pytest.raises(BagError):
            unpack_payload(bad)
    frames = wire.encode("t", examples()["core/Tick"], "pub", 42, seq=11)
    assert peek(frames[1]) == ("core/Tick", 1, "pub", 42, examples()["core/Tick"].header.stamp_ns, 11)
    for bad in (b"", b"\xc1", msgpack.packb({"type": 1}), msgpack.packb([1, 2])):
        with pytest.raises(BagError):
            peek(bad)


def test_json_schema_validates_wire_documents(tmp_path):
    import jsonschema
    for name, msg in examples().items():
        schema = json_schema(type(msg))
        jsonschema.Draft202012Validator.check_schema(schema)
        assert schema["title"] == name and schema["x-probeless-version"] == type(msg).VERSION
        doc = msgpack.unpackb(wire.encode("t", msg, "p", T0)[1])
        jsonschema.validate(doc, schema, cls=jsonschema.Draft202012Validator)
    schema = json_schema(Image)
    data = schema["properties"]["fields"]["properties"]["data"]
    assert data["prefixItems"][2]["x-shape"] == ["h", "w", "c"] and "own frame" in data["description"]
    doc = msgpack.unpackb(wire.encode("t", examples()["sensor/Image"], "p", T0)[1])
    doc["fields"]["data"][1] = "<f8"  # float64 is not an allowed Image dtype
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate(doc, schema, cls=jsonschema.Draft202012Validator)
    # the schema stored in a recording is this one
    path = tmp_path / "s.mcap"
    record(path, [("t", examples()["core/Tick"], T0)])
    with open(path, "rb") as f:
        (schema_rec,) = make_reader(f).get_summary().schemas.values()
    assert (schema_rec.name, schema_rec.encoding) == ("core/Tick", "jsonschema")
    assert json.loads(schema_rec.data) == json_schema(Tick)
