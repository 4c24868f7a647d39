"""``probeless bench soak --minutes N``: bounded memory of the full pipeline run for a long time.

Runs ``launch/probeless.yaml`` (``source:=recording``) on a recording its player loops (``loop: true``),
for N minutes, with a recorder on every node's diagnostics. Meanwhile every ``--period`` seconds it
samples the launcher and every node process (:mod:`probeless.bench.soak_sample`): RSS, open file
descriptors, threads. It reports their series, their growth after warm-up and whether the goal holds
(:mod:`probeless.bench.soak_stats`: RSS growth < 5 %, no descriptor or thread growth, per process and
in total), whether messages kept flowing (each producing node's published data and each
sink's received count, from their diagnostics, grew after warm-up), and any node that exited or restarted.

The recording defaults to 2 s of ``launch/scenes/l_shaped_lounge.yaml``, rendered once (``scene render
--no-envmaps``, about 30 s) and cached as ``out/soak/lounge_2s.mcap``. ``--json`` prints one JSON
object on stdout; progress and graph logs go to stderr. ``--plot PNG`` draws RSS per process over time.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from probeless.bench.common import emit, log, rounded
from probeless.bench.soak_report import plot_rss, print_table
from probeless.bench.soak_stats import (
    GOAL_RSS_GROWTH_PCT,
    MIN_WINDOW,
    WARMUP_FRAC,
    WARMUP_MIN_S,
    WINDOW_FRAC,
    exits_and_restarts,
    goal_checks,
    health,
    summarize,
    total_series,
    warmup_s,
)
from probeless.errors import BagError, ProbelessError
from probeless.paths import REPO_ROOT

GRAPH = REPO_ROOT / "launch" / "probeless.yaml"
SCENE = REPO_ROOT / "launch" / "scenes" / "l_shaped_lounge.yaml"
RECORDING = REPO_ROOT / "out" / "soak" / "lounge_2s.mcap"
RECORDING_SECONDS = 2.0
PERIOD_S = 2.0
RATE = 0.5  # the graph's default speed for a recording: 2 shared cores keep up
QUICK_MINUTES = 1.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--minutes", type=float, default=30.0,
                        help=f"how long to run the pipeline [min] (default 30; --quick: {QUICK_MINUTES:g})")
    parser.add_argument("--recording", type=Path, default=None,
                        help=f"rig recording to loop (default: {RECORDING.relative_to(REPO_ROOT)}, "
                             "rendered if missing)")
    parser.add_argument("--rate", type=float, default=RATE, help=f"playback speed (default {RATE})")
    parser.add_argument("--period", type=float, default=PERIOD_S, help=f"sampling period [s] (default {PERIOD_S:g})")
    parser.add_argument("--plot", type=Path, default=None, metavar="PNG", help="draw RSS per process over time")


def ensure_recording(path: Path | None) -> Path:
    """The recording to loop: ``path``, or the cached default, rendered first when missing."""
    if path is not None:
        if not path.is_file():
            raise BagError(f"bench soak: --recording {path}: file not found")
        return path
    if not RECORDING.is_file():
        RECORDING.parent.mkdir(parents=True, exist_ok=True)
        log(f"rendering the recording to loop: {RECORDING}")
        cmd = [sys.executable, "-m", "probeless", "scene", "render", str(SCENE), "--duration",
               str(RECORDING_SECONDS), "--no-envmaps", "-o", str(RECORDING), "--force"]
        subprocess.run(cmd, check=True, stdout=sys.stderr, timeout=900)
    return RECORDING


def build_graph(recording: Path, rate: float, out_dir: str, diag_bag: str):
    """The full pipeline on ``recording``, looped, with a recorder on every node's diagnostics."""
    from probeless.launch.launcher import load_checked
    from probeless.launch.replay import add_recorder

    graph = load_checked(str(GRAPH), {"source": "recording", "bag": str(recording), "rate": rate,
                                      "seconds": 0.0, "out_dir": out_dir})
    graph.nodes["rig"].params["loop"] = True
    add_recorder(graph, diag_bag, topics=[f"{n}/diagnostics" for n in graph.nodes], diagnostics=True)
    return graph


def producers(plan: dict) -> set[str]:
    """Nodes of a run plan whose data outputs (not diagnostics) have subscribers."""
    return {nid for nid, spec in plan["nodes"].items()
            if any(o.get("subscribers") and not o["topic"].endswith("/diagnostics") for o in spec["outputs"].values())}


def node_activity(diag_bag: str, t0_wall: float, producing: set[str]) -> dict[str, list[tuple[float, int]]]:
    """node -> [(t [s since sampling began], work count: see :func:`activity`)] from the recorded diagnostics."""
    from probeless.bag.reader import BagReader
    from probeless.bench.soak_stats import activity

    out: dict[str, list[tuple[float, int]]] = {}
    with BagReader(diag_bag) as reader:
        for m in reader.messages():
            st = reader.decode(m)
            count = activity(st.published, [i.received for i in st.inputs], st.node_id in producing)
            out.setdefault(st.node_id, []).append((m.publish_time_ns / 1e9 - t0_wall, count))
    return out


def run_soak(minutes: float, recording: Path | None = None, rate: float = RATE, period_s: float = PERIOD_S,
             show_progress: bool = True) -> dict:
    """Run the soak; the result dict (see the module docstring)."""
    from probeless.bench.soak_sample import ProcessSampler
    from probeless.launch.launcher import Launcher
    from probeless.progress import progress

    recording = ensure_recording(recording)
    duration = minutes * 60.0
    with tempfile.TemporaryDirectory(prefix="soak-") as tmp:
        diag_bag = str(Path(tmp) / "diagnostics.mcap")
        launcher = Launcher(build_graph(recording, rate, tmp, diag_bag), duration=duration, out=sys.stderr,
                            ready_timeout=120.0)
        with progress(int(duration / period_s) + 1, f"soak, {minutes:g} min", enabled=show_progress) as tick:
            # the last sample comes before the launcher stops the graph (its duration counts from the spawn)
            sampler = ProcessSampler(period_s, on_sample=tick, until_s=duration - 1.0)
            sampler.start()
            code = launcher.run()
            wall = time.monotonic() - sampler.t0
            sampler.stop()
        activity_t = (node_activity(diag_bag, sampler.t0_wall, producers(launcher.plan))
                      if Path(diag_bag).is_file() else {})
    return analyse(sampler.series, sampler.sample_t, activity_t, duration, period_s,
                   {"graph": str(GRAPH.relative_to(REPO_ROOT)), "recording": str(recording), "loop": True,
                    "rate": rate, "wall_s": wall, "exit_code": code, "nodes": sorted(launcher.children),
                    "restarts": {n: c.restarts for n, c in launcher.children.items() if c.restarts}})


def analyse(series: dict, sample_t: list[float], activity_t: dict, duration: float, period_s: float,
            run_info: dict) -> dict:
    """Figures of a soak run from its samples (:class:`ProcessSampler`), node activity and ``run_info``
    (which must hold ``nodes``, the graph's node ids)."""
    cut = warmup_s(duration)
    completed = run_info.get("wall_s", duration) >= duration  # the launcher returns early when a node fails
    per = {name: summarize(s, cut) for name, s in sorted(series.items())}
    total = summarize(total_series(series, sample_t), cut)
    flow = health(activity_t, cut)
    events = exits_and_restarts(series, sample_t[-1] if sample_t else 0.0, period_s, set(run_info["nodes"]))
    # a process gone before warm-up ended has no growth to judge: its exit is reported (and unhealthy for a node)
    failures = [f"{n}: {f}" for n, s in per.items() if s["samples_after_warmup"] for f in s["failures"]]
    failures += [f"total: {f}" for f in total["failures"]]
    return rounded({
        "minutes": duration / 60.0, "sample_period_s": period_s, **run_info, "warmup_s": cut,
        "warmup_rule": f"first {WARMUP_FRAC:.0%} of the run, at least {WARMUP_MIN_S:g} s, at most half of it",
        "window_rule": f"medians of the first and the last {WINDOW_FRAC:.0%} of the samples after warm-up "
                       f"(at least {MIN_WINDOW})",
        "goal": {"rss_growth_pct_below": GOAL_RSS_GROWTH_PCT, "fd_growth_max": 0, "thread_growth_max": 0,
                 "meets_goal": not failures, "checks": goal_checks(per, total), "failures": failures},
        "ran_full_duration": completed,
        "healthy": flow["healthy"] and not events["exited_at_s"] and completed,
        "flow": flow, **events, "processes": per, "total": total,
        "series": {"sample_t_s": sample_t, "processes": series},
    }, 3)


def run(ns: argparse.Namespace) -> int:
    """``probeless bench soak``: figures (a table, or one JSON object); 0 (the verdicts are in the figures)."""
    minutes = QUICK_MINUTES if ns.quick and ns.minutes == 30.0 else ns.minutes
    if not minutes > 0 or not ns.period > 0:
        raise ProbelessError(f"bench soak: --minutes and --period must be > 0 (got {ns.minutes}, {ns.period})")
    result = run_soak(minutes, ns.recording, ns.rate, ns.period, show_progress=True)
    if ns.plot is not None:
        plot_rss(result, ns.plot)
        log(f"wrote {ns.plot}")
    emit(result, ns.json, print_table)
    return 0


def main(json_out: bool = False, quick: bool = False) -> int:
    """Run with the defaults (``--quick``: 1 minute)."""
    return run(argparse.Namespace(json=json_out, quick=quick, minutes=30.0, recording=None, rate=RATE,
                                  period=PERIOD_S, plot=None))


if __name__ == "__main__":
    from probeless.bench.common import module_main

    raise SystemExit(module_main(__spec__.name))
