"""Corrupt and truncated recordings: a clear error naming the file, or the valid prefix with a warning.

Never a traceback, never a hang. The many-offsets sweeps call the reader directly; the command
line (``bag info|play|export``, ``launch --replay``) is run in-process for the error cases and as
real processes for playback. The reference for what a prefix holds is the ``mcap`` package's
reader on the intact file (its chunk indexes say which messages a cut keeps).
"""

from __future__ import annotations

import json
import os
import random
import subprocess
import sys

import numpy as np
import pytest
from mcap.reader import make_reader

from probeless import wire
from probeless.bag.export import export_png_dir
from probeless.bag.reader import BagReader
from probeless.bag.writer import BagWriter
from probeless.cli import main
from probeless.errors import BagError
from probeless.messages import Header, Image

T0 = 1_700_000_000_000_000_000
N = 30


def image(i: int) -> Image:
    pixels = np.random.default_rng(i).integers(0, 256, (24, 32, 3), dtype=np.uint8)  # incompressible
    return Image(Header(T0 + i, "cam", i), pixels, "rgb8")


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """A recording of our writer with several chunks: path, sent (topic, log time, payload frames), chunk indexes."""
    path = tmp_path_factory.mktemp("corrupt") / "rec.mcap"
    sent = []
    with BagWriter(path, chunk_size=12_000, compression="lz4") as w:
        for i in range(N):
            frames = wire.encode("src/image", image(i), "src", T0)
            w.write_frames(frames, log_time_ns=T0 + i * 10_000_000)
            sent.append(("src/image", T0 + i * 10_000_000, [bytes(f) for f in frames[1:]]))
    with open(path, "rb") as f:
        chunks = sorted(make_reader(f).get_summary().chunk_indexes, key=lambda c: c.chunk_start_offset)
    assert len(chunks) >= 5
    return path, sent, chunks


def read_all(path, **kw) -> tuple[BagReader, list]:
    r = BagReader(path)
    got = [(m.topic, m.log_time_ns, [bytes(f) for f in m.frames[1:]]) for m in r.messages(**kw)]
    return r, got


def summary_start(data: bytes) -> int:
    """Where the summary section starts, from the footer (opcode, length, summary_start, ...) before the magic."""
    footer = data[-8 - 29:-8]
    return int.from_bytes(footer[9:17], "little")


def kept_by_cut(chunks, sent, size: int) -> int:
    """Messages in the chunks that end before byte ``size`` (log times are distinct and increasing)."""
    ends = [c.message_end_time for c in chunks if c.chunk_start_offset + c.chunk_length <= size]
    return sum(1 for s in sent if ends and s[1] <= max(ends))


@pytest.mark.timeout(120)
def test_cut_every_997_bytes_reads_the_valid_prefix_or_fails_naming_the_file(recording, tmp_path):
    path, sent, chunks = recording
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    summary = summary_start(data)
    for size in list(range(0, len(data), 997)) + [len(data) - 1]:
        cut.write_bytes(data[:size])
        if size < 8:
            with pytest.raises(BagError, match="is not an MCAP file") as exc:
                BagReader(cut)
            assert str(cut) in str(exc.value)
            continue
        r, got = read_all(cut)
        assert got == sent[:len(got)], size                       # a prefix, bit for bit
        assert len(got) == kept_by_cut(chunks, sent, size), size  # every complete chunk, nothing more
        assert sum(t.count for t in r.topics().values()) == len(got)
        assert r.truncated and r.truncation_note, size
        if size < summary:
            assert f"of {size} bytes valid" in r.truncation_note, r.truncation_note


@pytest.mark.timeout(60)
def test_crc_mismatch_in_a_chunk_is_reported_with_the_messages_lost(recording, tmp_path):
    path, sent, chunks = recording
    c = chunks[2]
    data = bytearray(path.read_bytes())
    data[c.chunk_start_offset + c.chunk_length - 50] ^= 0x10        # inside the compressed records
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(bytes(data))
    lost = [s for s in sent if c.message_start_time <= s[1] <= c.message_end_time]
    with pytest.raises(BagError, match=f"{bad}: chunk at byte {c.chunk_start_offset} is corrupt"):
        read_all(bad)
    warnings: list[str] = []
    r, got = read_all(bad, on_corrupt=warnings.append)
    assert got == [s for s in sent if s not in lost] and len(lost) > 0
    assert len(warnings) == 1 and f"its {len(lost)} message(s)" in warnings[0] and str(bad) in warnings[0]
    summary = export_png_dir(bad, tmp_path / "png")                 # export skips it the same way
    assert summary.written == {"src/image": len(sent) - len(lost)} and summary.warnings == warnings
    # the same file without its summary: the scan stops at the bad chunk, everything before it is kept
    cut = tmp_path / "bad_cut.mcap"
    cut.write_bytes(bytes(data[:chunks[-1].chunk_start_offset + chunks[-1].chunk_length]))
    r, got = read_all(cut)
    assert got == sent[:kept_by_cut(chunks[:2], sent, c.chunk_start_offset)]
    assert f"byte {c.chunk_start_offset} is corrupt" in r.truncation_note


def test_flipped_record_length_and_flipped_summary(recording, tmp_path):
    path, sent, chunks = recording
    data = bytearray(path.read_bytes())
    summary = summary_start(data)
    flipped = bytearray(data)
    flipped[summary + 40] ^= 0x01                               # a summary byte: its CRC fails
    p = tmp_path / "summary.mcap"
    p.write_bytes(bytes(flipped))
    r, got = read_all(p)
    assert got == sent and r.truncated and "CRC" in r.truncation_note and "data is complete" in r.truncation_note
    c = chunks[3]
    flipped = bytearray(data[:summary])                         # no summary: the scan needs the lengths
    flipped[c.chunk_start_offset + 1 + 5] ^= 0x40                     # a high byte of the chunk's record length
    p = tmp_path / "length.mcap"
    p.write_bytes(bytes(flipped))
    r, got = read_all(p)
    assert got == sent[:kept_by_cut(chunks[:3], sent, c.chunk_start_offset)]
    assert f"partial chunk at byte {c.chunk_start_offset}" in r.truncation_note


@pytest.mark.timeout(120)
def test_random_bit_flips_never_give_garbage_or_a_traceback(recording, tmp_path):
    path, sent, _ = recording
    data = path.read_bytes()
    rng = random.Random(18)
    p = tmp_path / "flip.mcap"
    errors = clean = 0
    for _ in range(150):
        flipped = bytearray(data)
        pos = rng.randrange(len(data))
        flipped[pos] ^= 1 << rng.randrange(8)
        p.write_bytes(bytes(flipped))
        try:
            _, got = read_all(p, on_corrupt=lambda w: None)
        except BagError as exc:
            assert str(p) in str(exc), (pos, exc)
            errors += 1
            continue
        assert all(m in sent for m in got), pos                  # never a message that was not recorded
        clean += len(got) == len(sent)
    assert errors + clean < 150  # some flips cost messages, and those are reported rather than decoded


def cli_lines(capsys) -> tuple[str, str]:
    out = capsys.readouterr()
    return out.out, out.err


def test_cli_errors_are_one_line_naming_the_file(recording, tmp_path, capsys):
    path, sent, _ = recording
    magic = tmp_path / "magic.mcap"
    magic.write_bytes(b"\x89MCAP1\r\n" + path.read_bytes()[8:])
    empty = tmp_path / "empty.mcap"
    empty.write_bytes(b"")
    graph = tmp_path / "g.yaml"
    graph.write_text(f"nodes:\n  - id: src\n    node: nodes_for_tests:Ticker\n    inputs: {{tick: timer/hz/50}}\n"
                     f"  - id: sink\n    node: nodes_for_tests:Recorder\n    inputs: {{image: src/image}}\n"
                     f"    params: {{out: {tmp_path}/sink.json}}\n")
    for bad in (magic, empty, tmp_path):
        for argv in (["bag", "info", str(bad)], ["bag", "play", str(bad)],
                     ["bag", "export", str(bad), "-o", str(tmp_path / "x.mcap")],
                     ["launch", str(graph), "--replay", str(bad)]):
            assert main(argv) == 2, argv
            out, err = cli_lines(capsys)
            assert err.startswith("error: ") and err.count("\n") == 1 and str(bad) in err, (argv, err)
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(path.read_bytes()[:path.stat().st_size // 3])
    assert main(["bag", "info", str(cut), "--json"]) == 0
    report = json.loads(cli_lines(capsys)[0])
    assert report["warnings"] and "bytes valid" in report["warnings"][0] and str(cut) in report["warnings"][0]
    assert 0 < report["message_count"] < len(sent)
    assert main(["bag", "export", str(cut), "-o", str(tmp_path / "cut_fox.mcap")]) == 0
    out, err = cli_lines(capsys)
    assert "bytes valid" in err and f"src/image: {report['message_count']} message(s)" in out


def run_cli(*args: str, timeout: float = 240) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([os.path.dirname(os.path.dirname(__file__)),
                                                          os.environ.get("PYTHONPATH", "")])}
    return subprocess.run([sys.executable, "-m", "probeless.cli", *args], capture_output=True, text=True,
                          timeout=timeout, env=env)


@pytest.mark.graph
@pytest.mark.slow
def test_replay_of_a_cut_recording_plays_its_valid_prefix_with_a_warning(recording, tmp_path):
    path, sent, chunks = recording
    size = chunks[3].chunk_start_offset + chunks[3].chunk_length // 2
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(path.read_bytes()[:size])
    graph = tmp_path / "g.yaml"
    graph.write_text(f"nodes:\n  - id: src\n    node: nodes_for_tests:Ticker\n    inputs: {{tick: timer/hz/50}}\n"
                     f"  - id: sink\n    node: nodes_for_tests:Recorder\n"
                     f"    inputs: {{image: {{source: src/image, policy: block, queue_size: 64}}}}\n"
                     f"    params: {{out: {tmp_path}/sink.json}}\n")
    res = run_cli("launch", str(graph), "--replay", str(cut), "--rate", "0")
    assert res.returncode == 0 and "Traceback" not in res.stderr, res.stderr
    assert f"{cut}: file ends after 3 complete chunk(s) ({chunks[3].chunk_start_offset} of {size} bytes valid)" \
        in res.stderr
    got = json.loads((tmp_path / "sink.json").read_text())
    assert got["seqs"]["image"] == list(range(kept_by_cut(chunks, sent, size))) and got["seqs"]["image"]
    # a chunk failing its CRC in an indexed file: `bag play` skips it, says where and how many were lost
    data = bytearray(path.read_bytes())
    c = chunks[1]
    data[c.chunk_start_offset + c.chunk_length - 50] ^= 0x10
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(bytes(data))
    lost = sum(1 for s in sent if c.message_start_time <= s[1] <= c.message_end_time)
    res = run_cli("bag", "play", str(bad), "--rate", "0")
    out = res.stdout + res.stderr
    assert res.returncode == 0 and "Traceback" not in out, out
    assert f"chunk at byte {c.chunk_start_offset} is corrupt" in out and f"its {lost} message(s)" in out
    assert f"played {len(sent) - lost} message(s)" in out
