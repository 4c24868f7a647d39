"""Running graphs: one run directory per launch, holding the launcher's ``graph.json`` plan.

A run is named by its **run id**, the name of its run directory (``093012-k2j4x1``), which
``probeless runs`` lists. :func:`resolve_runs` maps what a user passes (``--graph``, an
``external:`` input) to the running graphs it names: a run id, a run directory, or the graph file
the run was launched from. Used by the topic/node/param tools and by the launcher (``external:``).
"""

from __future__ import annotations

import json
import os
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from probeless.errors import ProbelessError

# a run's longest socket path is BASE/HHMMSS-xxxxxxxx/recorder.lossy; a unix socket path holds 107 bytes
IPC_PATH_MAX = 107
RUN_NAME_MAX = 32


def runs_base() -> Path:
    """The directory holding one run directory per launched graph (``$PROBELESS_RUN_DIR`` or
    ``$TMPDIR/probeless-<uid>``).

    Raises :class:`ProbelessError` naming the variable when the folder is too long to hold ipc sockets.
    """
    env = os.environ.get("PROBELESS_RUN_DIR")
    base = Path(env or Path(tempfile.gettempdir()) / f"probeless-{os.getuid()}")
    room = IPC_PATH_MAX - RUN_NAME_MAX
    if len(os.fsencode(str(base))) > room:
        where = "PROBELESS_RUN_DIR" if env else "TMPDIR"
        raise ProbelessError(f"{where}: run directory {str(base)!r} is {len(str(base))} characters; ipc socket "
                             f"paths inside it would pass the {IPC_PATH_MAX}-byte limit of a unix socket: "
                             f"set {where} to a folder of at most {room} characters")
    return base


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
    def run_id(self) -> str:
        return self.run_dir.name

    @property
    def launcher_pid(self) -> int | None:
        return self.plan.get("launcher_pid")

    @property
    def started_ns(self) -> int:
        return int(self.plan.get("started_ns") or 0)

    @property
    def alive(self) -> bool:
        return pid_alive(self.launcher_pid)

    @property
    def graph_file(self) -> str:
        """The graph file the run was launched from (absolute when the plan says so)."""
        return str(self.plan.get("file_abs") or self.plan.get("file") or "?")

    def describe(self) -> str:
        started = time.strftime("%H:%M:%S", time.localtime(self.started_ns / 1e9)) if self.started_ns else "?"
        return (f"{self.run_id}  {self.plan.get('file', '?')} (launcher pid {self.launcher_pid}, "
                f"started {started}, {len(self.plan.get('nodes', {}))} nodes)")


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


def resolve_runs(spec: str, *, base: str | Path | None = None, relative_to: Path | None = None
                 ) -> list[RunningGraph]:
    """The running graphs ``spec`` names: a run id, a run directory, or a graph file (every running
    launch of that file; a relative file is taken from ``relative_to``, else the working folder).

    Raises ProbelessError when ``spec`` names a run directory whose graph has ended, or nothing at all.
    """
    base = Path(base) if base is not None else runs_base()
    as_dir = Path(spec) if Path(spec).is_absolute() or "/" in spec else base / spec
    if (as_dir / "graph.json").is_file():
        g = load_graph_dir(as_dir)
        if not g.alive:
            raise ProbelessError(f"run {g.run_id} ({g.plan.get('file', '?')}) is not running any more "
                                 f"(launcher pid {g.launcher_pid} is gone)")
        return [g]
    path = Path(spec)
    if not path.is_absolute() and relative_to is not None:
        path = relative_to / path
    if path.is_file():
        target = path.resolve()
        return [g for g in running_graphs(base) if _same_file(g, target)]
    raise ProbelessError(f"{spec!r} is neither the id of a running graph nor a graph file "
                         f"(`probeless runs` lists the running graphs and their ids)")


def _same_file(g: RunningGraph, target: Path) -> bool:
    try:
        return Path(g.graph_file).resolve() == target
    except OSError:
        return False
