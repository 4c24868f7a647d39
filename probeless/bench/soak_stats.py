"""The numbers of ``probeless bench soak``: warm-up cut, growth of a sampled series, the goal, graph health.

Pure functions on plain lists, so each rule can be checked against hand-made series:

- warm-up: the first ``WARMUP_FRAC`` of the run, at least ``WARMUP_MIN_S``, at most half of it;
- RSS growth [%]: median of the last window vs median of the first window after warm-up, each window
  ``WINDOW_FRAC`` of the samples after warm-up (at least ``MIN_WINDOW`` samples), so one outlier sample
  (a frame in flight, a read-ahead thread starting) moves neither end;
- descriptor and thread growth: the smallest count of the last window minus the smallest of the first, so a
  thread that comes and goes (a read-ahead worker, a loop restart) is not growth however often it is caught,
  but one that stays open is; the window medians' difference and the peak after warm-up are reported beside it;
- the goal: RSS growth < ``GOAL_RSS_GROWTH_PCT`` and no descriptor or thread growth, per process and in total.
"""

from __future__ import annotations

import math
import statistics

WARMUP_FRAC = 0.2
WARMUP_MIN_S = 60.0
WINDOW_FRAC = 0.2
MIN_WINDOW = 3
GOAL_RSS_GROWTH_PCT = 5.0
METRICS = ("rss_mb", "fds", "threads")


def warmup_s(duration_s: float, frac: float = WARMUP_FRAC, min_s: float = WARMUP_MIN_S) -> float:
    """Seconds cut from the start of a run of ``duration_s``: ``frac`` of it, at least ``min_s``, at most half."""
    return min(max(frac * duration_s, min_s), duration_s / 2)


def window_len(n_after: int, frac: float = WINDOW_FRAC, min_len: int = MIN_WINDOW) -> int:
    """Samples in each comparison window, of ``n_after`` samples after warm-up."""
    return min(n_after, max(min_len, math.ceil(frac * n_after)))


def growth(t_s: list[float], values: list[float], cut_s: float) -> dict:
    """Growth of one series after the warm-up cut (see the module docstring); NaNs when nothing is left."""
    after = [v for t, v in zip(t_s, values) if t >= cut_s]
    if not after:
        nan = float("nan")
        return {"samples_after_warmup": 0, "at_warmup_end": nan, "first_window_median": nan,
                "last_window_median": nan, "growth_pct": nan, "window_growth": nan, "floor_growth": nan,
                "max_after_warmup_minus_start": nan}
    n = window_len(len(after))
    first, last = statistics.median(after[:n]), statistics.median(after[-n:])
    return {"samples_after_warmup": len(after), "at_warmup_end": after[0],
            "first_window_median": first, "last_window_median": last,
            "growth_pct": 100.0 * (last - first) / first if first else float("nan"),
            "window_growth": last - first, "floor_growth": min(after[-n:]) - min(after[:n]),
            "max_after_warmup_minus_start": max(after) - after[0]}


def summarize(series: dict[str, list], cut_s: float) -> dict:
    """Per-metric growth of one process's series (keys ``t_s`` and :data:`METRICS`) and its goal verdict."""
    g = {m: growth(series["t_s"], series[m], cut_s) for m in METRICS}
    out = {"rss_mb_at_warmup_end": g["rss_mb"]["at_warmup_end"],
           "rss_mb_first_window": g["rss_mb"]["first_window_median"],
           "rss_mb_last_window": g["rss_mb"]["last_window_median"],
           "rss_growth_pct": g["rss_mb"]["growth_pct"],
           "fds_at_warmup_end": g["fds"]["at_warmup_end"], "fd_growth": g["fds"]["floor_growth"],
           "fd_peak_growth": g["fds"]["max_after_warmup_minus_start"],
           "threads_at_warmup_end": g["threads"]["at_warmup_end"],
           "thread_growth": g["threads"]["floor_growth"],
           "thread_peak_growth": g["threads"]["max_after_warmup_minus_start"],
           "samples_after_warmup": g["rss_mb"]["samples_after_warmup"]}
    out["failures"] = goal_failures(out)
    out["meets_goal"] = not out["failures"]
    return out


def goal_failures(s: dict) -> list[str]:
    """What breaks the goal in one :func:`summarize` result (empty: it holds)."""
    if not s["samples_after_warmup"]:
        return ["no sample after warm-up"]
    bad = []
    if not s["rss_growth_pct"] < GOAL_RSS_GROWTH_PCT:
        bad.append(f"RSS grew {s['rss_growth_pct']:.2f} % (goal < {GOAL_RSS_GROWTH_PCT:g} %)")
    if s["fd_growth"] > 0:
        bad.append(f"open descriptors grew by {s['fd_growth']:g}")
    if s["thread_growth"] > 0:
        bad.append(f"threads grew by {s['thread_growth']:g}")
    return bad


def goal_checks(per_process: dict[str, dict], total: dict) -> dict[str, bool]:
    """Each part of the goal over a run (:func:`summarize` results of the processes sampled after warm-up and
    of the total): ``rss_per_process``, ``rss_total``, ``fds`` and ``threads`` (no growth anywhere)."""
    judged = [s for s in per_process.values() if s["samples_after_warmup"]]
    every = judged + [total]
    return {"rss_per_process": all(s["rss_growth_pct"] < GOAL_RSS_GROWTH_PCT for s in judged),
            "rss_total": bool(total["samples_after_warmup"]) and total["rss_growth_pct"] < GOAL_RSS_GROWTH_PCT,
            "fds": all(s["fd_growth"] <= 0 for s in every), "threads": all(s["thread_growth"] <= 0 for s in every)}


def total_series(per_process: dict[str, dict[str, list]], sample_t: list[float]) -> dict[str, list]:
    """Sum of every process's metrics at each sampling instant ``sample_t`` (a process adds where sampled)."""
    index = {t: i for i, t in enumerate(sample_t)}
    total = {"t_s": list(sample_t), **{m: [0.0] * len(sample_t) for m in METRICS}}
    for series in per_process.values():
        for k, t in enumerate(series["t_s"]):
            for m in METRICS:
                total[m][index[t]] += series[m][k]
    return total


def exits_and_restarts(per_process: dict[str, dict[str, list]], end_t: float, period_s: float,
                       nodes: set[str]) -> dict:
    """Nodes whose process vanished before the end (last sample over two periods before ``end_t``, the last
    sampling instant), and pid changes (restarts) of every process."""
    exited = {name: s["t_s"][-1] for name, s in per_process.items()
              if name in nodes and s["t_s"] and s["t_s"][-1] < end_t - 2 * period_s}
    restarts = {name: sum(a != b for a, b in zip(s["pid"], s["pid"][1:])) for name, s in per_process.items()}
    return {"exited_at_s": exited, "pid_changes": {n: c for n, c in restarts.items() if c}}


def activity(published: tuple[str, ...], received: list[int], producer: bool) -> int:
    """A node's work count: the data it published (``"<topic>=<count>"`` items, diagnostics left out) when it is a
    ``producer`` (its data outputs have subscribers), else what it received (a sink). A stage that keeps receiving
    but stops producing (a synchroniser stuck after the loop's time jump) is then stalled, not flowing."""
    if producer:
        return sum(int(c) for t, _, c in (p.rpartition("=") for p in published) if not t.endswith("/diagnostics"))
    return sum(received)


def health(activity_t: dict[str, list[tuple[float, int]]], cut_s: float) -> dict:
    """Did messages keep flowing after warm-up? Per node: its activity count at warm-up end and at the end.

    ``activity_t`` maps node -> [(t_s, activity)] from its diagnostics; a node is flowing when its count
    grew after the cut (a node restarted meanwhile counts from zero: it is then flowing if it counts at all).
    """
    nodes = {}
    for node, pts in sorted(activity_t.items()):
        before = [a for t, a in pts if t <= cut_s]
        start = before[-1] if before else 0
        end = pts[-1][1] if pts else 0
        after = [t for t, _ in pts if t > cut_s]
        nodes[node] = {"at_warmup_end": start, "at_end": end,
                       "flowing": bool(after) and (end > start or (end > 0 and end < start))}
    stalled = [n for n, v in nodes.items() if not v["flowing"]]
    return {"nodes": nodes, "stalled": stalled, "healthy": bool(nodes) and not stalled}
