"""Wire codec: round trips of every message type, zero-copy framing, and malformed input."""

from __future__ import annotations

import msgpack
import numpy as np
import pytest
from message_examples import examples

from probeless import wire
from probeless.errors import SchemaError
from probeless.messages import Header, Image, registry
from probeless.messages.base import messages_equal

EXAMPLES = examples()


@pytest.mark.parametrize("type_name", sorted(EXAMPLES))
def test_round_trip_every_type(type_name):
    msg = EXAMPLES[type_name]
    frames = wire.encode("node/out", msg, "node", 123)
    frames = [bytes(memoryview(f)) if isinstance(f, np.ndarray) else f for f in frames]
    topic, env, back = wire.decode(frames)
    assert topic == "node/out"
    assert env == wire.Envelope(type_name, type(msg).VERSION, "node", 123)
    assert messages_equal(back, msg)


def test_every_registered_type_has_an_example():
    assert set(registry()) == set(EXAMPLES)


def test_arrays_travel_as_own_frames_without_copy():
    data = np.zeros((480, 640, 3), np.uint8)
    frames = wire.encode("cam/image", Image(Header(1), data, "rgb8"), "cam", 0)
    assert len(frames) == 3
    assert frames[2] is data  # the array itself, handed to zmq with copy=False
    meta = msgpack.unpackb(frames[1])
    assert meta["fields"]["data"] == [0, "|u1", [480, 640, 3]]
    assert len(frames[1]) < 200  # no pixel data in the metadata


def test_non_contiguous_array_is_made_contiguous():
    base = np.arange(8 * 10 * 3, dtype=np.uint8).reshape(8, 10, 3)
    view = base[:, ::2]
    msg = Image(Header(1), view, "rgb8")
    assert msg.data.flags.c_contiguous
    frames = wire.encode("t", msg, "p", 0)
    _, _, back = wire.decode([bytes(memoryview(f)) if isinstance(f, np.ndarray) else f for f in frames])
    np.testing.assert_array_equal(back.data, view)


def _frames(msg=None):
    msg = msg or EXAMPLES["sensor/Image"]
    return [bytes(memoryview(f)) if isinstance(f, np.ndarray) else f for f in wire.encode("a/b", msg, "a", 5)]


def _with_meta(frames, mutate):
    meta = msgpack.unpackb(frames[1])
    mutate(meta)
    return [frames[0], msgpack.packb(meta), *frames[2:]]


@pytest.mark.parametrize("mutate, match", [
    (lambda m: m.update(type="sensor/Nope"), "unknown message type"),
    (lambda m: m.update(version=99), "schema version 99"),
    (lambda m: m["fields"].pop("encoding"), "do not match"),
    (lambda m: m["fields"].update(extra=1), "do not match"),
    (lambda m: m["fields"]["data"].__setitem__(1, "<f4"), "buffer has"),
    (lambda m: m["fields"]["data"].__setitem__(1, "|O"), "not allowed"),
    (lambda m: m["fields"]["data"].__setitem__(2, [4, 6, 2]), "buffer has"),
    (lambda m: m["fields"]["data"].__setitem__(0, 3), "buffer index"),
    (lambda m: m["fields"].update(encoding=5), "expected str"),
    (lambda m: m["fields"]["header"].update(seq="x"), "expected int"),
    (lambda m: m.update(publish_ns="now"), "publisher/publish_ns"),
    (lambda m: m.pop("publisher"), "envelope"),
])
def test_malformed_metadata_raises_schema_error(mutate, match):
    with pytest.raises(SchemaError, match=match):
        wire.decode(_with_meta(_frames(), mutate))


def test_wrong_expected_type_and_size_limit_and_buffers():
    frames = _frames()
    with pytest.raises(SchemaError, match="expected sensor/DepthImage"):
        wire.decode(frames, expected="sensor/DepthImage")
    with pytest.raises(SchemaError, match="exceeds the limit"):
        wire.decode(frames, max_bytes=50)
    with pytest.raises(SchemaError, match="not referenced"):
        wire.decode(frames + [b"spare"])
    with pytest.raises(SchemaError, match="at least topic"):
        wire.decode(frames[:1])
    with pytest.raises(SchemaError, match="malformed|envelope"):
        wire.decode([b"t", b"\xc1garbage"])


def test_eos_marker():
    assert wire.is_eos([b"a/b", wire.EOS])
    assert not wire.is_eos(_frames())


def test_fuzz_malformed_frames_only_raise_schema_error():
    """10,000+ seeded mutations of valid encodings: decode succeeds or raises SchemaError, nothing else."""
    rng = np.random.default_rng(20261122)
    seeds = [_frames(m) for m in EXAMPLES.values()]
    outcomes = {"ok": 0, "schema": 0}
    for case in range(12_000):
        frames = [bytearray(f) for f in seeds[case % len(seeds)]]
        kind = rng.integers(6)
        if kind == 0:    # flip random bytes in the metadata
            for _ in range(rng.integers(1, 6)):
                frames[1][rng.integers(len(frames[1]))] = rng.integers(256)
        elif kind == 1:  # truncate the metadata
            frames[1] = frames[1][: rng.integers(len(frames[1]))]
        elif kind == 2:  # truncate or extend a buffer
            if len(frames) > 2:
                i = rng.integers(2, len(frames))
                frames[i] = frames[i][: rng.integers(len(frames[i]) + 1)] + bytes(rng.integers(0, 3))
        elif kind == 3:  # drop or duplicate frames
            frames = frames[: rng.integers(len(frames) + 1)] if rng.random() < 0.5 else frames + frames[1:2]
        elif kind == 4:  # random msgpack document
            docs = [None, 1, "x", [1, 2], {"type": 1}, {"fields": []}, [[[[]]]] * 3, {1: 2}]
            doc = docs[rng.integers(len(docs))]
            frames[1] = bytearray(msgpack.packb(doc))
        else:            # random bytes everywhere
            frames = [bytearray(rng.bytes(rng.integers(0, 64))) for _ in range(rng.integers(0, 5))]
        try:
            wire.decode([bytes(f) for f in frames], max_bytes=1 << 20)
            outcomes["ok"] += 1
        except SchemaError:
            outcomes["schema"] += 1
    assert outcomes["schema"] > 10_000
