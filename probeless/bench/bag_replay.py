"""Measurements 2 and 3 of ``probeless bench bag`` (:mod:`probeless.bench.bag`): replay timing and lockstep.

An irregular stream of ``bench_timing_source`` is recorded, then replayed by ``bag_player`` to a raw
``bench_timing_sink`` (interval errors), and to two ``bench_jitter_worker`` nodes whose outputs are
recorded with and without lockstep (content digests).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from probeless.bench.bag_record import launch_graph, load_graph, unlink

WORKER_MAX_SLEEP_MS = 2.0
NONLOCKSTEP_RATE = 4.0


# -- 2. replay timing ---------------------------------------------------------------------------------
TIMING_YAML = """\
description: replay timing benchmark (probeless bench bag)
nodes:
  - id: source
    node: bench_timing_source
    outputs: [image]
    params: {{count: {count}, min_ms: 5.0, max_ms: 30.0}}
{extra}"""

SINK_NODE = """\
  - id: sink
    node: bench_timing_sink
    inputs:
      image: {{source: source/image, queue_size: 64, policy: block}}
    params: {{out_path: {out}}}
"""

WORKER_NODE = """\
  - id: {id}
    node: bench_jitter_worker
    inputs:
      image: {{source: source/image, queue_size: 8, policy: block}}
    outputs: [image]
    params: {{max_sleep_ms: {sleep}, operation: {op}, out_path: {out}}}
"""


def record_timing(tmp: Path, count: int) -> tuple[Path, list[tuple[int, int]]]:
    """Record the irregular stream; returns the file and its (seq, log_time_ns) in log-time order."""
    from probeless.bag.reader import BagReader
    from probeless.launch.replay import add_recorder

    bag = tmp / "timing.mcap"
    graph = load_graph(tmp, "timing-record", TIMING_YAML.format(count=count, extra=""))
    add_recorder(graph, str(bag), topics=["source/image"], params={"command": "probeless bench bag"})
    launch_graph(graph, "timing record")
    with BagReader(bag) as reader:
        rec = [(m.sequence, m.log_time_ns) for m in reader.messages("source/image")]
        # log times that start or end an MCAP chunk (the player decompresses a chunk when it reaches it)
        edges = {t for c in getattr(reader, "_chunks", ()) for t in (c.start_ns, c.end_ns)}
    if len(rec) != count:
        raise RuntimeError(f"timing recording holds {len(rec)} of {count} messages")
    return bag, rec, edges


def replay_timing(tmp: Path, bag: Path, recorded: list[tuple[int, int]], rate: float,
                  edges: set[int] = frozenset()) -> dict:
    from probeless.bag.run import recorded_types
    from probeless.launch.replay import PLAYER_ID, add_player

    out = tmp / f"sink-rate{rate:g}.json"
    count = len(recorded)
    graph = load_graph(tmp, f"timing-replay-{rate:g}", TIMING_YAML.format(
        count=count, extra=SINK_NODE.format(out=json.dumps(str(out)))))
    add_player(graph, str(bag), recorded_types(str(bag)), params={"rate": rate})
    launch_graph(graph, f"replay at rate {rate:g}", clock_node=PLAYER_ID)
    got = json.loads(out.read_text())
    recv = dict(zip(got["seqs"], got["recv_ns"]))
    pairs = [(recv.get(s), t) for s, t in recorded]
    errs, at_edge = [], []
    for (r0, t0), (r1, t1) in zip(pairs, pairs[1:]):
        if r0 is not None and r1 is not None:
            errs.append(abs((r1 - r0) - (t1 - t0) / rate) / 1e6)
            at_edge.append(t0 in edges or t1 in edges)
    e = np.asarray(errs) if errs else np.asarray([float("nan")])
    intervals = np.diff([t for _, t in recorded]) / 1e6
    return {"rate": rate, "messages": count, "received": len(got["seqs"]),
            "complete": got["seqs"] == [s for s, _ in recorded],
            "p50_ms": float(np.percentile(e, 50)), "p99_ms": float(np.percentile(e, 99)), "max_ms": float(e.max()),
            "mean_ms": float(e.mean()),
            # how many errors exceed 1 ms, and how many of those touch a message that starts/ends a chunk
            "over_1ms": sum(x > 1.0 for x in errs),
            "over_1ms_at_chunk_edge": sum(x > 1.0 and a for x, a in zip(errs, at_edge)),
            "intervals_at_chunk_edge": sum(at_edge), "intervals": len(errs),
            "p99_ms_off_chunk_edges": float(np.percentile([x for x, a in zip(errs, at_edge) if not a]
                                                          or [float("nan")], 99)),
            "recorded_interval_ms": {"min": float(intervals.min()), "max": float(intervals.max()),
                                     "mean": float(intervals.mean())}}


# -- 3. lockstep -------------------------------------------------------------------------------------------
def replay_workers(tmp: Path, bag: Path, count: int, lockstep: bool, tag: str) -> dict:
    from probeless.bag.compare import content_digest
    from probeless.bag.reader import BagReader
    from probeless.bag.run import recorded_types
    from probeless.launch.replay import PLAYER_ID, add_player, add_recorder

    outs = {w: tmp / f"{w}-{tag}.json" for w in ("worker_a", "worker_b")}
    extra = "".join(WORKER_NODE.format(id=w, sleep=WORKER_MAX_SLEEP_MS, op=op, out=json.dumps(str(p)))
                    for (w, p), op in zip(outs.items(), ("invert", "halve")))
    graph = load_graph(tmp, f"lockstep-{tag}", TIMING_YAML.format(count=count, extra=extra))
    params = {"lockstep": True, "rate": 0.0} if lockstep else {"lockstep": False, "rate": NONLOCKSTEP_RATE}
    add_player(graph, str(bag), recorded_types(str(bag)), params=params)
    out = tmp / f"outputs-{tag}.mcap"
    add_recorder(graph, str(out), diagnostics=False, skip={PLAYER_ID}, params={"command": "probeless bench bag"})
    try:
        wall = launch_graph(graph, f"{'lockstep' if lockstep else 'free'} replay {tag}", clock_node=PLAYER_ID)
        digest = content_digest(str(out))
        with BagReader(out) as reader:
            counts = {t: i.count for t, i in reader.topics().items()}
            order = [(m.topic, m.sequence, m.log_time_ns) for m in reader.messages(in_file_order=True)]
    finally:
        unlink(out)
    workers = {w: json.loads(p.read_text()) for w, p in outs.items()}
    a = workers["worker_a"]
    n = a["count"]
    return {"digest": digest, "counts": counts, "order": order, "wall_s": wall,
            "ms_per_message": (a["last_ns"] - a["first_ns"]) / 1e6 / (n - 1) if n > 1 else float("nan"),
            "worker_sleep_ms": {w: v["slept_s"] * 1e3 / max(1, v["count"]) for w, v in workers.items()}}
