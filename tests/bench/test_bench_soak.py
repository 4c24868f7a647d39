"""``probeless bench soak``: its growth rules on hand-made series (analytic values), its sampler against a real
process whose memory, descriptors and threads grow by known amounts, and the CI run of the full pipeline."""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import textwrap

import pytest

from probeless.bench import soak
from probeless.bench.soak import analyse
from probeless.bench.soak_sample import ProcessSampler, node_id_of
from probeless.bench.soak_stats import exits_and_restarts, growth, health, summarize, total_series, warmup_s
from probeless.errors import BagError, ProbelessError
from probeless.paths import REPO_ROOT


def _series(t, rss, fds=None, threads=None, pid=None) -> dict:
    n = len(t)
    return {"t_s": list(t), "pid": pid or [1] * n, "rss_mb": list(rss), "fds": fds or [10] * n,
            "threads": threads or [4] * n}


def test_warmup_cut_is_a_fifth_at_least_a_minute_at_most_half():
    assert warmup_s(30 * 60) == 360.0       # 20 % of 30 min
    assert warmup_s(2 * 60) == 60.0         # the minute floor
    assert warmup_s(60) == 30.0             # never more than half the run


def test_growth_of_a_linear_ramp_is_the_analytic_window_medians():
    # v = 100 + t at t = 0..99 s, cut at 20 s: 80 samples after, windows of 16;
    # first window t = 20..35 (median 27.5), last t = 84..99 (median 91.5)
    t = list(range(100))
    g = growth(t, [100.0 + x for x in t], 20.0)
    assert g["samples_after_warmup"] == 80
    assert g["first_window_median"] == pytest.approx(127.5)
    assert g["last_window_median"] == pytest.approx(191.5)
    assert g["growth_pct"] == pytest.approx(100 * 64 / 127.5)
    assert g["at_warmup_end"] == 120.0 and g["max_after_warmup_minus_start"] == 79.0
    assert g["window_growth"] == pytest.approx(64.0)


def test_one_outlier_sample_moves_neither_window_but_a_step_does():
    t = list(range(60))
    spike = [100.0] * 60
    spike[-1] = 200.0       # a frame in flight at the last sample
    spike[30] = 300.0
    assert growth(t, spike, 10.0)["growth_pct"] == 0.0
    step = [100.0] * 40 + [110.0] * 20      # a real step up that stays
    assert growth(t, step, 10.0)["growth_pct"] == pytest.approx(10.0)


def test_goal_names_what_grew():
    t = list(range(50))
    ok = summarize(_series(t, [100.0] * 50), 10.0)
    assert ok["meets_goal"] and ok["failures"] == []
    fds = [10] * 30 + [11] * 20             # one descriptor more, kept open
    leak = summarize(_series(t, [100.0 + 0.5 * x for x in t], fds=fds, threads=[4] * 35 + [5] * 15), 10.0)
    assert not leak["meets_goal"]
    assert leak["fd_growth"] == 1 and leak["thread_growth"] == 1
    # a worker thread alive for the last sample only (CI saw this in the player) is a peak, not growth
    blip = summarize(_series(t, [100.0] * 50, threads=[4] * 49 + [5]), 10.0)
    assert blip["meets_goal"] and blip["thread_growth"] == 0 and blip["thread_peak_growth"] == 1
    # one that comes and goes, caught in half the last window's samples (CI saw "grew by 0.5" from medians)
    flicker = summarize(_series(t, [100.0] * 50, threads=[4] * 40 + [5, 4] * 5), 10.0)
    assert flicker["meets_goal"] and flicker["thread_growth"] == 0
    text = " ".join(leak["failures"])
    assert "RSS grew" in text and "descriptors grew by 1" in text and "threads grew by 1" in text


def test_total_sums_processes_at_each_instant_and_exits_and_restarts_are_found():
    a = _series([0, 2, 4, 6], [10, 10, 10, 10], pid=[5, 5, 9, 9])      # restarted once
    b = _series([0, 2], [1, 2])                                       # gone after t = 2 s
    total = total_series({"a": a, "b": b}, [0, 2, 4, 6])
    assert total["rss_mb"] == [11, 12, 10, 10] and total["fds"] == [20, 20, 10, 10]
    ev = exits_and_restarts({"a": a, "b": b, "helper:7": _series([0], [1])}, 6.0, 1.0, {"a", "b"})
    assert ev == {"exited_at_s": {"b": 2}, "pid_changes": {"a": 1}}


def test_health_finds_a_node_whose_counts_stopped():
    flow = health({"rig": [(10, 100), (50, 400), (90, 800)], "sink": [(10, 5), (50, 40), (90, 40)]}, 50.0)
    assert flow["nodes"]["rig"]["flowing"] and not flow["nodes"]["sink"]["flowing"]
    assert flow["stalled"] == ["sink"] and flow["healthy"] is False


def test_analyse_fails_the_goal_for_the_leaking_process_only():
    t = [float(x) for x in range(0, 300, 2)]
    series = {"slam": _series(t, [500.0] * len(t)), "rig": _series(t, [50.0 + 0.1 * x for x in t])}
    r = analyse(series, t, {"slam": [(x, int(x)) for x in t]}, 300.0, 2.0,
                {"nodes": ["slam", "rig"], "exit_code": 0})
    assert r["warmup_s"] == 60.0
    assert r["processes"]["slam"]["meets_goal"] and not r["processes"]["rig"]["meets_goal"]
    assert [f.split(":")[0] for f in r["goal"]["failures"]] == ["rig"]
    assert r["goal"]["meets_goal"] is False and r["healthy"] is True
    assert r["goal"]["checks"] == {"rss_per_process": False, "rss_total": True, "fds": True, "threads": True}
    stopped = analyse(series, t, {"slam": [(x, int(x)) for x in t]}, 300.0, 2.0,
                      {"nodes": ["slam", "rig"], "exit_code": 1, "wall_s": 200.0})
    assert stopped["ran_full_duration"] is False and stopped["healthy"] is False
    assert json.loads(json.dumps(r)) == r   # the JSON output as is


def test_bad_options_are_refused_naming_the_option(tmp_path):
    ns = argparse.Namespace(json=True, quick=False, minutes=0.0, recording=None, rate=0.5, period=2.0, plot=None)
    with pytest.raises(ProbelessError, match="--minutes"):
        soak.run(ns)
    missing = tmp_path / "no.mcap"
    with pytest.raises(BagError, match=f"--recording {missing}: file not found"):
        soak.run(argparse.Namespace(**{**vars(ns), "minutes": 1.0, "recording": missing}))


def test_node_id_is_read_from_a_node_command_line():
    cmd = [sys.executable, "-u", "-m", "probeless.runtime.process", "/tmp/run-x", "slam"]
    assert node_id_of(cmd) == "slam"
    assert node_id_of([sys.executable, "-m", "probeless", "launch", "g.yaml"]) is None
    assert node_id_of(["probeless.runtime.process"]) is None


GROWER = textwrap.dedent("""
    import os, sys, threading, time
    print("ready", flush=True)
    time.sleep(1.0)
    block = b"\\x01" * (64 << 20)                      # 64 MiB, every page touched
    fds = [os.open(os.devnull, os.O_RDONLY) for _ in range(5)]
    stop = threading.Event()
    workers = [threading.Thread(target=stop.wait) for _ in range(3)]
    for w in workers:
        w.start()
    time.sleep(2.0)
    stop.set()
""")


def test_sampler_sees_a_process_grow_by_known_amounts():
    """A child named like a node process allocates 64 MiB, opens 5 descriptors and starts 3 threads after 1 s."""
    cmd = [sys.executable, "-c", GROWER, "-m", "probeless.runtime.process", "/tmp/none", "grower"]
    child = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout.readline() == "ready\n"   # started: its descriptors are open from here on
        sampler = ProcessSampler(0.1, until_s=2.6)
        sampler.start()
        child.wait(timeout=20)
        sampler.stop()
    finally:
        child.kill()
    s = sampler.series["grower"]
    assert set(s["pid"]) == {child.pid} and "launcher" in sampler.series
    rss_growth = max(s["rss_mb"]) - s["rss_mb"][0]
    assert 60.0 < rss_growth < 72.0                   # 64 MiB, plus what allocating it touched
    assert max(s["fds"]) - s["fds"][0] == 5
    assert max(s["threads"]) - s["threads"][0] == 3
    verdict = summarize(s, 0.5)
    assert not verdict["meets_goal"] and verdict["fd_growth"] == 5 and verdict["thread_growth"] == 3


@pytest.mark.graph
@pytest.mark.slow
@pytest.mark.timeout(600)
def test_soak_two_minutes_of_the_full_pipeline_meets_the_goal():
    """CI's soak: ``probeless bench soak --minutes 2 --json`` (the 30-minute figures are in the docs)."""
    cmd = [sys.executable, "-m", "probeless", "bench", "soak", "--minutes", "2", "--json"]
    proc = subprocess.run(cmd, cwd=REPO_ROOT, capture_output=True, text=True, timeout=560,
                          env={**os.environ, "PYTHONUNBUFFERED": "1"})
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.count("\n") == 1
    r = json.loads(proc.stdout)
    why = json.dumps({k: r[k] for k in ("goal", "flow", "exited_at_s", "pid_changes", "wall_s", "exit_code")})
    nodes = set(r["nodes"])
    assert {"rig", "slam", "texturer", "envmap", "compositor", "video"} <= nodes
    assert nodes | {"launcher"} <= set(r["processes"]), why
    assert len(r["series"]["sample_t_s"]) >= 50, why          # every 2 s over 2 min
    assert r["healthy"] and r["ran_full_duration"], why
    assert not r["exited_at_s"] and not r["pid_changes"], why
    # over 2 min: no descriptor growth in any process, total RSS growth < 5 %. Per-process RSS and threads are
    # judged by the long run (docs): several nodes still step up for ~2 min after starting, RSS and, in some runs,
    # the player by one thread that then stays (no growth over the 30-minute run). A steady leak is still caught
    # here: more than one thread more in any process fails.
    checks = r["goal"]["checks"]
    assert checks["fds"] and checks["rss_total"], why
    assert all(p["thread_growth"] <= 1 for p in r["processes"].values() if p["samples_after_warmup"]), why


def test_a_stage_that_receives_but_no_longer_produces_is_stalled():
    from probeless.bench.soak_stats import activity

    # interp kept receiving after the loop's time jump but published nothing more: its work count is flat
    early = activity(("interp/fisheye_pose=40", "interp/diagnostics=10"), [100, 50], producer=True)
    late = activity(("interp/fisheye_pose=40", "interp/diagnostics=70"), [900, 450], producer=True)
    assert early == late == 40
    flow = health({"interp": [(10, early), (50, early), (90, late)]}, 50.0)
    assert flow["stalled"] == ["interp"]
    assert activity(("png/diagnostics=9",), [3, 4], producer=False) == 7   # a sink counts what it receives
