"""Finding running graphs: one run directory per launch, holding the launcher's ``graph.json`` plan.

The run directories themselves are read by :mod:`probeless.runtime.runs` (shared with ``external:``
inputs); this module adds the tools' rule for choosing one: never guess.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import IO

from probeless.errors import ProbelessError
from probeless.runtime.runs import (  # noqa: F401 (re-exported: the topic tools' API)
    RunningGraph,
    load_graph_dir,
    pid_alive,
    resolve_runs,
    running_graphs,
    runs_base,
)

NO_GRAPH_HINT = "start one with `probeless launch GRAPH`, or pass --graph RUN_ID"


def select_graph(graph: str | Path | None = None, *, base: str | Path | None = None,
                 err: IO[str] | None = None) -> RunningGraph:
    """The running graph to inspect: the one ``graph`` names (a run id, a run directory or the graph file
    it was launched from), else the only one running. Never guesses: when several match, they are
    listed on ``err`` and a ProbelessError asks for ``--graph RUN_ID``."""
    err = err or sys.stderr
    where = Path(base) if base is not None else runs_base()
    if graph is not None:
        graphs = resolve_runs(str(graph), base=base)
        if not graphs:
            raise ProbelessError(f"no running graph was launched from {graph} "
                                 f"(`probeless runs` lists the running graphs)")
    else:
        graphs = running_graphs(base)
        if not graphs:
            raise ProbelessError(f"no running probeless graph found in {where}; {NO_GRAPH_HINT}")
    if len(graphs) > 1:
        print(f"{len(graphs)} graphs are running{f' from {graph}' if graph is not None else ''}:", file=err)
        for g in graphs:
            print(f"  {g.describe()}", file=err)
        raise ProbelessError(f"{len(graphs)} graphs are running; choose one with --graph RUN_ID")
    return graphs[0]


def _launcher_gone(graph: RunningGraph, state: dict) -> bool:
    """True once the launcher has exited (checked at most once a second)."""
    now = time.monotonic()
    if now - state.get("t", 0.0) < 1.0:
        return False
    state["t"] = now
    return not graph.alive
