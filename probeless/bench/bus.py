"""``probeless bench bus``: our node-to-node bus against raw pyzmq PUB/SUB, side by side, same run.

For each payload (640x480x3 and 1280x1024x3 uint8 images) and each repetition, two runs alternate
(order flipped every repetition):

* **ours**: a real graph through the real :class:`~probeless.launch.launcher.Launcher`:
  ``bench_source`` -> ``bench_sink`` (input policy ``block``, queue_size 8), two node processes
  over ipc://, messages are ``sensor/Image``.
* **raw** (:mod:`probeless.bench.bus_raw`): two plain processes with pyzmq: XPUB (XPUB_NODROP=1,
  same SNDHWM) -> SUB, ipc://, frames ``[topic, 17-byte header, payload]``, payload sent with
  ``copy=False``. Equal buffering: the raw SUB's RCVHWM is the whole buffer of our ``block`` input
  (its SUB socket's RCVHWM + its queue_size, :func:`~probeless.bench.bus_raw.subscriber_buffer`).

Each run has two phases: a back-to-back burst (throughput = (n-1) / (last - first receive time) at
the receiver, so process start-up is excluded) and, after a short pause, a paced stream (one-way
latency = receive wall time - publish wall time, both ``time.time_ns()`` on this machine). Loss is
checked on both sides: every message counted, seqs contiguous. Figures are medians over the
repetitions (5, ``--quick``: 1); ``throughput_ratio`` = ours / raw of the medians (reference named in
``throughput_reference``),
``latency_added_*_ms`` = ours - raw.

``--json`` prints exactly one JSON object on stdout; progress and graph logs go to stderr.
"""

from __future__ import annotations

import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from probeless.bench.bus_raw import GAP_S, run_raw, subscriber_buffer
from probeless.bench.common import emit, finite_median, log, rounded

GOALS = {"throughput_ratio_min": 0.8, "latency_added_p50_ms_max": 0.3}
QUEUE_SIZE = 8

# name, width, height, throughput messages, latency messages, latency rate [Hz]
PAYLOADS_FULL = (("640x480x3", 640, 480, 2000, 500, 200.0),
                 ("1280x1024x3", 1280, 1024, 600, 500, 100.0))
PAYLOADS_QUICK = (("640x480x3", 640, 480, 200, 50, 200.0),
                  ("1280x1024x3", 1280, 1024, 60, 50, 100.0))


# -- ours: a real graph through the Launcher ----------------------------------------------------
GRAPH_YAML = """\
description: bus benchmark (probeless bench bus)
nodes:
  - id: source
    node: bench_source
    outputs: [image]
    params: {{width: {w}, height: {h}, count: {n}, paced_count: {m}, rate_hz: {rate}, gap_s: {gap}}}
  - id: sink
    node: bench_sink
    inputs:
      image: {{source: source/image, queue_size: {q}, policy: block}}
    params: {{out_path: {out}}}
"""


def run_ours(cfg: tuple, tmp: Path, tag: str) -> dict:
    from probeless.launch.launcher import Launcher, load_checked

    name, w, h, n, m, rate = cfg
    out = tmp / f"ours-{tag}.json"
    graph_file = tmp / f"bench-{tag}.yaml"
    graph_file.write_text(GRAPH_YAML.format(w=w, h=h, n=n, m=m, rate=rate, gap=GAP_S, q=QUEUE_SIZE,
                                            out=json.dumps(str(out))))
    graph = load_checked(str(graph_file), {})
    code = Launcher(graph, out=sys.stderr, ready_timeout=60.0).run()
    if code != 0 or not out.exists():
        raise RuntimeError(f"bench graph failed (exit code {code}, results {'present' if out.exists() else 'missing'})")
    return json.loads(out.read_text())


# -- analysis ---------------------------------------------------------------------------------------
def _seq_check(seqs: list[int]) -> tuple[int, int]:
    """(gaps, out_of_order_or_duplicate) of a received seq sequence."""
    gaps = disorder = 0
    for a, b in zip(seqs, seqs[1:]):
        if b > a + 1:
            gaps += b - a - 1
        elif b <= a:
            disorder += 1
    return gaps, disorder


def analyze(res: dict, cfg: tuple) -> dict:
    """Figures of one run: throughput of the burst phase, latency of the paced phase, loss."""
    name, w, h, n, m, rate = cfg
    nbytes = w * h * 3
    tput, lat = res["phases"]["tput"], res["phases"]["lat"]
    out: dict[str, Any] = {}
    recv = tput["recv_ns"]
    span = (recv[-1] - recv[0]) / 1e9 if len(recv) > 1 else 0.0
    out["msgs_per_s"] = (len(recv) - 1) / span if span > 0 else float("nan")
    out["mb_per_s"] = out["msgs_per_s"] * nbytes / 1e6
    lat_ms = (np.asarray(lat["recv_ns"], np.int64) - np.asarray(lat["stamp_ns"], np.int64)) / 1e6
    if lat_ms.size:
        out["latency_p50_ms"], out["latency_p99_ms"] = (float(x) for x in np.percentile(lat_ms, [50, 99]))
    else:
        out["latency_p50_ms"] = out["latency_p99_ms"] = float("nan")
    seqs = tput["seqs"] + lat["seqs"]
    gaps, disorder = _seq_check(seqs)
    expected = n + m
    received = len(seqs)
    missing_tail = 0 if not seqs else max(0, expected - 1 - seqs[-1])
    out.update(expected=expected, received=received, seq_gaps=gaps + missing_tail + (seqs[0] if seqs else 0),
               out_of_order=disorder, bad_shape=res.get("bad_shape", 0) + res.get("other", 0),
               received_tput=len(recv), received_lat=int(lat_ms.size))
    out["lossless"] = (received == expected and out["seq_gaps"] == 0 and disorder == 0
                       and out["bad_shape"] == 0 and len(recv) == n and lat_ms.size == m)
    return out


def _median(runs: list[dict], key: str) -> float:
    return finite_median([r[key] for r in runs])


def summarize_side(runs: list[dict]) -> dict:
    s = {k: _median(runs, k) for k in ("msgs_per_s", "mb_per_s", "latency_p50_ms", "latency_p99_ms")}
    s.update(expected=sum(r["expected"] for r in runs), received=sum(r["received"] for r in runs),
             seq_gaps=sum(r["seq_gaps"] for r in runs), out_of_order=sum(r["out_of_order"] for r in runs),
             lossless=all(r["lossless"] for r in runs), runs=runs)
    return s


# -- main -----------------------------------------------------------------------------------------------
def run_bench(quick: bool = False, reps: int | None = None) -> dict:
    import zmq

    payloads = PAYLOADS_QUICK if quick else PAYLOADS_FULL
    reps = reps or (1 if quick else 5)
    runs: dict[str, dict[str, list]] = {p[0]: {"ours": [], "raw": []} for p in payloads}
    t_start = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="pbench-") as tmpname:
        tmp = Path(tmpname)
        for rep in range(reps):
            for cfg in payloads:
                order = ("ours", "raw") if rep % 2 == 0 else ("raw", "ours")
                for side in order:
                    tag = f"{cfg[0]}-{rep}"
                    t0 = time.monotonic()
                    res = (run_ours(cfg, tmp, tag) if side == "ours"
                           else run_raw(cfg, tmp, tag, subscriber_buffer(QUEUE_SIZE)))
                    fig = analyze(res, cfg)
                    runs[cfg[0]][side].append(fig)
                    log(f"rep {rep + 1}/{reps} {cfg[0]:>11} {side:>4}: {fig['msgs_per_s']:8.1f} msg/s "
                        f"{fig['mb_per_s']:8.1f} MB/s  latency p50 {fig['latency_p50_ms']:.3f} ms "
                        f"p99 {fig['latency_p99_ms']:.3f} ms  {fig['received']}/{fig['expected']} received, "
                        f"{fig['seq_gaps']} gaps  ({time.monotonic() - t0:.1f} s)")
    result: dict[str, Any] = {"benchmark": "bus", "quick": quick, "repetitions": reps, "payloads": {}}
    meets = True
    lossless = True
    for name, w, h, n, m, rate in payloads:
        ours, raw = summarize_side(runs[name]["ours"]), summarize_side(runs[name]["raw"])
        entry = {"bytes": w * h * 3, "throughput_messages": n, "latency_messages": m, "latency_rate_hz": rate,
                 "ours": ours, "raw": raw,
                 "throughput_ratio": ours["msgs_per_s"] / raw["msgs_per_s"],
                 "latency_added_p50_ms": ours["latency_p50_ms"] - raw["latency_p50_ms"],
                 "latency_added_p99_ms": ours["latency_p99_ms"] - raw["latency_p99_ms"],
                 # per repetition, ours / the raw run next to it in time (drift cancels, noise shows)
                 "throughput_ratio_runs": [o["msgs_per_s"] / r["msgs_per_s"]
                                           for o, r in zip(ours["runs"], raw["runs"])]}
        entry["meets_goals"] = bool(entry["throughput_ratio"] >= GOALS["throughput_ratio_min"]
                                    and entry["latency_added_p50_ms"] <= GOALS["latency_added_p50_ms_max"])
        meets &= entry["meets_goals"]
        lossless &= ours["lossless"] and raw["lossless"]
        result["payloads"][name] = entry
    buffer = subscriber_buffer(QUEUE_SIZE)
    result.update(goals=dict(GOALS), meets_goals=bool(meets), lossless=bool(lossless),
                  throughput_reference="raw pyzmq XPUB(NODROP) -> SUB, same payloads, same ipc:// transport, "
                                       "same send and receive buffers",
                  subscriber_buffer_messages={"ours": buffer, "raw": buffer,
                                              "ours_split": f"SUB RCVHWM {buffer - QUEUE_SIZE} + input queue "
                                                            f"{QUEUE_SIZE}", "raw_split": f"SUB RCVHWM {buffer}"},
                  settings={"transport": "ipc", "policy": "block", "queue_size": QUEUE_SIZE,
                            "raw": "XPUB(NODROP) -> SUB, [topic, header, payload], payload copy=False",
                            "throughput": "(n-1) / (last - first receive) of a back-to-back burst",
                            "latency": "receive - publish wall time of a paced stream",
                            "statistic": f"median of {reps} alternating repetition(s)"},
                  machine={"cpus": os.cpu_count(), "python": platform.python_version(),
                           "pyzmq": zmq.__version__, "libzmq": zmq.zmq_version(), "numpy": np.__version__,
                           "platform": platform.platform()},
                  duration_s=time.monotonic() - t_start)
    return rounded(result)


def print_table(result: dict) -> None:
    goals = result["goals"]
    title = (f"probeless bench bus: ours (Launcher graph) vs raw pyzmq, median of {result['repetitions']} "
             f"run(s), ipc://")
    header = ["payload", "side", "msgs/s", "MB/s", "lat p50 ms", "lat p99 ms", "received", "lossless"]
    rows = []
    for name, e in result["payloads"].items():
        for side in ("ours", "raw"):
            s = e[side]
            rows.append([name, side, f"{s['msgs_per_s']:.1f}", f"{s['mb_per_s']:.1f}", f"{s['latency_p50_ms']:.3f}",
                         f"{s['latency_p99_ms']:.3f}", f"{s['received']}/{s['expected']}",
                         "yes" if s["lossless"] else f"NO ({s['seq_gaps']} gaps)"])
        rows.append([name, "ours/raw", f"ratio {e['throughput_ratio']:.3f}", "",
                     f"{e['latency_added_p50_ms']:+.3f}", f"{e['latency_added_p99_ms']:+.3f}", "",
                     "meets goals" if e["meets_goals"] else "MISSES goals"])
    foot = (f"goals: throughput_ratio >= {goals['throughput_ratio_min']}, latency_added_p50_ms <= "
            f"{goals['latency_added_p50_ms_max']} -> meets_goals={result['meets_goals']}, "
            f"lossless={result['lossless']}")
    try:
        from rich.console import Console
        from rich.table import Table
    except ImportError:
        print(title)
        print("  ".join(f"{c:>12}" for c in header))
        for r in rows:
            print("  ".join(f"{c:>12}" for c in r))
        print(foot)
        return
    table = Table(title=title, caption=foot)
    for i, c in enumerate(header):
        table.add_column(c, justify="left" if i < 2 else "right")
    for i, r in enumerate(rows):
        table.add_row(*r, end_section=(i % 3 == 2))
    console = Console(file=sys.stdout)
    if not console.is_terminal:
        console = Console(file=sys.stdout, width=132)
    console.print(table)


def main(json_out: bool = False, quick: bool = False) -> int:
    """Run the benchmark; print a table, or exactly one JSON object with ``json_out``. 1 on any loss."""
    result = run_bench(quick=quick)
    emit(result, json_out, print_table)
    return 0 if result["lossless"] else 1


if __name__ == "__main__":
    from probeless.bench.common import module_main

    raise SystemExit(module_main(__spec__.name))
