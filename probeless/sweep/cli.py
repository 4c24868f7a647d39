"""The ``probeless sweep`` command: ``sweep SWEEP.yaml``, ``sweep report DIR``, ``sweep bench SWEEP.yaml``."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from probeless.errors import SweepError

USAGE = """probeless sweep SWEEP.yaml [-o DIR] [--jobs N] [--ray auto|ADDRESS] [--resume] [--only AXIS=LABEL[,LABEL]]
       probeless sweep report DIR
       probeless sweep bench SWEEP.yaml [--jobs-list 1 2] [--ray auto] [--only AXIS=LABEL]"""


def add_sweep_parser(sub: Any) -> argparse.ArgumentParser:
    """Add ``sweep`` to the top-level subparsers."""
    p = sub.add_parser("sweep", usage=USAGE, help="run grids of evaluations or graph variants (docs/sweeps.md)",
                       description="run a sweep file's grid of runs locally or on Ray, write results/<run-id>/ and "
                                   "results.csv; 'sweep report DIR' aggregates and plots; 'sweep bench' times the "
                                   "local pool and Ray. See docs/sweeps.md.")
    p.add_argument("target", nargs="+", metavar="SWEEP.yaml | report DIR | bench SWEEP.yaml")
    p.add_argument("-o", "--out", metavar="DIR", help="results directory (default out/sweeps/<sweep name>)")
    p.add_argument("--jobs", type=int, metavar="N", help="CPUs to use at once (default: the core count); a run "
                                                         "takes the sweep's resources.cpus of them")
    p.add_argument("--ray", metavar="auto|ADDRESS", help="run each run as a Ray task: 'auto' starts a local Ray "
                                                         "for the sweep, else the cluster address to join")
    p.add_argument("--resume", action="store_true", help="skip runs finished before under the same key")
    p.add_argument("--only", action="append", default=[], metavar="AXIS=LABEL[,LABEL]",
                   help="run only the runs with one of these labels on this axis (repeatable: all must hold)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--no-plots", action="store_true", help="report: tables only")
    p.add_argument("--jobs-list", type=int, nargs="+", default=[1, 2], metavar="N", help="bench: --jobs values")
    p.set_defaults(func=cmd_sweep)
    return p


def cmd_sweep(ns: argparse.Namespace) -> int:
    """Dispatch ``sweep FILE`` / ``sweep report DIR`` / ``sweep bench FILE``."""
    t = ns.target
    if t[0] == "report" and len(t) == 2:
        from probeless.sweep.report import report

        print(report(t[1], plots=not ns.no_plots), end="")
        return 0
    if t[0] == "bench" and len(t) == 2:
        from probeless.sweep.bench import bench, format_bench

        print(format_bench(bench(t[1], ns.jobs_list, ray=ns.ray, only=ns.only)))
        return 0
    if len(t) != 1:
        raise SweepError(f"expected one sweep file, 'report DIR' or 'bench FILE', got {' '.join(t)!r}")
    return run(ns, t[0])


def run(ns: argparse.Namespace, sweep_file: str) -> int:
    """Run a sweep file; exit status 0 when every run finished, 1 when some failed, 130 on Ctrl-C."""
    from pathlib import Path

    from probeless.sweep.driver import run_sweep
    from probeless.sweep.spec import load_sweep

    out = ns.out or str(Path("out/sweeps") / load_sweep(sweep_file).name)
    try:
        s = run_sweep(sweep_file, out, jobs=ns.jobs, ray=ns.ray, resume=ns.resume, only=ns.only,
                      show_progress=not ns.no_progress)
    except KeyboardInterrupt:
        print(f"interrupted: finished runs are kept in {out}; rerun with --resume to go on", file=sys.stderr)
        return 130
    ray = f", Ray start-up {s.ray_startup_s:.1f} s" if s.ray_startup_s else ""
    print(f"{s.total} runs: {s.ok} ran ok, {s.failed} failed, {s.skipped} already done; {s.wall_s:.1f} s{ray}")
    for run_id, error in s.failures.items():
        print(f"failed: {run_id}: {error}")
    print(f"results: {', '.join(map(str, s.files))}; report: probeless sweep report {out}")
    return 1 if s.failed else 0
