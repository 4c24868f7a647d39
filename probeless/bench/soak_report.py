"""Output of ``probeless bench soak``: the table, and RSS per process over time as a PNG."""

from __future__ import annotations

from pathlib import Path


def _fmt(v, spec: str) -> str:
    return "-" if v is None else format(v, spec)


def print_table(r: dict) -> None:
    """Per-process and total growth after warm-up, the goal verdict, flow and exits."""
    print(f"soak: {r['graph']} on {r['recording']} (looped, rate {r['rate']}), {r['minutes']:g} min "
          f"({r['wall_s']:.0f} s wall), sampled every {r['sample_period_s']:g} s; warm-up {r['warmup_s']:g} s "
          f"({r['warmup_rule']})")
    print(f"{'process':<14}{'RSS MiB':>9}{'growth %':>10}{'fds':>6}{'+fds':>6}{'threads':>9}{'+thr':>6}  goal")
    rows = list(r["processes"].items()) + [("total", r["total"])]
    for name, s in rows:
        print(f"{name:<14}{_fmt(s['rss_mb_last_window'], '9.1f')}{_fmt(s['rss_growth_pct'], '10.2f')}"
              f"{_fmt(s['fds_at_warmup_end'], '6.0f')}{_fmt(s['fd_growth'], '6.0f')}"
              f"{_fmt(s['threads_at_warmup_end'], '9.0f')}{_fmt(s['thread_growth'], '6.0f')}"
              f"  {'ok' if s['meets_goal'] else 'FAIL'}")
    goal = r["goal"]
    print(f"goal (RSS growth < {goal['rss_growth_pct_below']:g} %, no fd or thread growth): "
          f"{'met' if goal['meets_goal'] else 'NOT met'} ("
          + ", ".join(f"{k.replace('_', ' ')}: {'ok' if v else 'NOT met'}" for k, v in goal["checks"].items()) + ")")
    for f in goal["failures"]:
        print(f"  {f}")
    stalled = r["flow"]["stalled"]
    print(f"messages kept flowing after warm-up: {'yes' if r['healthy'] else 'NO'}"
          + (f" (stalled: {', '.join(stalled)})" if stalled else ""))
    for name, t in r["exited_at_s"].items():
        print(f"  {name} exited at {t:.0f} s")
    for name, n in r["pid_changes"].items():
        print(f"  {name} restarted {n} time(s)")
    if not r["ran_full_duration"]:
        print(f"the graph stopped early, after {r['wall_s']:.0f} s")
    if r["exit_code"] != 0:
        print(f"launcher exit code {r['exit_code']}: a node failed or did not stop cleanly (its log is on stderr)")


def plot_rss(r: dict, path: Path) -> None:
    """RSS [MiB] per process over time, the warm-up cut marked, to ``path`` (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 5))
    colours = plt.get_cmap("tab20").colors
    for k, (name, s) in enumerate(sorted(r["series"]["processes"].items())):
        ax.plot([t / 60 for t in s["t_s"]], s["rss_mb"], label=name, lw=1.2, color=colours[2 * k % 20 + k // 10 % 2])
    ax.axvline(r["warmup_s"] / 60, color="k", ls="--", lw=0.8, label="warm-up end")
    ax.set_xlabel("time [min]")
    ax.set_ylabel("RSS [MiB]")
    ax.set_yscale("log")
    ax.set_title(f"bench soak: RSS per process ({r['minutes']:g} min)")
    ax.legend(fontsize=7, ncol=2, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)
