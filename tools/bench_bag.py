"""``probeless bench bag``: recording throughput against a raw ``mcap`` writer, replay timing, lockstep determinism.

Three measurements, every graph run through the real :class:`~probeless.launch.launcher.Launcher`:

1. **Record.** ``CameraSource`` (640x480 rgb8 + 640x480 uint16 depth per tick, a 1024x1024 rgb8
   fisheye every other tick; noisy, moving, barely lz4-compressible frames made once in setup)
   recorded by the real ``bag_recorder`` (``add_recorder``: the ``launch --record`` path), for
   compression ``none`` and ``lz4``:

   * *real time*: 30 Hz ticks (fisheye 15 Hz) for 20 s (~1.9 GB; ``--quick``: 3 s). Zero loss is
     checked in the file: per-topic counts equal the source's publish counts, per-topic sequences
     are 0..n-1 without gaps, and there is no ``probeless.incomplete`` report.
   * *max rate*: the same message mix back to back (the recorder's ``block`` inputs throttle the
     source), so the recorder runs flat out. Sustained rate = payload bytes / (file closed - first
     message received): the recorder's whole job, queue drain and summary included, start-up not.
     Side by side in the same run (alternating order), a raw ``mcap.writer.Writer`` in this process
     writes the same messages (same payload bytes: the msgpack-framed wire frames, same chunk size,
     compression and CRCs) as fast as it can, to a file written the way the recorder writes its own
     (:class:`~probeless.bag.directio.AppendFile`: page cache bypassed with ``O_DIRECT`` where the
     file system allows, ``raw_direct_io`` in the figures), so the ratio measures the recorder, not
     a difference in file I/O. ``record_ratio`` = ours / raw (median of reps).
     CPU (user + sys) and minor page faults per payload byte are reported for both sides (ours: every
     node process, start-up and frame generation included; raw: this process during the write).

     *Cold memory.* Both sides wait ``COLD_MEMORY_S`` after the previous run's file was deleted
     before they write. On a VM with free page reporting (virtio-balloon, as on the machines this
     runs on) memory the guest freed more than ~2 s ago has been handed back to the host, and every
     page taken from it then costs a host page fault: writing 1.6 GB through the page cache
     measured 0.35-0.5 s of system time right after deleting a 1.6 GB file, 1.6-2.3 s after a 3 s
     pause. The recorder cannot start writing sooner than ~2 s after launch (node start-up), so
     without the pause a raw writer starting at once wrote into the previous file's still-warm
     pages and looked up to 4x cheaper per byte for reasons unrelated to either writer. This
     matters where files go through the page cache (no ``O_DIRECT``); on bare metal the pause
     changes nothing.

2. **Replay timing.** ``TimingSource`` publishes 600 320x240 images at random 5-30 ms intervals
   (``--quick``: 100); the recording is replayed by ``bag_player`` (``add_player``) to a raw
   ``TimingSink`` at ``--rate 1`` and ``--rate 2``; error = |replayed receive interval - recorded
   log-time interval / rate| per consecutive message pair, p50/p99/max in ms; errors over 1 ms are
   counted, and how many of them touch a message that starts or ends an MCAP chunk.

3. **Lockstep.** The timing recording drives two ``JitterWorker`` nodes (truly random sleeps, so
   their outputs reach the recorder in a different order every run), replayed twice with
   ``lockstep: true, rate: 0`` and recorded (``add_recorder``, as ``probeless test`` does):
   ``content_digest`` of the two outputs must be identical. Twice more without lockstep (rate 4)
   shows the graph is nondeterministic (``nonlockstep_identical`` expected false).

``--json`` prints exactly one JSON object on stdout; progress and graph logs go to stderr. The
recordings live in a temporary directory and are deleted as soon as they are measured.
"""

from __future__ import annotations

import inspect
import json
import os
import platform
import resource
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
from probeless.tools.bench_common import emit, finite_median, log, rounded, run_cli

GOALS = {"record_ratio_min": 0.7, "replay_p99_ms_max": 2.0, "lockstep_identical": True, "lossless": True}
COMPRESSIONS = ("none", "lz4")
NODES = "probeless.tools.bench_bag_nodes"
CAMERA_TOPICS = ("camera/rgb", "camera/depth", "camera/fisheye")
RATE_HZ = 30.0
FULL = {"realtime_s": 20.0, "maxrate_ticks": 600, "reps": 3, "timing_messages": 600}
QUICK = {"realtime_s": 3.0, "maxrate_ticks": 30, "reps": 1, "timing_messages": 100}
WORKER_MAX_SLEEP_MS = 2.0
NONLOCKSTEP_RATE = 4.0
# Seconds both sides of the max-rate comparison wait, after the previous run's file was deleted,
# before they write (see "Cold memory" in the module docstring).
COLD_MEMORY_S = 3.0




def _load(tmp: Path, name: str, text: str):
    from probeless.launch.launcher import load_checked

    path = tmp / f"{name}.yaml"
    path.write_text(text)
    return load_checked(str(path), {})


def _launch(graph, what: str, clock_node: str | None = None) -> float:
    """Run a graph to its end; its wall time [s]. RuntimeError when it fails."""
    from probeless.launch.launcher import Launcher

    t0 = time.monotonic()
    code = Launcher(graph, out=sys.stderr, ready_timeout=60.0, clock_node=clock_node).run()
    if code != 0:
        raise RuntimeError(f"{what}: graph failed (exit code {code})")
    return time.monotonic() - t0


def _unlink(path: Path) -> None:
    try:
        path.unlink()
    except FileNotFoundError:
        pass


# -- 1. record -------------------------------------------------------------------------------------
CAMERA_YAML = """\
description: recording benchmark camera (probeless bench bag)
nodes:
  - id: camera
    node: {nodes}:CameraSource
    outputs: [rgb, depth, fisheye]
    params: {{ticks: {ticks}, rate_hz: {rate}, max_rate: {max_rate}, out_path: {out}}}
"""


def _check_recording(path: Path, published: dict[str, int]) -> dict:
    """Counts, payload bytes, first log time and sequence continuity of a camera recording."""
    from probeless.bag.reader import BagReader

    with BagReader(path) as reader:
        topics = reader.topics()
        incomplete = reader.metadata().get("probeless.incomplete", {})
        seqs: dict[str, list[int]] = {t: [] for t in topics}
        for m in reader.messages(in_file_order=True):
            seqs[m.topic].append(m.sequence)
        first_ns = reader.start_ns
    recorded = {t: topics[t].count if t in topics else 0 for t in CAMERA_TOPICS}
    gaps = {t: sum(1 for i, s in enumerate(seqs.get(t, [])) if s != i) for t in CAMERA_TOPICS}
    lossless = (recorded == published and not any(gaps.values()) and not incomplete
                and set(topics) == set(CAMERA_TOPICS))
    return {"recorded": recorded, "published": published, "seq_errors": gaps, "incomplete": incomplete,
            "lossless": bool(lossless), "bytes": sum(topics[t].bytes for t in topics),
            "file_bytes": path.stat().st_size, "first_ns": first_ns, "closed_ns": path.stat().st_mtime_ns}


def run_ours_record(tmp: Path, compression: str, ticks: int, max_rate: bool, tag: str) -> dict:
    from probeless.launch.replay import add_recorder

    out = tmp / f"camera-{tag}.json"
    bag = tmp / f"camera-{tag}.mcap"
    graph = _load(tmp, f"camera-{tag}", CAMERA_YAML.format(nodes=NODES, ticks=ticks, rate=RATE_HZ,
                                                           max_rate=str(max_rate).lower(),
                                                           out=json.dumps(str(out))))
    add_recorder(graph, str(bag), topics=list(CAMERA_TOPICS),
                 params={"compression": compression, "command": "probeless bench bag"})
    os.sync()  # start from a clean page cache: no run pays for the previous run's writeback
    if max_rate:
        time.sleep(COLD_MEMORY_S)  # the same cold memory as the raw writer's (module docstring)
    ru0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    try:
        wall = _launch(graph, f"record ({compression}, {tag})")
        ended_ns = time.time_ns()  # the launcher returned: the recorder fsynced and exited
        ru = resource.getrusage(resource.RUSAGE_CHILDREN)
        src = json.loads(out.read_text())
        fig = _check_recording(bag, {f"camera/{k}": v for k, v in src["published"].items()})
    finally:
        _unlink(bag)
    # first message received -> launcher returned: includes the recorder's fsync and process teardown
    span = (ended_ns - fig["first_ns"]) / 1e9
    fig.update(wall_s=wall, record_s=span, mb_per_s=fig["bytes"] / 1e6 / span if span > 0 else float("nan"),
               publish_s=(src["last_ns"] - src["first_ns"]) / 1e9, missed_ticks=src["missed_ticks"],
               ticks=src["ticks"], close_lag_s=(fig["closed_ns"] - src["last_ns"]) / 1e9,
               cpu_s=(ru.ru_utime - ru0.ru_utime) + (ru.ru_stime - ru0.ru_stime), sys_s=ru.ru_stime - ru0.ru_stime,
               minor_faults=ru.ru_minflt - ru0.ru_minflt)
    fig["messages"] = sum(fig["recorded"].values())
    return fig


def _raw_payloads(ticks: int) -> tuple[list[tuple[str, bytes]], dict]:
    """The camera messages as the recorder stores them: msgpack-framed ``[meta, buffers...]``."""
    from probeless.tools.bench_bag_nodes import camera_frames, camera_message

    from probeless import wire
    from probeless.bag.format import pack_payload

    sizes = {"rgb": (640, 480), "depth": (640, 480), "fisheye": (1024, 1024)}
    frames = {k: camera_frames(k, *sizes[k], 8) for k in sizes}
    seq = {k: 0 for k in sizes}
    out = []
    now = time.time_ns()
    for i in range(ticks):
        for kind in ("rgb", "depth", "fisheye"):
            if kind == "fisheye" and i % 2:
                continue
            msg = camera_message(kind, frames[kind][i % 8], now)
            topic = f"camera/{kind}"
            out.append((topic, pack_payload(wire.encode(topic, msg, "camera", now, seq=seq[kind])[1:])))
            seq[kind] += 1
    types = {f"camera/{k}": (camera_message(k, frames[k][0], 0)) for k in sizes}
    return out, {t: (type(m).TYPE_NAME, type(m).VERSION, type(m)) for t, m in types.items()}


class _AppendStream:
    """The write/tell stream mcap's Writer needs, appending through the recorder's own file output
    (:class:`~probeless.bag.directio.AppendFile`: page cache bypassed where the file system allows)."""

    def __init__(self, fd: int):
        from probeless.bag.directio import AppendFile

        self.out = AppendFile(fd)

    def write(self, data) -> int:
        return self.out.write([data])

    def tell(self) -> int:
        return self.out.pos


def run_raw_record(tmp: Path, compression: str, payloads: list[tuple[str, bytes]], types: dict, tag: str) -> dict:
    """The same messages through a bare mcap Writer, as fast as possible, in this process."""
    from mcap.writer import CompressionType, Writer

    from probeless.bag.format import MESSAGE_ENCODING, PROFILE, SCHEMA_ENCODING
    from probeless.bag.schema import json_schema
    from probeless.bag.writer import BagWriter

    chunk_size = inspect.signature(BagWriter.__init__).parameters["chunk_size"].default
    ctype = {"none": CompressionType.NONE, "lz4": CompressionType.LZ4}[compression]
    path = tmp / f"raw-{tag}.mcap"
    seq: dict[str, int] = {}
    os.sync()  # start from a clean page cache, like the recorder's runs
    time.sleep(COLD_MEMORY_S)  # and from memory as cold as the recorder's (module docstring)
    try:
        ru0 = resource.getrusage(resource.RUSAGE_SELF)
        t0 = time.perf_counter()
        with open(path, "xb", buffering=0) as f:
            stream = _AppendStream(f.fileno())
            w = Writer(stream, chunk_size=chunk_size, compression=ctype, enable_crcs=True)
            w.start(profile=PROFILE, library="raw")
            channels, schemas = {}, {}
            for topic, payload in payloads:
                cid = channels.get(topic)
                if cid is None:
                    name, version, cls = types[topic]
                    if name not in schemas:
                        schemas[name] = w.register_schema(name=name, encoding=SCHEMA_ENCODING, data=json.dumps(
                            json_schema(cls), separators=(",", ":")).encode())
                    cid = channels[topic] = w.register_channel(topic=topic, message_encoding=MESSAGE_ENCODING,
                                                               schema_id=schemas[name],
                                                               metadata={"type": name, "version": str(version)})
                s = seq.get(topic, 0)
                now = time.time_ns()
                w.add_message(cid, log_time=now, data=payload, publish_time=now, sequence=s)
                seq[topic] = s + 1
            w.finish()
            direct = stream.out.direct
            stream.out.close()
            os.fsync(f.fileno())  # timed to the same point as the recorder: data on disk
        span = time.perf_counter() - t0
        ru = resource.getrusage(resource.RUSAGE_SELF)
        size = path.stat().st_size
    finally:
        _unlink(path)
    nbytes = sum(len(p) for _, p in payloads)
    return {"bytes": nbytes, "file_bytes": size, "record_s": span, "mb_per_s": nbytes / 1e6 / span,
            "messages": len(payloads), "cpu_s": (ru.ru_utime - ru0.ru_utime) + (ru.ru_stime - ru0.ru_stime),
            "sys_s": ru.ru_stime - ru0.ru_stime, "minor_faults": ru.ru_minflt - ru0.ru_minflt,
            "direct_io": direct}


# -- 2. replay timing ---------------------------------------------------------------------------------
TIMING_YAML = """\
description: replay timing benchmark (probeless bench bag)
nodes:
  - id: source
    node: {nodes}:TimingSource
    outputs: [image]
    params: {{count: {count}, min_ms: 5.0, max_ms: 30.0}}
{extra}"""

SINK_NODE = """\
  - id: sink
    node: {nodes}:TimingSink
    inputs:
      image: {{source: source/image, queue_size: 64, policy: block}}
    params: {{out_path: {out}}}
"""

WORKER_NODE = """\
  - id: {id}
    node: {nodes}:JitterWorker
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
    graph = _load(tmp, "timing-record", TIMING_YAML.format(nodes=NODES, count=count, extra=""))
    add_recorder(graph, str(bag), topics=["source/image"], params={"command": "probeless bench bag"})
    _launch(graph, "timing record")
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
    graph = _load(tmp, f"timing-replay-{rate:g}", TIMING_YAML.format(
        nodes=NODES, count=count, extra=SINK_NODE.format(nodes=NODES, out=json.dumps(str(out)))))
    add_player(graph, str(bag), recorded_types(str(bag)), params={"rate": rate})
    _launch(graph, f"replay at rate {rate:g}", clock_node=PLAYER_ID)
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
            "p99_ms_off_chunk_edges": float(np.percentile([x for x, a in zip(errs, at_edge) if not a] or [float("nan")], 99)),
            "recorded_interval_ms": {"min": float(intervals.min()), "max": float(intervals.max()),
                                     "mean": float(intervals.mean())}}


# -- 3. lockstep -------------------------------------------------------------------------------------------
def replay_workers(tmp: Path, bag: Path, count: int, lockstep: bool, tag: str) -> dict:
    from probeless.bag.compare import content_digest
    from probeless.bag.reader import BagReader
    from probeless.bag.run import recorded_types
    from probeless.launch.replay import PLAYER_ID, add_player, add_recorder

    outs = {w: tmp / f"{w}-{tag}.json" for w in ("worker_a", "worker_b")}
    extra = "".join(WORKER_NODE.format(id=w, nodes=NODES, sleep=WORKER_MAX_SLEEP_MS, op=op, out=json.dumps(str(p)))
                    for (w, p), op in zip(outs.items(), ("invert", "halve")))
    graph = _load(tmp, f"lockstep-{tag}", TIMING_YAML.format(nodes=NODES, count=count, extra=extra))
    params = {"lockstep": True, "rate": 0.0} if lockstep else {"lockstep": False, "rate": NONLOCKSTEP_RATE}
    add_player(graph, str(bag), recorded_types(str(bag)), params=params)
    out = tmp / f"outputs-{tag}.mcap"
    add_recorder(graph, str(out), diagnostics=False, skip={PLAYER_ID}, params={"command": "probeless bench bag"})
    try:
        wall = _launch(graph, f"{'lockstep' if lockstep else 'free'} replay {tag}", clock_node=PLAYER_ID)
        digest = content_digest(str(out))
        with BagReader(out) as reader:
            counts = {t: i.count for t, i in reader.topics().items()}
            order = [(m.topic, m.sequence, m.log_time_ns) for m in reader.messages(in_file_order=True)]
    finally:
        _unlink(out)
    workers = {w: json.loads(p.read_text()) for w, p in outs.items()}
    a = workers["worker_a"]
    n = a["count"]
    return {"digest": digest, "counts": counts, "order": order, "wall_s": wall,
            "ms_per_message": (a["last_ns"] - a["first_ns"]) / 1e6 / (n - 1) if n > 1 else float("nan"),
            "worker_sleep_ms": {w: v["slept_s"] * 1e3 / max(1, v["count"]) for w, v in workers.items()}}


# -- main --------------------------------------------------------------------------------------------------




def run_bench(quick: bool = False) -> dict:
    import zmq

    cfg = QUICK if quick else FULL
    t_start = time.monotonic()
    result: dict[str, Any] = {"benchmark": "bag", "quick": quick}
    with tempfile.TemporaryDirectory(prefix="pbench-bag-") as tmpname:
        tmp = Path(tmpname)

        # 1a. real time, zero loss
        ticks = round(cfg["realtime_s"] * RATE_HZ)
        realtime = {}
        for c in COMPRESSIONS:
            fig = run_ours_record(tmp, c, ticks, False, f"rt-{c}")
            realtime[c] = fig
            log(f"real time {c:>4}: {fig['messages']} msgs {fig['bytes'] / 1e6:.0f} MB in {fig['publish_s']:.2f} s, "
                f"recorder {fig['mb_per_s']:.0f} MB/s, closed {fig['close_lag_s']:.2f} s after the last publish, "
                f"{'lossless' if fig['lossless'] else 'LOSS ' + str(fig['seq_errors'])}, "
                f"missed ticks {fig['missed_ticks']}")

        # 1b. max rate, ours vs raw mcap, alternating
        payloads, types = _raw_payloads(cfg["maxrate_ticks"])
        runs: dict[str, dict[str, list]] = {c: {"ours": [], "raw": []} for c in COMPRESSIONS}
        for rep in range(cfg["reps"]):
            for c in COMPRESSIONS:
                for side in (("ours", "raw") if rep % 2 == 0 else ("raw", "ours")):
                    tag = f"max-{c}-{rep}"
                    if side == "ours":
                        fig = run_ours_record(tmp, c, cfg["maxrate_ticks"], True, tag)
                    else:
                        fig = run_raw_record(tmp, c, payloads, types, tag)
                    runs[c][side].append(fig)
                    log(f"rep {rep + 1}/{cfg['reps']} max rate {c:>4} {side:>4}: {fig['bytes'] / 1e6:.0f} MB in "
                        f"{fig['record_s']:.2f} s = {fig['mb_per_s']:.0f} MB/s"
                        + (f", {'lossless' if fig['lossless'] else 'LOSS'}" if side == "ours" else ""))
        del payloads

        # 2. replay timing
        bag, recorded, edges = record_timing(tmp, cfg["timing_messages"])
        timing = {}
        for rate in (1.0, 2.0):
            fig = replay_timing(tmp, bag, recorded, rate, edges)
            timing[f"rate_{rate:g}"] = fig
            log(f"replay rate {rate:g}: interval error p50 {fig['p50_ms']:.3f} ms p99 {fig['p99_ms']:.3f} ms "
                f"max {fig['max_ms']:.3f} ms ({fig['received']}/{fig['messages']} received; "
                f"{fig['over_1ms']} errors > 1 ms, {fig['over_1ms_at_chunk_edge']} of them at a chunk edge, "
                f"{fig['intervals_at_chunk_edge']}/{fig['intervals']} intervals touch one)")

        # 3. lockstep determinism
        n = len(recorded)
        lock = [replay_workers(tmp, bag, n, True, f"lock{i}") for i in range(2)]
        free = [replay_workers(tmp, bag, n, False, f"free{i}") for i in range(2)]
        for name, pair in (("lockstep", lock), (f"rate {NONLOCKSTEP_RATE:g} free", free)):
            log(f"{name}: digests {pair[0]['digest'][:12]} {pair[1]['digest'][:12]}, "
                f"{pair[0]['ms_per_message']:.2f} / {pair[1]['ms_per_message']:.2f} ms per message")

    # -- figures
    record = {}
    for c in COMPRESSIONS:
        ours, raw = runs[c]["ours"], runs[c]["raw"]
        o, r = finite_median([x["mb_per_s"] for x in ours]), finite_median([x["mb_per_s"] for x in raw])
        record[c] = {"ours_mb_per_s": o, "raw_mb_per_s": r, "record_ratio": o / r,
                     "record_ratio_runs": [a["mb_per_s"] / b["mb_per_s"] for a, b in zip(ours, raw)],
                     "lossless": all(x["lossless"] for x in ours), "messages": ours[0]["recorded"],
                     "payload_mb": ours[0]["bytes"] / 1e6, "file_mb": ours[0]["file_bytes"] / 1e6,
                     "raw_file_mb": raw[0]["file_bytes"] / 1e6, "raw_direct_io": raw[0]["direct_io"],
                     "ours_runs_mb_per_s": [x["mb_per_s"] for x in ours],
                     "raw_runs_mb_per_s": [x["mb_per_s"] for x in raw],
                     # CPU (user + sys) per GB of payload: ours = every node process, raw = this process
                     "ours_cpu_s_per_gb": finite_median([x["cpu_s"] / x["bytes"] * 1e9 for x in ours]),
                     "raw_cpu_s_per_gb": finite_median([x["cpu_s"] / x["bytes"] * 1e9 for x in raw]),
                     "ours_sys_s_per_gb": finite_median([x["sys_s"] / x["bytes"] * 1e9 for x in ours]),
                     "raw_sys_s_per_gb": finite_median([x["sys_s"] / x["bytes"] * 1e9 for x in raw]),
                     "ours_minor_faults_per_mb": finite_median([x["minor_faults"] / x["bytes"] * 1e6 for x in ours]),
                     "raw_minor_faults_per_mb": finite_median([x["minor_faults"] / x["bytes"] * 1e6 for x in raw])}
    rt = {"duration_s": cfg["realtime_s"], "rate_hz": RATE_HZ, "fisheye_rate_hz": RATE_HZ / 2,
          "published": {c: realtime[c]["published"] for c in COMPRESSIONS},
          "recorded": {c: realtime[c]["recorded"] for c in COMPRESSIONS},
          "lossless": all(realtime[c]["lossless"] for c in COMPRESSIONS),
          "runs": {c: {k: realtime[c][k] for k in ("publish_s", "missed_ticks", "mb_per_s", "close_lag_s",
                                                   "seq_errors", "incomplete", "lossless")}
                        | {"payload_mb": realtime[c]["bytes"] / 1e6, "file_mb": realtime[c]["file_bytes"] / 1e6,
                           "input_mb_per_s": realtime[c]["bytes"] / 1e6 / realtime[c]["publish_s"]}
                   for c in COMPRESSIONS}}
    lockstep = {"identical": lock[0]["digest"] == lock[1]["digest"] and lock[0]["counts"] == lock[1]["counts"]
                and sum(lock[0]["counts"].values()) == 2 * n,
                "digest": lock[0]["digest"], "digests": [x["digest"] for x in lock],
                "messages": n, "ms_per_message": finite_median([x["ms_per_message"] for x in lock]),
                "worker_sleep_ms_mean": statistics.mean(v for x in lock for v in x["worker_sleep_ms"].values()),
                "nonlockstep_rate": NONLOCKSTEP_RATE,
                "nonlockstep_identical": free[0]["digest"] == free[1]["digest"],
                "nonlockstep_order_identical": [t for t, _, _ in free[0]["order"]] == [t for t, _, _ in free[1]["order"]],
                "nonlockstep_digests": [x["digest"] for x in free],
                "nonlockstep_counts": [x["counts"] for x in free]}
    lossless = rt["lossless"] and all(record[c]["lossless"] for c in COMPRESSIONS) and all(
        t["complete"] for t in timing.values())
    goals_met = {
        "record_ratio": all(record[c]["record_ratio"] >= GOALS["record_ratio_min"] for c in COMPRESSIONS),
        "replay_p99": timing["rate_1"]["p99_ms"] <= GOALS["replay_p99_ms_max"],
        "lockstep_identical": lockstep["identical"],
        "lossless": lossless}
    result.update(record=record, realtime=rt, replay_timing=timing, lockstep=lockstep, lossless=lossless,
                  goals=dict(GOALS), goals_met=goals_met, meets_goals=all(goals_met.values()),
                  settings={"rgbd": "640x480 rgb8 + 640x480 uint16 depth (depth_scale 1000)",
                            "fisheye": "1024x1024 rgb8 at half the tick rate",
                            "maxrate_ticks": cfg["maxrate_ticks"], "repetitions": cfg["reps"],
                            "ours": "CameraSource -> bag_recorder (add_recorder, block inputs) via Launcher; "
                                    "payload bytes / (file closed - first receive)",
                            "raw": "mcap.writer.Writer in-process, same payloads, chunk size, compression, CRCs, "
                                   "same file output (AppendFile: O_DIRECT where possible)",
                            "statistic": f"median of {cfg['reps']} alternating repetition(s)",
                            "timing_messages": cfg["timing_messages"], "worker_max_sleep_ms": WORKER_MAX_SLEEP_MS},
                  machine={"cpus": os.cpu_count(), "python": platform.python_version(), "mcap": _version("mcap"),
                           "lz4": _version("lz4"), "pyzmq": zmq.__version__, "libzmq": zmq.zmq_version(),
                           "numpy": np.__version__, "platform": platform.platform()},
                  duration_s=time.monotonic() - t_start)
    return rounded(result)


def _version(dist: str) -> str:
    try:
        from importlib.metadata import version
        return version(dist)
    except Exception:
        return "unknown"


def print_table(result: dict) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console(file=sys.stdout)
    if not console.is_terminal:
        console = Console(file=sys.stdout, width=132)
    g = result["goals"]
    t = Table(title=f"probeless bench bag: recorder vs raw mcap Writer, max rate, median of "
                    f"{result['settings']['repetitions']} run(s)",
              caption=f"goal record_ratio >= {g['record_ratio_min']}")
    for c in ("compression", "msgs", "payload MB", "file MB", "ours MB/s", "raw MB/s", "record_ratio",
              "CPU s/GB ours/raw", "faults/MB ours/raw", "lossless"):
        t.add_column(c, justify="left" if c == "compression" else "right")
    for c, e in result["record"].items():
        t.add_row(c, str(sum(e["messages"].values())), f"{e['payload_mb']:.0f}", f"{e['file_mb']:.0f}",
                  f"{e['ours_mb_per_s']:.1f}", f"{e['raw_mb_per_s']:.1f}", f"{e['record_ratio']:.3f}",
                  f"{e['ours_cpu_s_per_gb']:.2f} / {e['raw_cpu_s_per_gb']:.2f}",
                  f"{e['ours_minor_faults_per_mb']:.0f} / {e['raw_minor_faults_per_mb']:.0f}",
                  "yes" if e["lossless"] else "NO")
    console.print(t)
    rt = result["realtime"]
    t = Table(title=f"real time: {rt['rate_hz']:g} Hz RGB-D + {rt['fisheye_rate_hz']:g} Hz fisheye for "
                    f"{rt['duration_s']:g} s")
    for c in ("compression", "published", "recorded", "payload MB", "input MB/s", "publish s", "missed ticks",
              "closed after last", "lossless"):
        t.add_column(c, justify="left" if c == "compression" else "right")
    for c, e in rt["runs"].items():
        t.add_row(c, str(sum(rt["published"][c].values())), str(sum(rt["recorded"][c].values())),
                  f"{e['payload_mb']:.0f}", f"{e['input_mb_per_s']:.1f}", f"{e['publish_s']:.2f}",
                  str(e["missed_ticks"]), f"{e['close_lag_s']:.2f} s", "yes" if e["lossless"] else "NO")
    console.print(t)
    t = Table(title="replay timing: |replayed - recorded interval / rate|",
              caption=f"goal p99 <= {g['replay_p99_ms_max']} ms at rate 1")
    for c in ("rate", "messages", "received", "p50 ms", "p99 ms", "max ms", "p99 off edges", "> 1 ms (at chunk edge)"):
        t.add_column(c, justify="right")
    for e in result["replay_timing"].values():
        t.add_row(f"{e['rate']:g}", str(e["messages"]), str(e["received"]), f"{e['p50_ms']:.3f}",
                  f"{e['p99_ms']:.3f}", f"{e['max_ms']:.3f}", f"{e['p99_ms_off_chunk_edges']:.3f}",
                  f"{e['over_1ms']} ({e['over_1ms_at_chunk_edge']}; {e['intervals_at_chunk_edge']}/{e['intervals']} "
                  f"intervals touch an edge)")
    console.print(t)
    ls = result["lockstep"]
    t = Table(title="lockstep determinism (2 workers with truly random sleeps -> recorder)")
    for c in ("mode", "identical", "digest", "ms/message"):
        t.add_column(c)
    t.add_row("lockstep, rate 0", str(ls["identical"]), ls["digest"][:16],
              f"{ls['ms_per_message']:.2f} (worker sleep {ls['worker_sleep_ms_mean']:.2f})")
    t.add_row(f"free, rate {ls['nonlockstep_rate']:g}", str(ls["nonlockstep_identical"]),
              " ".join(d[:16] for d in ls["nonlockstep_digests"]), "")
    console.print(t)
    console.print(f"meets_goals={result['meets_goals']} {result['goals_met']}, lossless={result['lossless']}, "
                  f"{result['duration_s']:.0f} s")


def main(json_out: bool = False, quick: bool = False) -> int:
    """Run the benchmark; print tables, or exactly one JSON object with ``json_out``.
    1 on any loss or a lockstep mismatch."""
    result = run_bench(quick=quick)
    emit(result, json_out, print_table)
    return 0 if result["lossless"] and result["lockstep"]["identical"] else 1


if __name__ == "__main__":
    run_cli(main, "recording benchmark: recorder vs raw mcap, replay timing, lockstep")
