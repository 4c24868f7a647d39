"""Time synchronisers: analytic cases, edge cases and randomized properties."""

from __future__ import annotations

import random
from functools import lru_cache

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from probeless.messages.header import Header, Tick
from probeless.runtime.sync import ApproximateTimeSync, ExactTimeSync

MS = 1_000_000
T30 = 33_333_333  # 30 Hz period [ns]


def msg(stamp: int, uid: int = 0) -> Tick:
    """A message with a stamp; ``uid`` (in header.seq) identifies it in assertions."""
    return Tick(header=Header(stamp_ns=stamp, seq=uid), period_ns=1)


class Recorder:
    """Feeds a synchroniser and records what comes out."""

    def __init__(self, cls, names, **kw):
        self.sets: list[dict] = []
        self.dropped: list[tuple[str, int, str]] = []
        self.added = 0
        self.sync = cls(names, self.sets.append,
                        on_unmatched=lambda n, m, r: self.dropped.append((n, m.header.seq, r)), **kw)

    def feed(self, events):
        for name, stamp, uid in events:
            self.added += 1
            self.sync.add(name, msg(stamp, uid))

    def conserved(self) -> bool:
        s = self.sync
        assert s.unmatched == len(self.dropped) == sum(s.unmatched_by_reason.values())
        return s.matched * len(s.names) + s.unmatched + s.queued == self.added


def interleave(streams: dict[str, list[int]], rng: random.Random, max_latency: int) -> list:
    """Arrival order: stamp + random latency, each input kept in order. Events are (name, stamp, uid)."""
    events = []
    for name, stamps in streams.items():
        arrival = 0
        for i, stamp in enumerate(stamps):
            arrival = max(arrival, stamp + rng.randrange(max_latency + 1))
            events.append((arrival, name, stamp, hash((name, i)) & 0xFFFFFFFF))
    events.sort(key=lambda e: e[0])
    return [e[1:] for e in events]


@pytest.mark.parametrize("slop, wait", [(5 * MS, False), (5 * MS, True), (40 * MS, True)])
@pytest.mark.parametrize("seed", range(5))
def test_30hz_15hz_match_nearest_partner(slop, wait, seed):
    rng = random.Random(seed)
    jitter = 2 * MS  # |stamp error| < 2 ms on both streams, so pairs differ by < 4 ms < slop
    fast = [k * T30 + rng.randrange(-jitter + 1, jitter) for k in range(62)]
    slow = [2 * k * T30 + rng.randrange(-jitter + 1, jitter) for k in range(30)]
    rec = Recorder(ApproximateTimeSync, ["fast", "slow"], slop_ns=slop, queue_size=8, wait_for_nearest=wait)
    rec.feed(interleave({"fast": fast, "slow": slow}, rng, max_latency=50 * MS))
    rec.sync.flush()  # end of stream: the last pair may be waiting for a later 'slow' message
    pairs = [(s["fast"].header.stamp_ns, s["slow"].header.stamp_ns) for s in rec.sets]
    assert pairs == [(fast[2 * k], slow[k]) for k in range(30)]
    assert rec.sync.unmatched_by_reason.keys() <= {"no_match", "superseded", "flushed"}
    assert rec.sync.queued == 0 and rec.conserved()


@pytest.mark.parametrize("wait", [False, True])
def test_slop_smaller_than_offset_matches_nothing(wait):
    a = [k * T30 for k in range(40)]
    b = [k * T30 + 10 * MS for k in range(40)]
    rec = Recorder(ApproximateTimeSync, ["a", "b"], slop_ns=5 * MS, queue_size=4, wait_for_nearest=wait)
    rec.feed(interleave({"a": a, "b": b}, random.Random(1), max_latency=20 * MS))
    assert rec.sync.matched == 0 and rec.sets == []
    assert rec.sync.unmatched >= 78 and rec.sync.queued <= 2
    assert rec.conserved()


def test_exact_sync_matches_identical_stamps_only():
    a = [0, 10, 20, 30, 50, 60]
    b = [10, 20, 25, 40, 50, 60]
    rec = Recorder(ExactTimeSync, ["a", "b"])
    rec.feed(interleave({"a": a, "b": b}, random.Random(0), max_latency=15))
    assert [(s["a"].header.stamp_ns, s["b"].header.stamp_ns) for s in rec.sets] == [(t, t) for t in (10, 20, 50, 60)]
    assert rec.sync.unmatched == 4 and rec.sync.queued == 0  # 0, 30 of a; 25, 40 of b can never match
    assert rec.conserved()


def test_exact_sync_duplicate_overflow_and_out_of_order():
    rec = Recorder(ExactTimeSync, ["a", "b"], queue_size=2)
    rec.feed([("a", 5, 1), ("a", 5, 2), ("a", 6, 3), ("a", 7, 4)])
    assert dict(rec.sync.unmatched_by_reason) == {"duplicate": 1, "overflow": 1}
    rec.feed([("b", 7, 5), ("b", 6, 6)])  # b goes backwards: 6 < last emitted 7
    assert len(rec.sets) == 1 and rec.sync.unmatched_by_reason["out_of_order"] == 1
    assert rec.sync.unmatched_by_reason["superseded"] == 1  # a@6, older than the emitted set
    assert rec.sync.queued == 0 and rec.conserved()


def test_three_inputs():
    rec = Recorder(ApproximateTimeSync, ["rgb", "depth", "imu"], slop_ns=3, wait_for_nearest=False)
    rec.feed([("imu", 0, 1), ("imu", 5, 2), ("rgb", 9, 3), ("imu", 10, 4), ("depth", 11, 5),
              ("imu", 15, 6), ("rgb", 20, 7), ("depth", 21, 8), ("imu", 20, 9)])
    got = [{n: m.header.stamp_ns for n, m in s.items()} for s in rec.sets]
    assert got == [{"rgb": 9, "depth": 11, "imu": 10}, {"rgb": 20, "depth": 21, "imu": 20}]
    assert rec.sync.unmatched_by_reason == {"no_match": 3}  # imu 0, 5, 15
    assert rec.conserved()


@pytest.mark.parametrize("cls, kw", [(ExactTimeSync, {}), (ApproximateTimeSync, {"slop_ns": 5})])
def test_overflow_and_unknown_name(cls, kw):
    rec = Recorder(cls, ["a", "b"], queue_size=3, **kw)
    rec.feed([("a", t, t) for t in range(0, 50, 10)])
    assert rec.sync.unmatched_by_reason == {"overflow": 2} and rec.sync.queued == 3
    assert [d[1] for d in rec.dropped] == [0, 10]
    with pytest.raises(ValueError, match="unknown input 'c'"):
        rec.sync.add("c", msg(0))
    with pytest.raises(ValueError):
        cls(["a", "a"], print, **kw)


def test_approximate_out_of_order_and_flush():
    rec = Recorder(ApproximateTimeSync, ["a", "b"], slop_ns=2, wait_for_nearest=True)
    rec.feed([("a", 10, 1), ("b", 10, 2), ("a", 5, 3), ("a", 20, 4), ("b", 21, 5), ("b", 40, 6)])
    assert rec.sync.matched == 1 and rec.sync.unmatched_by_reason == {"out_of_order": 1}
    assert rec.sync.queued == 3  # waiting: a later 'a' could be nearer to 21 than 20
    rec.sync.flush()
    assert rec.sync.matched == 2 and rec.sync.unmatched_by_reason["flushed"] == 1
    assert rec.sync.queued == 0 and rec.conserved()


@lru_cache(maxsize=None)
def best_matching(streams: tuple[tuple[int, ...], ...], slop: int, idx: tuple[int, ...] = None) -> int:
    """Brute force: most disjoint sets (one message per input, span <= slop, in order per input)."""
    idx = idx or (0,) * len(streams)
    if any(i >= len(s) for i, s in zip(idx, streams)):
        return 0
    best = max(best_matching(streams, slop, idx[:k] + (idx[k] + 1,) + idx[k + 1:]) for k in range(len(idx)))
    heads = [s[i] for i, s in zip(idx, streams)]
    if max(heads) - min(heads) <= slop:
        best = max(best, 1 + best_matching(streams, slop, tuple(i + 1 for i in idx)))
    return best


def run_random(streams: list[list[int]], slop: int, queue_size: int, order: list[int], wait: bool) -> Recorder:
    names = [f"in{i}" for i in range(len(streams))]
    cursors = [0] * len(streams)
    events = []
    for k in order:  # order: which input delivers next; each input's stamps stay in order
        if cursors[k] < len(streams[k]):
            events.append((names[k], streams[k][cursors[k]], len(events)))
            cursors[k] += 1
    rec = Recorder(ApproximateTimeSync, names, slop_ns=slop, queue_size=queue_size, wait_for_nearest=wait)
    rec.feed(events)
    emitted = [m.header.seq for s in rec.sets for m in s.values()]
    assert len(emitted) == len(set(emitted)), "a message was emitted twice"
    assert not set(emitted) & {d[1] for d in rec.dropped}, "a message was both emitted and dropped"
    for s in rec.sets:
        stamps = [m.header.stamp_ns for m in s.values()]
        assert max(stamps) - min(stamps) <= slop and set(s) == set(names)
    for name in names:
        seq = [s[name].header.stamp_ns for s in rec.sets]
        assert seq == sorted(seq)
    assert rec.conserved()
    assert rec.sync.matched <= best_matching(tuple(map(tuple, streams)), slop)
    return rec


stream = st.lists(st.integers(0, 120), max_size=7).map(sorted)


@settings(max_examples=300, deadline=None)
@given(streams=st.lists(stream, min_size=1, max_size=3), slop=st.integers(0, 30),
       queue_size=st.integers(1, 6), order=st.lists(st.integers(0, 2), max_size=25), wait=st.booleans())
def test_random_invariants(streams, slop, queue_size, order, wait):
    order = [k % len(streams) for k in order] + [k for k in range(len(streams)) for _ in range(7)]
    run_random(streams, slop, queue_size, order, wait)


@settings(max_examples=300, deadline=None)
@given(data=st.data(), n_inputs=st.integers(1, 3), n_msgs=st.integers(1, 6), slop=st.integers(2, 40),
       wait=st.booleans())
@pytest.mark.slow
def test_identical_streams_with_small_jitter_all_match(data, n_inputs, n_msgs, slop, wait):
    gaps = data.draw(st.lists(st.integers(2 * slop + 1, 5 * slop), min_size=n_msgs, max_size=n_msgs))
    base = [sum(gaps[:k + 1]) for k in range(n_msgs)]
    half = (slop - 1) // 2  # |jitter| <= half < slop / 2
    jit = st.integers(-half, half)
    streams = [[b + data.draw(jit) for b in base] for _ in range(n_inputs)]
    order = data.draw(st.permutations([k for k in range(n_inputs) for _ in range(n_msgs)]))
    rec = run_random(streams, slop, n_msgs + 1, order, wait)
    rec.sync.flush()
    assert best_matching(tuple(map(tuple, streams)), slop) == n_msgs
    assert rec.sync.matched == n_msgs and rec.sync.unmatched == 0
    assert [[s[f"in{i}"].header.stamp_ns for s in rec.sets] for i in range(n_inputs)] == streams
