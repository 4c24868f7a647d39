"""Input queues are bounded in bytes as well as messages; the memory watch tells a leak from a plateau."""

from __future__ import annotations

import numpy as np
import pytest

from probeless.runtime.memwatch import MemoryWatch, rss_bytes
from probeless.runtime.queues import InputQueue

MB = 1 << 20


@pytest.mark.parametrize("policy", ["drop_oldest", "latest"])
def test_dropping_queue_stays_under_its_byte_bound(policy):
    q = InputQueue("image", policy, queue_size=100 if policy == "drop_oldest" else 1, max_bytes=10 * MB)
    for i in range(50):
        q.push(i, i, seq=i, nbytes=3 * MB)
        assert q.queued_bytes <= 10 * MB
    assert q.peak_bytes <= 10 * MB
    kept = [m for _, m in q.items]
    expect = [47, 48, 49] if policy == "drop_oldest" else [49]   # the newest that fit: 3 x 3 MB <= 10 MB
    assert kept == expect
    assert q.dropped == 50 - len(expect) and q.received == 50


def test_block_queue_refuses_when_bytes_would_exceed_and_takes_one_big_message_when_empty():
    q = InputQueue("cloud", "block", queue_size=100, max_bytes=10 * MB)
    assert q.push(0, "a", 0, nbytes=6 * MB)
    assert not q.push(1, "b", 1, nbytes=6 * MB)        # would make 12 MB: backpressure, nothing dropped
    assert q.dropped == 0 and q.received == 1
    assert q.pop() == "a" and q.queued_bytes == 0
    assert q.push(2, "huge", 1, nbytes=64 * MB)         # larger than the bound, but alone: never a deadlock
    assert q.full


def test_seq_restart_is_counted_not_mistaken_for_a_gap():
    q = InputQueue("x", "drop_oldest", queue_size=100)
    for s in [0, 1, 2, 5, 6, 0, 1, 3]:
        q.push(s, s, seq=s)
    assert q.seq_gaps == 2 + 1 and q.restarts == 1


def _feed(watch: MemoryWatch, values) -> None:
    for v in values:
        watch.sample(int(v))


def test_memory_watch_flags_a_steady_leak_but_not_a_plateau_or_spikes():
    rng = np.random.default_rng(0)
    n = 60 + 30 * 8
    base = 400 * MB
    leak = MemoryWatch()
    _feed(leak, base + np.arange(n) * 0.5 * MB + rng.uniform(0, 5 * MB, n))   # +0.5 MB/s
    assert leak.growing and "rising without bound" in leak.describe()

    plateau = MemoryWatch()   # warm-up growth, then flat with big transient spikes (a frame decoded, then freed)
    values = np.concatenate([np.linspace(100 * MB, base, 60), np.full(n - 60, base)])
    values[rng.integers(60, n, 40)] += 300 * MB
    _feed(plateau, values)
    assert not plateau.growing

    small = MemoryWatch()     # rising, but by less than 32 MiB in all: allocator noise, not a leak
    _feed(small, base + np.arange(n) * 0.05 * MB)
    assert not small.growing


def test_rss_of_this_process_matches_psutil():
    import psutil
    ours, theirs = rss_bytes(), psutil.Process().memory_info().rss
    assert abs(ours - theirs) < 0.05 * theirs


def test_an_inputs_byte_bound_travels_from_the_graph_to_the_node_queue(tmp_path):
    from probeless.launch.launcher import load_checked
    from probeless.launch.plan import build_plan
    from probeless.runtime.process import NodeRuntime

    g = tmp_path / "g.yaml"
    g.write_text("""nodes:
  - id: camera
    node: pattern_source
    inputs: {tick: timer/hz/10}
  - id: sink
    node: summary_sink
    inputs:
      image: {source: camera/image, max_bytes: 5000000}
""")
    plan = build_plan(load_checked(str(g), {}), tmp_path)
    runtime = NodeRuntime(plan, "sink", "inproc://wake-test")
    try:
        assert runtime.queues["image"].max_bytes == 5_000_000
    finally:
        runtime.zctx.term()
