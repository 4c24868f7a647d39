"""Disk full while recording: a clear error naming the file, a file readable to its last complete chunk, and (with
real processes) the rest of the graph running on. Records onto a small tmpfs mounted by the test (needs root)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from faults_common import node_env
from mcap.reader import make_reader

from probeless.bag.reader import BagReader
from probeless.bag.writer import BagWriter
from probeless.errors import BagError
from probeless.messages import Header, Image
from probeless.wire import encode

TMPFS_BYTES = 8 << 20


@pytest.fixture
def small_disk(tmp_path):
    """An 8 MiB tmpfs at ``tmp_path/disk``, unmounted afterwards."""
    mnt = tmp_path / "disk"
    mnt.mkdir()
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={TMPFS_BYTES}", "tmpfs", str(mnt)],
                          capture_output=True, text=True, timeout=30)
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here (needs root and CAP_SYS_ADMIN): {done.stderr.strip()}")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], capture_output=True, timeout=30)


def _noise(i: int) -> Image:
    """A 256x256 rgb8 frame of random bytes (incompressible), frame index in the header."""
    data = np.random.default_rng(i).integers(0, 256, (256, 256, 3), np.uint8)
    return Image(Header(i * 1_000_000, "cam"), data, "rgb8")


def _mcap_package_messages(path: Path) -> list[tuple[str, int]]:
    """(topic, sequence) of every message, read by the ``mcap`` package (the independent reader)."""
    with open(path, "rb") as f:
        return [(ch.topic, m.sequence) for _, ch, m in make_reader(f).iter_messages(log_time_order=False)]


def test_writer_stops_at_disk_full_and_leaves_a_file_every_reader_reads(small_disk):
    path = small_disk / "full.mcap"
    writer = BagWriter(path, compression="none", chunk_size=1 << 20, metadata={"probeless.graph": {"command": "x"}})
    written = 0
    with pytest.raises(BagError) as err:
        for i in range(10_000):  # 196 KiB each: the 8 MiB disk is full long before
            writer.write_frames(encode("cam/image", _noise(i), "cam", i, seq=i), log_time_ns=i * 1_000_000)
            written += 1
    assert written < 60  # it failed because the disk filled, not later
    message = str(err.value)
    assert str(path) in message and "No space left on device (disk full)" in message
    size = path.stat().st_size
    with pytest.raises(BagError, match="disk full"):
        writer.close()  # says it again, and writes nothing more
    with pytest.raises(BagError, match="disk full"):
        writer.write_frames(encode("cam/image", _noise(0), "cam", 0, seq=0), log_time_ns=0)
    assert path.stat().st_size == size

    ours = BagReader(path)
    seqs = [m.sequence for m in ours.messages("cam/image")]
    assert len(seqs) > 10 and seqs == list(range(len(seqs)))  # a clean prefix: whole chunks of 1 MiB
    # lost: only what was in the writer's 3 chunk buffers (being written, queued, filling) when the disk filled
    assert written - len(seqs) <= 3 * (1 + (1 << 20) // (256 * 256 * 3))
    assert ours.decode(next(iter(ours.messages("cam/image")))).data.shape == (256, 256, 3)
    assert "disk full" in ours.metadata()["probeless.incomplete"]["recording"]
    theirs = _mcap_package_messages(path)  # the mcap package reads the sealed file to its end, no error
    assert theirs == [("cam/image", s) for s in seqs]
    assert path.stat().st_size <= TMPFS_BYTES


@pytest.mark.parametrize("direct_io", [False, True])
def test_a_failed_write_leaves_the_file_ending_at_its_last_complete_record(tmp_path, monkeypatch, direct_io):
    """Where not even the footer fits, the file is cut back to its complete chunks (read as truncated), with
    page-cache writes and with O_DIRECT block writes (where the file system allows them)."""
    import probeless.bag.directio as directio

    path = tmp_path / "cut.mcap"
    writer = BagWriter(path, compression="none", chunk_size=1 << 20, direct_io=direct_io)
    if direct_io and not writer.direct_io:
        pytest.skip(f"{tmp_path}: the file system refuses O_DIRECT")
    real = os.pwritev
    state = {"budget": 3 << 20}  # bytes the "disk" still takes

    def pwritev(fd, views, offset):
        n = sum(memoryview(v).nbytes for v in views)
        if n > state["budget"]:
            real(fd, [memoryview(views[0])[:state["budget"] // 8192 * 4096]], offset)  # a partial write first ...
            state["budget"] = 0
            raise OSError(28, "No space left on device")  # ... then ENOSPC, as a full disk does
        state["budget"] -= n
        return real(fd, views, offset)

    monkeypatch.setattr(directio.os, "pwritev", pwritev)
    with pytest.raises(BagError, match=r"cut\.mcap: No space left on device \(disk full\).*no room left for its"):
        for i in range(200):
            writer.write_frames(encode("cam/image", _noise(i), "cam", i, seq=i), log_time_ns=i * 1_000_000)
    monkeypatch.setattr(directio.os, "pwritev", real)
    reader = BagReader(path)
    seqs = [m.sequence for m in reader.messages("cam/image")]
    assert reader.truncated and len(seqs) >= 10 and seqs == list(range(len(seqs)))
    assert "partial" not in reader.truncation_note  # the partial chunk was cut off, not left to skip


GRAPH = """
nodes:
  - id: cam
    node: pattern_source
    inputs: {{tick: timer/hz/60}}
    params: {{width: 320, height: 240}}
  - id: sink
    node: nodes_for_tests:Recorder
    inputs: {{image: cam/image}}
    params: {{out: {out}}}
"""


@pytest.mark.graph
@pytest.mark.slow
@pytest.mark.timeout(300)
def test_recording_graph_fills_the_disk_and_the_graph_runs_on(small_disk, tmp_path, short_run_dir):
    g = tmp_path / "g.yaml"
    g.write_text(GRAPH.format(out=tmp_path / "sink.json"))
    out = small_disk / "run.mcap"
    env = dict(node_env(), PROBELESS_RUN_DIR=str(short_run_dir))
    proc = subprocess.Popen([sys.executable, "-m", "probeless.cli", "launch", str(g), "--record", str(out),
                             "--compression", "none"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            env=env)
    lines: list[str] = []
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:  # 60 frames/s of 225 KiB fill 8 MiB in about a second
            line = proc.stdout.readline()
            if not line:
                break
            lines.append(line)
            if "No space left on device" in line:
                break
        failed_at = time.monotonic()
        time.sleep(2.0)  # the graph runs on for 2 s after the recorder failed
        assert proc.poll() is None, "".join(lines)
        proc.send_signal(signal.SIGINT)
        rest, _ = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate(timeout=30)
    log = "".join(lines) + rest
    error = next((ln for ln in log.splitlines() if "No space left on device" in ln), None)
    assert error is not None, log
    assert "ERROR" in error and str(out) in error and "disk full" in error
    assert "Traceback" not in log
    assert proc.returncode != 0  # the recording is incomplete: the launch says so at the end
    assert time.monotonic() - failed_at < 60

    seqs = [m.sequence for m in BagReader(out).messages("cam/image")]
    assert len(seqs) > 5 and seqs == list(range(len(seqs)))
    assert [s for t, s in _mcap_package_messages(out) if t == "cam/image"] == seqs
    sink = json.loads((tmp_path / "sink.json").read_text())["seqs"]["image"]
    assert max(sink) >= seqs[-1] + 60  # the camera and the sink went on for > 1 s (60 Hz) after the failure
