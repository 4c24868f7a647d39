"""``probeless sweep SWEEP.yaml``: check every run up front, run what is not done (locally or on Ray), write
each run's files under ``results/<run-id>/`` as it ends, and the results table at the end (also after Ctrl-C).
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator

from probeless.jsonio import dumps
from probeless.sweep.expand import Run, check_runs, expand
from probeless.sweep.runner import job_of, run_local
from probeless.sweep.spec import Sweep, load_sweep, short_label
from probeless.sweep.table import collect, columns, row, write_table


@dataclass
class Summary:
    """What a sweep did."""

    total: int = 0
    skipped: int = 0        # finished before (--resume)
    ok: int = 0
    failed: int = 0
    wall_s: float = 0.0
    ray_startup_s: float | None = None
    failures: dict[str, str] = field(default_factory=dict)  # run id -> error
    files: list[Path] = field(default_factory=list)


def prepare(sweep_file: str | Path, out_dir: str | Path, only: list[str] = ()) -> tuple[Sweep, list[Run]]:
    """The sweep and its runs, every run checked. ``only``: ``axis=label[,label...]`` filters (a run must have
    one of the labels on each axis named; a file's stem names it too)."""
    sweep = load_sweep(sweep_file)
    runs = expand(sweep, out_dir)
    for cond in only:
        axis, _, labels = cond.partition("=")
        if axis not in {a.name for a in sweep.axes}:
            raise sweep.error(f"--only {cond!r}: no axis {axis!r}", "axes")
        wanted = labels.split(",")
        runs = [r for r in runs if r.labels[axis] in wanted or short_label(r.labels[axis]) in wanted]
    check_runs(sweep, runs)
    return sweep, runs


def read_record(run: Run) -> dict[str, Any] | None:
    """A run's ``run.json``, or None."""
    try:
        return json.loads((Path(run.run_dir) / "run.json").read_text())
    except (OSError, ValueError):
        return None


def is_done(run: Run) -> bool:
    """Finished with status ok under the same resume key."""
    rec = read_record(run)
    return bool(rec) and rec.get("status") == "ok" and rec.get("key") == run.key()


def write_record(run: Run, sweep: Sweep, rec: dict[str, Any]) -> dict[str, Any]:
    """Write ``result.json``, ``stdout.log``, ``stderr.log`` and ``run.json`` of a finished run."""
    d = Path(run.run_dir)
    d.mkdir(parents=True, exist_ok=True)
    (d / "stdout.log").write_text(rec.get("stdout") or "")
    (d / "stderr.log").write_text(rec.get("stderr") or "")
    if rec.get("result") is not None:
        (d / "result.json").write_text(dumps(rec["result"], indent=1))
    out = {"run_id": run.run_id, "labels": run.labels, "argv": ["probeless", *run.argv], "key": run.key(),
           "status": rec["status"], "error": rec.get("error"), "returncode": rec.get("returncode"),
           "wall_s": rec.get("wall_s"), "collected": collect(rec.get("result"), run.collect)
           if rec.get("result") is not None else {}, "finished": time.strftime("%Y-%m-%dT%H:%M:%S")}
    (d / "run.json").write_text(dumps(out, indent=1))
    return out


def write_meta(sweep: Sweep, runs: list[Run], out_dir: Path) -> None:
    """``sweep.json`` (what ``sweep report`` needs) and a copy of the sweep file."""
    meta = {"sweep": sweep.file, "name": sweep.name, "kind": sweep.kind, "target": sweep.target,
            "axes": [a.name for a in sweep.axes], "collect": sweep.collect, "report": sweep.report,
            "runs": [r.run_id for r in runs]}
    (out_dir / "sweep.json").write_text(dumps(meta, indent=1))
    shutil.copyfile(sweep.file, out_dir / "sweep.yaml")


def write_results(sweep: Sweep, runs: list[Run], out_dir: Path) -> list[Path]:
    """The table of every run: its record, or status ``pending`` if it has none yet."""
    axes, keys = [a.name for a in sweep.axes], list(sweep.collect)
    rows = []
    for run in runs:
        rec = read_record(run) or {"run_id": run.run_id, "status": "pending", "labels": run.labels}
        rows.append(row(rec, axes, keys))
    return write_table(rows, columns(axes, keys), out_dir)


class _Counter:
    """Runs done / failed / running, shown on a rich progress bar on stderr."""

    def __init__(self, bar, task, name: str):
        self.bar, self.task, self.name = bar, task, name
        self.ok = self.failed = self.running = 0
        self.lock = threading.Lock()

    def started(self, _job=None) -> None:
        with self.lock:
            self.running += 1
            self._show()

    def finished(self, ok: bool) -> None:
        with self.lock:
            self.running -= 1
            self.ok += ok
            self.failed += not ok
            self._show(advance=1)

    def _show(self, advance: int = 0) -> None:
        if self.bar is not None:
            desc = f"{self.name}: {self.ok} done, {self.failed} failed, {self.running} running"
            self.bar.update(self.task, advance=advance, description=desc)


@contextlib.contextmanager
def _progress(total: int, name: str, enabled: bool) -> Iterator[_Counter]:
    if not enabled:
        yield _Counter(None, None, name)
        return
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                  console=Console(stderr=True)) as bar:
        yield _Counter(bar, bar.add_task(name, total=total), name)


def run_sweep(sweep_file: str | Path, out_dir: str | Path, *, jobs: int | None = None, ray: str | None = None,
              resume: bool = False, only: list[str] = (), show_progress: bool = True) -> Summary:
    """Run a sweep (module doc). ``jobs``: concurrent CPUs (default: the core count); ``ray``: ``auto`` or a
    cluster address; ``resume``: skip runs finished under the same key. KeyboardInterrupt propagates after
    the table is written."""
    out_dir = Path(out_dir)
    sweep, runs = prepare(sweep_file, out_dir, only)
    out_dir.mkdir(parents=True, exist_ok=True)
    write_meta(sweep, runs, out_dir)
    jobs = jobs or os.cpu_count() or 1
    todo = [r for r in runs if not (resume and is_done(r))]
    summary = Summary(total=len(runs), skipped=len(runs) - len(todo))
    for run in todo:
        shutil.rmtree(run.run_dir, ignore_errors=True)
    by_id = {r.run_id: r for r in todo}
    cwd = os.getcwd()
    job_list = [job_of(r, cwd, sweep.timeout_s, sweep.cpus) for r in todo]
    t0 = time.monotonic()
    with _progress(len(todo), f"sweep {sweep.name}", show_progress and bool(todo)) as counter:
        def on_done(rec: dict[str, Any]) -> None:
            out = write_record(by_id[rec["run_id"]], sweep, rec)
            counter.finished(out["status"] == "ok")
            if out["status"] != "ok":
                summary.failures[out["run_id"]] = out["error"]

        try:
            if ray:
                from probeless.sweep.ray_runner import run_ray

                summary.ray_startup_s = run_ray(job_list, ray, sweep.cpus, sweep.gpus, jobs, counter.started,
                                                on_done)
            else:
                run_local(job_list, max(1, jobs // max(1, sweep.cpus)), counter.started, on_done)
        finally:
            summary.wall_s = time.monotonic() - t0
            summary.ok, summary.failed = counter.ok, counter.failed
            summary.files = write_results(sweep, runs, out_dir)
    return summary
