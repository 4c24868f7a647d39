"""Finding running graphs: one run directory per launch, holding the launcher's ``graph.json`` plan."""

from __future__ import annotations

import json
import os
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from probeless.errors import ProbelessError

NO_GRAPH_HINT = "start one with `probeless launch GRAPH`, or pass --graph-dir RUN_DIR"


def runs_base() -> Path:
    """The directory holding one run directory per launched graph (same rule as ``new_run_dir``)."""
    return Path(os.environ.get("PROBELESS_RUN_DIR") or Path(tempfile.gettempdir()) / f"probeless-{os.getuid()}")


def pid_alive(pid: Any) -> bool:
    if type(pid) is not int or pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # exists, owned by someone else
    return True


@dataclass
class RunningGraph:
    """One launched graph: its run directory and the plan the launcher wrote there."""

    run_dir: Path
    plan: dict

    @property
    def launcher_pid(self) -> int | None:
        return self.plan.get("launcher_pid")

    @property
    def started_ns(self) -> int:
        return int(self.plan.get("started_ns") or 0)

    @property
    def alive(self) -> bool:
        return pid_alive(self.launcher_pid)

    def describe(self) -> str:
        started = time.strftime("%H:%M:%S", time.localtime(self.started_ns / 1e9)) if self.started_ns else "?"
        return (f"{self.plan.get('file', '?')} (run dir {self.run_dir}, launcher pid {self.launcher_pid}, "
                f"started {started})")


def load_graph_dir(run_dir: str | Path) -> RunningGraph:
    """The graph of one run directory (or of its ``graph.json``); ProbelessError when unreadable."""
    path = Path(run_dir)
    if path.name == "graph.json":
        path = path.parent
    try:
        plan = json.loads((path / "graph.json").read_text())
    except FileNotFoundError:
        raise ProbelessError(f"{path} is not a graph run directory (no graph.json)") from None
    except (OSError, ValueError) as exc:
        raise ProbelessError(f"cannot read {path / 'graph.json'}: {exc}") from None
    if not isinstance(plan, dict) or not isinstance(plan.get("nodes"), dict):
        raise ProbelessError(f"{path / 'graph.json'} is not a graph plan")
    return RunningGraph(path, plan)


def running_graphs(base: str | Path | None = None) -> list[RunningGraph]:
    """Every graph whose launcher is still alive, most recently started first."""
    base = Path(base) if base is not None else runs_base()
    found = []
    try:
        dirs = list(base.iterdir())
    except OSError:
        return []
    for d in dirs:
        if not (d / "graph.json").is_file():
            continue
        try:
            g = load_graph_dir(d)
        except ProbelessError:
            continue  # being written, or not ours
        if g.alive:
            found.append(g)
    return sorted(found, key=lambda g: g.started_ns, reverse=True)


def select_graph(graph_dir: str | Path | None = None, *, base: str | Path | None = None,
                 err: IO[str] | None = None) -> RunningGraph:
    """The graph to inspect: ``graph_dir`` when given, else the most recently started running one."""
    err = err or sys.stderr
    if graph_dir is not None:
        g = load_graph_dir(graph_dir)
        if not g.alive:
            raise ProbelessError(f"the graph of {g.run_dir} is not running (launcher pid {g.launcher_pid} is gone)")
        return g
    graphs = running_graphs(base)
    if not graphs:
        where = Path(base) if base is not None else runs_base()
        raise ProbelessError(f"no running probeless graph found in {where}; {NO_GRAPH_HINT}")
    if len(graphs) > 1:
        print(f"note: {len(graphs)} graphs are running; using the most recently started one "
              f"(choose with --graph-dir):", file=err)
        for i, g in enumerate(graphs):
            print(f"  {'*' if i == 0 else ' '} {g.describe()}", file=err)
    return graphs[0]


def _launcher_gone(graph: RunningGraph, state: dict) -> bool:
    """True once the launcher has exited (checked at most once a second)."""
    now = time.monotonic()
    if now - state.get("t", 0.0) < 1.0:
        return False
    state["t"] = now
    return not graph.alive
