"""Hostile inputs: oversized frames, msgpack bombs, lying array descriptors, YAML bombs.

Each is refused with our own error naming the thing at fault (topic and field, file and line),
quickly and without allocating what the input declares; never a MemoryError, a RecursionError
or a hang.
"""

from __future__ import annotations

import logging
import socket
import threading
import time
import tracemalloc

import msgpack
import numpy as np
import pytest
import zmq

from probeless import wire
from probeless.cli import main
from probeless.errors import GraphError, SceneError, SchemaError
from probeless.launch.graph import parse_graph
from probeless.launch.yamlload import MAX_DEPTH, MAX_YAML_BYTES, load_yaml
from probeless.messages import Header, Image
from probeless.runtime.queues import InputQueue
from probeless.runtime.receiver import InputWire, Receiver
from probeless.scene.extends import load_scene_doc

TOPIC = "cam/image"


def _image_frames() -> list[bytes]:
    frames = wire.encode(TOPIC, Image(Header(1, "cam", 3), np.zeros((4, 6, 3), np.uint8), "rgb8"), "cam", 5)
    return [bytes(memoryview(f)) if isinstance(f, np.ndarray) else f for f in frames]


def _with_data(desc_update: dict, buffer: bytes | None = None) -> list[bytes]:
    """The image message with its ``data`` descriptor [index, dtype, shape] changed, and optionally its buffer."""
    frames = _image_frames()
    meta = msgpack.unpackb(frames[1])
    for i, v in desc_update.items():
        meta["fields"]["data"][i] = v
    return [frames[0], msgpack.packb(meta), frames[2] if buffer is None else buffer]


# -- decode limits -------------------------------------------------------------------------------

MSGPACK_BOMBS = {
    "array32 of 4e9 items": b"\xdd\xff\xff\xff\xff",
    "map32 of 4e9 pairs": b"\xdf\xff\xff\xff\xff",
    "str32 of 4 GiB": b"\xdb\xff\xff\xff\xff" + b"a" * 16,
    "bin32 of 4 GiB": b"\xc6\xff\xff\xff\xff" + b"a" * 16,
    "ext32 of 4 GiB": b"\xc9\xff\xff\xff\xff\x01",
    "100000 nested arrays": b"\x91" * 100_000,
    "100000 nested maps": b"\x81\xa1k" * 100_000,
}


@pytest.mark.parametrize("name", sorted(MSGPACK_BOMBS))
def test_msgpack_bomb_in_metadata_is_a_schema_error_naming_the_topic(name):
    tracemalloc.start()
    t0 = time.perf_counter()
    with pytest.raises(SchemaError) as info:
        wire.decode([TOPIC.encode(), MSGPACK_BOMBS[name]])
    elapsed = time.perf_counter() - t0
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert str(info.value).startswith(f"topic {TOPIC!r}: malformed message")
    assert elapsed < 0.5
    assert peak < 4 << 20   # nothing near the declared 4 GiB (or 4e9 items) was allocated


@pytest.mark.parametrize("desc, buffer, match", [
    ({1: "<u2"}, None, "buffer has 72 bytes, shape [4, 6, 3] of uint16 needs 144"),          # dtype lies
    ({2: [8, 6, 3]}, None, "buffer has 72 bytes, shape [8, 6, 3] of uint8 needs 144"),       # shape lies
    ({2: [4, 6, 3]}, b"\0" * 71, "buffer has 71 bytes"),                                     # buffer short
    ({2: [-4, -6, 3]}, None, "shape [-4, -6, 3] malformed"),                                 # negative
    ({2: [1 << 31, 1 << 31, 3]}, None, "needs 13835058055282163712"),                     # 12 EiB
    ({2: [0, (1 << 63) - 1, 3]}, b"", "malformed"),                                          # beyond MAX_DIM
    ({2: [0, 1 << 32, 1 << 32]}, b"", "not representable"),                                  # numpy overflow
    ({2: [4, 6, 3, 1]}, None, "has rank 4"),
    ({2: [1] * 100}, None, "malformed"),                                                     # rank > MAX_RANK
])
def test_array_descriptor_that_disagrees_with_its_buffer_names_topic_and_field(desc, buffer, match):
    with pytest.raises(SchemaError) as info:
        wire.decode(_with_data(desc, buffer))
    text = str(info.value)
    assert text.startswith(f"topic {TOPIC!r}: sensor/Image.data: "), text
    assert match in text


def test_frame_sum_above_the_cap_is_refused_before_decoding():
    frames = _image_frames()
    total = sum(map(len, frames))
    with pytest.raises(SchemaError, match=f"topic {TOPIC!r}: message of {total} bytes exceeds the limit of 100 bytes"):
        wire.decode(frames, max_bytes=100)


def _receiver(endpoints: list[str], max_bytes: int):
    """A receiver thread with one drop_oldest input per endpoint (``in0``, ``in1``, ...)."""
    zctx = zmq.Context()
    queues = {f"in{i}": InputQueue(f"in{i}", "drop_oldest", 100) for i in range(len(endpoints))}
    cond = threading.Condition()
    wires = [InputWire(f"in{i}", e, TOPIC, "sensor/Image") for i, e in enumerate(endpoints)]
    rx = Receiver(zctx, wires, queues, cond, f"inproc://wake-limits-{id(queues)}", max_bytes=max_bytes,
                  node_id="victim")
    rx.start()
    return zctx, rx, queues, cond


def _stop(zctx: zmq.Context, rx: Receiver) -> None:
    wake = zctx.socket(zmq.PAIR)
    wake.connect(f"inproc://wake-limits-{id(rx.queues)}")
    rx.stop(wake)
    rx.join(3)
    wake.close(0)
    zctx.term()


def _wait(pred, timeout: float = 5.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if pred():
            return True
        time.sleep(0.01)
    return False


def test_receiver_discards_hostile_messages_and_keeps_receiving(caplog):
    zctx = zmq.Context()
    pub = zctx.socket(zmq.PUB)
    port = pub.bind_to_random_port("tcp://127.0.0.1")
    rzctx, rx, queues, cond = _receiver([f"tcp://127.0.0.1:{port}"], max_bytes=1 << 20)
    q = queues["in0"]
    try:
        hostile = [[TOPIC.encode(), bomb] for bomb in MSGPACK_BOMBS.values()]
        hostile += [_with_data({2: [1 << 31, 1 << 31, 3]}), _with_data({1: "<u2"})]
        with caplog.at_level(logging.ERROR, logger="probeless.receiver"):
            assert _wait(lambda: pub.poll(0) or True)  # let the subscription arrive
            time.sleep(0.3)
            for frames in hostile:
                pub.send_multipart(frames)
            pub.send_multipart(_image_frames())
            assert _wait(lambda: q.received == 1 and q.invalid == len(hostile))
        with cond:
            msg = q.pop()
        assert msg.data.shape == (4, 6, 3) and msg.header.seq == 3
        assert sum(TOPIC in r.getMessage() for r in caplog.records) == len(hostile)
    finally:
        _stop(rzctx, rx)
        pub.close(0)
        zctx.term()


def _zmtp(data: bytes, more: bool = False, command: bool = False) -> bytes:
    """One ZMTP 3 frame (short or long form)."""
    flags = (0x01 if more else 0) | (0x04 if command else 0)
    if len(data) < 256:
        return bytes([flags, len(data)]) + data
    return bytes([flags | 0x02]) + len(data).to_bytes(8, "big") + data


def _handshake(conn: socket.socket) -> None:
    """Be a ZMTP 3.0 PUB with the NULL mechanism."""
    conn.sendall(b"\xff" + b"\0" * 8 + b"\x7f" + b"\x03\x00" + b"NULL".ljust(20, b"\0") + b"\0" * 32)
    got = b""
    while len(got) < 64:
        got += conn.recv(64 - len(got))
    conn.sendall(_zmtp(b"\x05READY\x0bSocket-Type" + (3).to_bytes(4, "big") + b"PUB", command=True))


def _closed(conn: socket.socket, timeout: float) -> bool:
    """True when the peer closes the connection within ``timeout`` (whatever it still sends is read)."""
    conn.settimeout(timeout)
    try:
        while conn.recv(65536):
            pass
        return True
    except ConnectionResetError:
        return True
    except socket.timeout:
        return False


def test_frame_declaring_one_tebibyte_drops_the_connection_before_allocating():
    """A hand-made ZMTP frame header declares 2^40 bytes: the receiver's SUB (MAXMSGSIZE) hangs up at once.
    Allocating it would abort libzmq (or wait for data that never comes). The receiver lives on: its
    other input still delivers. (libzmq does not reconnect after such a protocol error.)"""
    server = socket.create_server(("127.0.0.1", 0))
    server.settimeout(5)
    zctx = zmq.Context()
    pub = zctx.socket(zmq.PUB)
    port = pub.bind_to_random_port("tcp://127.0.0.1")
    rzctx, rx, queues, cond = _receiver([f"tcp://127.0.0.1:{server.getsockname()[1]}",
                                         f"tcp://127.0.0.1:{port}"], max_bytes=1 << 20)
    try:
        conn, _ = server.accept()
        _handshake(conn)
        conn.sendall(bytes([0x02]) + (1 << 40).to_bytes(8, "big") + b"x" * 4096)
        t0 = time.monotonic()
        assert _closed(conn, timeout=3.0), "the receiver kept a connection that declared a 1 TiB frame"
        assert time.monotonic() - t0 < 1.0
        conn.close()
        time.sleep(0.3)   # the honest publisher's subscription arrives
        pub.send_multipart(_image_frames())
        assert _wait(lambda: queues["in1"].received == 1)
        assert rx.is_alive() and queues["in0"].received == 0 and queues["in0"].invalid == 0
    finally:
        _stop(rzctx, rx)
        pub.close(0)
        zctx.term()
        server.close()


# -- YAML limits ---------------------------------------------------------------------------------

def _laughs(levels: int = 9) -> str:
    lines = ["lol0: &lol0 [lol, lol, lol, lol, lol, lol, lol, lol, lol]"]
    for i in range(1, levels):
        lines.append(f"lol{i}: &lol{i} [" + ", ".join([f"*lol{i - 1}"] * 9) + "]")
    return "\n".join(lines) + "\n"


YAML_BOMBS = {
    # name: (text, line the error names, words in the message)
    "10000 nested flow lists": ("nodes: " + "[" * 10_000 + "]" * 10_000 + "\n", 1, "nested deeper than"),
    "10000 nested flow maps": ("nodes: " + "{a: " * 10_000 + "}" * 10_000 + "\n", 1, "nested deeper than"),
    "2000 nested block maps": ("".join(" " * i + "k:\n" for i in range(2000)), MAX_DEPTH, "nested deeper than"),
    "billion laughs": (_laughs(), 7, "aliases expand to more than"),   # lol6 = 9^7 nodes, line 7
}


@pytest.mark.parametrize("name", sorted(YAML_BOMBS))
def test_yaml_bomb_in_a_graph_is_a_graph_error_naming_file_and_line(name, tmp_path):
    text, line, words = YAML_BOMBS[name]
    path = tmp_path / "hostile.yaml"
    path.write_text(text)
    tracemalloc.start()
    t0 = time.perf_counter()
    with pytest.raises(GraphError) as info:
        parse_graph(path)
    elapsed = time.perf_counter() - t0
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert info.value.file == str(path) and info.value.line == line, info.value
    assert words in info.value.message
    assert elapsed < 1.0
    assert peak < 64 << 20


def test_huge_yaml_file_is_refused_without_reading_it_all(tmp_path):
    path = tmp_path / "huge.yaml"
    with path.open("wb") as f:
        f.truncate(4 * MAX_YAML_BYTES)          # sparse: 32 MiB of zeros on disk in no time
    tracemalloc.start()
    t0 = time.perf_counter()
    with pytest.raises(GraphError, match=f"larger than the limit of {MAX_YAML_BYTES} bytes") as info:
        load_yaml(path)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert info.value.file == str(path)
    assert time.perf_counter() - t0 < 1.0
    assert peak < 2 * MAX_YAML_BYTES


def test_check_reports_a_yaml_bomb_as_one_error(tmp_path, capsys):
    path = tmp_path / "laughs.yaml"
    path.write_text(_laughs())
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {path}:7: YAML aliases expand to more than")


def test_scene_file_bomb_is_a_scene_error_naming_the_file(tmp_path):
    path = tmp_path / "scene.yaml"
    path.write_text("objects: " + "[" * 10_000 + "]" * 10_000 + "\n")
    with pytest.raises(SceneError, match=f"{path}:1: YAML nested deeper than {MAX_DEPTH} levels"):
        load_scene_doc(path)


def test_ordinary_anchors_and_merge_keys_still_load(tmp_path):
    path = tmp_path / "ok.yaml"
    path.write_text("base: &b {fps: 30, size: [640, 480]}\ncopy: *b\nmerged: {<<: *b, fps: 15}\n")
    doc = load_yaml(path)
    assert doc["copy"] == {"fps": 30, "size": [640, 480]}
    assert doc["merged"] == {"fps": 15, "size": [640, 480]}
