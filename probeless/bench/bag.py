"""``probeless bench bag``: recording throughput against a raw ``mcap`` writer, replay timing, lockstep determinism.

Three measurements, every graph run through the real :class:`~probeless.launch.launcher.Launcher`:

1. **Record.** ``bench_camera_source`` (640x480 rgb8 + 640x480 uint16 depth per tick, a 1024x1024 rgb8
   fisheye every other tick; noisy, moving, barely lz4-compressible frames made once in setup)
   recorded by the real ``bag_recorder`` (``add_recorder``: the ``launch --record`` path), for
   compression ``none`` and ``lz4``:

   * *real time*: 30 Hz ticks (fisheye 15 Hz) for 20 s (~1.9 GB; ``--quick``: 2 s). Zero loss is
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
     changes nothing. ``--quick`` (93 MB per run: a smoke test, not figures to quote) pauses 1 s.

2. **Replay timing.** ``bench_timing_source`` publishes 600 320x240 images at random 5-30 ms intervals
   (``--quick``: 60); the recording is replayed by ``bag_player`` (``add_player``) to a raw
   ``bench_timing_sink`` at ``--rate 1`` and ``--rate 2``; error = |replayed receive interval - recorded
   log-time interval / rate| per consecutive message pair, p50/p99/max in ms; errors over 1 ms are
   counted, and how many of them touch a message that starts or ends an MCAP chunk.

3. **Lockstep.** The timing recording drives two ``bench_jitter_worker`` nodes (truly random sleeps, so
   their outputs reach the recorder in a different order every run), replayed twice with
   ``lockstep: true, rate: 0`` and recorded (``add_recorder``, as ``probeless test`` does):
   ``content_digest`` of the two outputs must be identical. Twice more without lockstep (rate 4)
   shows the graph is nondeterministic (``nonlockstep_identical`` expected false).

``--json`` prints exactly one JSON object on stdout; progress and graph logs go to stderr. The
recordings live in a temporary directory and are deleted as soon as they are measured. The measurements
are :mod:`probeless.bench.bag_record` (1) and :mod:`probeless.bench.bag_replay` (2, 3); the nodes are
``probeless.nodes.bench.bag``.
"""

from __future__ import annotations

import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from probeless.bench.bag_record import (
    COLD_MEMORY_S,
    RATE_HZ,
    raw_payloads,
    run_ours_record,
    run_raw_record,
)
from probeless.bench.bag_replay import (
    NONLOCKSTEP_RATE,
    WORKER_MAX_SLEEP_MS,
    record_timing,
    replay_timing,
    replay_workers,
)
from probeless.bench.common import emit, finite_median, log, rounded

GOALS = {"record_ratio_min": 0.7, "replay_p99_ms_max": 2.0, "lockstep_identical": True, "lossless": True}
COMPRESSIONS = ("none", "lz4")
FULL = {"realtime_s": 20.0, "maxrate_ticks": 600, "reps": 3, "timing_messages": 600, "cold_memory_s": COLD_MEMORY_S}
QUICK = {"realtime_s": 2.0, "maxrate_ticks": 30, "reps": 1, "timing_messages": 60, "cold_memory_s": 1.0}


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
        payloads, types = raw_payloads(cfg["maxrate_ticks"])
        runs: dict[str, dict[str, list]] = {c: {"ours": [], "raw": []} for c in COMPRESSIONS}
        for rep in range(cfg["reps"]):
            for c in COMPRESSIONS:
                for side in (("ours", "raw") if rep % 2 == 0 else ("raw", "ours")):
                    tag = f"max-{c}-{rep}"
                    if side == "ours":
                        fig = run_ours_record(tmp, c, cfg["maxrate_ticks"], True, tag, cfg["cold_memory_s"])
                    else:
                        fig = run_raw_record(tmp, c, payloads, types, tag, cfg["cold_memory_s"])
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
                     "record_reference": "a bare mcap.writer.Writer in one process: the same messages, payload "
                                         "bytes, chunk size, compression and CRCs, written the recorder's way",
                     "raw_messages": raw[0]["messages"], "raw_payload_mb": raw[0]["bytes"] / 1e6,
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
                "nonlockstep_order_identical": ([t for t, _, _ in free[0]["order"]]
                                                == [t for t, _, _ in free[1]["order"]]),
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
                            "cold_memory_s": cfg["cold_memory_s"],
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
    from probeless.bench.common import module_main

    raise SystemExit(module_main(__spec__.name))
