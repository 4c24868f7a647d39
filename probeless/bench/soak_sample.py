"""Process sampling for ``probeless bench soak``: RSS, open descriptors and threads of every node process.

A :class:`ProcessSampler` thread reads, every ``period_s``, the launcher process and each of its
descendants (psutil). Node processes are named by their node id, read from their command line
(``python -m probeless.runtime.process RUN_DIR NODE_ID``); the launcher is ``launcher``; any other
descendant (a helper a node started) is ``<name>:<pid>``.
"""

from __future__ import annotations

import os
import threading
import time
from typing import Callable

import psutil

NODE_MODULE = "probeless.runtime.process"
LAUNCHER = "launcher"


def node_id_of(cmdline: list[str]) -> str | None:
    """The node id in a node process's command line (``... -m probeless.runtime.process RUN_DIR NODE_ID``)."""
    for i, arg in enumerate(cmdline[:-2]):
        if arg == NODE_MODULE and cmdline[i - 1:i] == ["-m"]:
            return cmdline[i + 2]
    return None


def read_process(proc: psutil.Process) -> tuple[str, int, float, int, int] | None:
    """(label, pid, RSS [MiB], open descriptors, threads) of one process; None when it is gone."""
    try:
        with proc.oneshot():
            label = node_id_of(proc.cmdline()) or f"{proc.name()}:{proc.pid}"
            return label, proc.pid, proc.memory_info().rss / 2**20, proc.num_fds(), proc.num_threads()
    except (psutil.NoSuchProcess, psutil.AccessDenied, psutil.ZombieProcess):
        return None


def _same_cmdline(proc: psutil.Process, cmdline: list[str]) -> bool:
    try:
        return proc.cmdline() == cmdline
    except psutil.Error:
        return True


class ProcessSampler:
    """Samples the process ``root_pid`` (default: this one, the launcher) and its descendants in a thread.

    ``series`` maps a process label to ``{"t_s", "pid", "rss_mb", "fds", "threads"}`` lists; ``sample_t``
    lists every sampling instant [s since :meth:`start`]; ``on_sample`` runs after each round. Sampling
    ends at ``until_s`` (before the graph's shutdown) or :meth:`stop`. A child forked but not yet running
    its own program (it still has the launcher's command line) is skipped.
    """

    def __init__(self, period_s: float, root_pid: int | None = None, on_sample: Callable[[], None] | None = None,
                 until_s: float = float("inf")):
        self.period_s, self.until_s = period_s, until_s
        self.root = psutil.Process(root_pid or os.getpid())
        self.root_cmdline = self.root.cmdline()
        self.on_sample = on_sample
        self.series: dict[str, dict[str, list]] = {}
        self.sample_t: list[float] = []
        self.t0 = 0.0
        self.t0_wall = 0.0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="soak-sampler", daemon=True)

    def start(self) -> None:
        self.t0, self.t0_wall = time.monotonic(), time.time()
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(10.0)

    def sample_once(self) -> None:
        """One round over the launcher and every descendant."""
        t = round(time.monotonic() - self.t0, 3)
        try:
            procs = [self.root] + self.root.children(recursive=True)
        except psutil.NoSuchProcess:
            return
        self.sample_t.append(t)
        for proc in procs:
            got = read_process(proc)
            if got is None or (proc.pid != self.root.pid and _same_cmdline(proc, self.root_cmdline)):
                continue
            label, pid, rss, fds, threads = got
            label = LAUNCHER if pid == self.root.pid else label
            s = self.series.setdefault(label, {"t_s": [], "pid": [], "rss_mb": [], "fds": [], "threads": []})
            if s["t_s"] and s["t_s"][-1] == t:
                continue  # two processes under one label in a round (a restart overlapping): keep the first
            for key, val in zip(("t_s", "pid", "rss_mb", "fds", "threads"), (t, pid, round(rss, 2), fds, threads)):
                s[key].append(val)

    def _loop(self) -> None:
        next_t = time.monotonic()
        while not self._stop.is_set() and next_t - self.t0 <= self.until_s:
            self.sample_once()
            if self.on_sample is not None:
                self.on_sample()
            next_t += self.period_s
            self._stop.wait(max(0.0, next_t - time.monotonic()))
