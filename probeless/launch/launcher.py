"""``probeless launch``: one process per node, log prefixing, readiness barrier, restarts, shutdown.

Restarts: a node with ``restart: on-failure`` that exits non-zero (or is killed) is started again after
``restart_backoff_s`` (doubling each time), at most ``max_restarts`` times; the new process gets
``PROBELESS_RESTARTS=<n>`` in its environment (:func:`restart_count`), so a node that loses state
with its process (SLAM's map) can say so. Shutdown is bounded: SIGTERM to every node, then, after
``kill_timeout`` seconds, SIGKILL to the process group of every node still alive (the node and
anything it started), each logged with the node id; such a node counts as failed.
"""

from __future__ import annotations

import ctypes
import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from typing import IO, Any

import msgpack
import zmq

from probeless.errors import GraphErrors, ProbelessError
from probeless.launch.graph import parse_graph
from probeless.launch.lockstep import QuiescenceCheck
from probeless.launch.plan import build_plan, new_run_dir
from probeless.launch.validate import validate

_PR_SET_PDEATHSIG = 1
# glibc serves allocations above 128 KiB (growing to 32 MiB) with fresh mmaps, so every received
# camera frame costs hundreds of page faults. Node processes keep such buffers on the heap instead
# (measured: recorder page faults 600-850/MB -> ~130/MB, throughput about doubled). Users may override.
NODE_MALLOC_ENV = {"MALLOC_MMAP_THRESHOLD_": str(64 << 20), "MALLOC_TRIM_THRESHOLD_": str(256 << 20)}
RESTARTS_ENV = "PROBELESS_RESTARTS"


def restart_count() -> int:
    """How often the launcher has restarted this node process (0 at the first start, or outside a launch)."""
    try:
        return max(0, int(os.environ.get(RESTARTS_ENV, "0")))
    except ValueError:
        return 0


def load_checked(path: str, overrides: dict[str, Any]):
    """Parse and validate a graph; raise GraphErrors listing every problem."""
    graph = parse_graph(path, overrides)
    errors = validate(graph)
    if errors:
        raise GraphErrors(errors)
    return graph


def _die_with_parent() -> None:  # runs in the child between fork and exec
    try:
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)
    except OSError:
        pass


@dataclass
class Child:
    node_id: str
    spec: dict
    proc: subprocess.Popen | None = None
    restarts: int = 0
    ready: bool = False
    restart_at: float | None = None
    threads: list = field(default_factory=list)


def _kill_group(proc: subprocess.Popen) -> None:
    """SIGKILL a node's process group (it leads its own session), then reap it."""
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        proc.kill()
    proc.wait()


class Launcher:
    """Supervises the node processes of one graph (or of one host's share of it)."""

    def __init__(self, graph, *, only: str | None = None, duration: float | None = None,
                 ready_timeout: float = 60.0, kill_timeout: float = 5.0, out: IO[str] = sys.stdout,
                 clock_node: str | None = None):
        self.graph = graph
        self.duration = duration
        self.ready_timeout = ready_timeout
        self.kill_timeout = kill_timeout
        self.out = out
        self.print_lock = threading.Lock()
        self.run_dir = new_run_dir()
        self.plan = build_plan(graph, self.run_dir, clock_node=clock_node)
        (self.run_dir / "graph.json").write_text(json.dumps(self.plan, indent=1))
        selected = [n for n in self.plan["nodes"].values() if only is None or n["host"] == only]
        if only is not None and not selected:
            raise ProbelessError(f"no node of {graph.file} runs on host {only!r}")
        self.children = {n["id"]: Child(n["id"], n) for n in selected}
        self.stopping = False
        self.failed: list[str] = []

    def log(self, text: str) -> None:
        with self.print_lock:
            print(f"[launch] {text}", file=self.out, flush=True)

    def run(self) -> int:
        """Run until every node has ended, the duration passes, a signal arrives or a node fails."""
        zctx = zmq.Context()
        ctl = zctx.socket(zmq.ROUTER)
        ctl.setsockopt(zmq.LINGER, 0)
        ctl.bind(self.plan["control"])
        old = {s: signal.signal(s, self._on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
        try:
            self.log(f"run id {self.run_dir.name} (`probeless runs` lists it; the tools take --graph "
                     f"{self.run_dir.name})")
            for child in self.children.values():
                self._spawn(child)
            self._supervise(ctl)
        finally:
            self._stop_all()
            for s, h in old.items():
                signal.signal(s, h)
            ctl.close()
            zctx.term()
            shutil.rmtree(self.run_dir, ignore_errors=True)
        if self.failed:
            self.log(f"graph stopped: node(s) failed: {', '.join(self.failed)}")
            return 1
        self.log("graph finished")
        return 0

    def _on_signal(self, signum, frame) -> None:
        if not self.stopping:
            self.log(f"received {signal.Signals(signum).name}, stopping the graph")
        self.stopping = True

    def _spawn(self, child: Child) -> None:
        cmd = [sys.executable, "-u", "-m", "probeless.runtime.process", str(self.run_dir), child.node_id]
        tuned = os.environ.get("PROBELESS_MALLOC_TUNING", "1") != "0"
        env = {**(NODE_MALLOC_ENV if tuned else {}), **os.environ, RESTARTS_ENV: str(child.restarts)}
        child.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, stdin=subprocess.DEVNULL,
                                      start_new_session=True, preexec_fn=_die_with_parent, env=env)
        child.ready = False
        child.threads = [threading.Thread(target=self._pump, args=(child.node_id, s), daemon=True)
                         for s in (child.proc.stdout, child.proc.stderr)]
        for t in child.threads:
            t.start()

    def _pump(self, node_id: str, stream: IO[bytes]) -> None:
        for raw in iter(stream.readline, b""):
            with self.print_lock:
                print(f"[{node_id}] {raw.decode(errors='replace').rstrip()}", file=self.out, flush=True)
        stream.close()

    def _supervise(self, ctl: zmq.Socket) -> None:
        t0 = time.monotonic()
        started = False
        self.quiescence: QuiescenceCheck | None = None
        self.collect_at: float | None = None  # when to collect again (lockstep: nodes were still working)
        while not self.stopping:
            if ctl.poll(1 if self.quiescence is not None else 50):
                parts = ctl.recv_multipart()
                child = self.children.get(parts[0].decode())
                if child is not None and parts[1] == b"ready":
                    child.ready = True
                    if started:
                        ctl.send_multipart([parts[0], b"start"])
                elif child is not None:
                    self._on_lockstep(ctl, child.node_id, parts[1:])
            if not started and all(c.ready for c in self.children.values()):
                started, t_started = True, time.monotonic()  # --duration counts from here, not from the spawn
                self.log(f"{len(self.children)} node(s) ready in {time.monotonic() - t0:.2f} s, starting")
                for c in self.children.values():
                    ctl.send_multipart([c.node_id.encode(), b"start"])
            if not started and time.monotonic() - t0 > self.ready_timeout:
                waiting = [c.node_id for c in self.children.values() if not c.ready]
                self.log(f"not ready after {self.ready_timeout:.0f} s: {', '.join(waiting)}")
                self.failed += waiting
                return
            if self.quiescence is not None and self.collect_at is not None and time.monotonic() >= self.collect_at:
                self._collect(ctl)
            elif self.quiescence is not None and any(
                    self.children[n].proc.poll() is not None for n in self.quiescence.expected):
                self._collect(ctl)  # a node ended mid-collect: collect again without it
            if self._reap() or (self.duration is not None and started
                                and time.monotonic() - t_started > self.duration):
                return

    def _on_lockstep(self, ctl: zmq.Socket, node_id: str, parts: list[bytes]) -> None:
        """Quiescence requests of a lockstep player and the status replies they trigger."""
        if parts[0] == b"quiesce":
            self.quiescence = QuiescenceCheck(self.plan, node_id, msgpack.unpackb(parts[1]))
            self._collect(ctl)
        elif parts[0] == b"status" and self.quiescence is not None:
            check = self.quiescence
            if check.add_reply(node_id, int(parts[1]), msgpack.unpackb(parts[2], strict_map_key=False)):
                if check.quiet():
                    self.quiescence = None
                    ctl.send_multipart([check.requester.encode(), b"quiet"])
                elif (delay := check.retry_delay_s()) > 0:
                    self.collect_at = time.monotonic() + delay
                else:
                    self._collect(ctl)

    def _collect(self, ctl: zmq.Socket) -> None:
        self.collect_at = None
        alive = [c.node_id for c in self.children.values() if c.proc is not None and c.proc.poll() is None]
        asked = self.quiescence.begin_round(alive)
        if not asked:
            requester = self.quiescence.requester
            self.quiescence = None
            ctl.send_multipart([requester.encode(), b"quiet"])
        for node_id in asked:
            ctl.send_multipart([node_id.encode(), b"status", str(self.quiescence.round).encode()])

    def _reap(self) -> bool:
        """Handle exited children; True when the graph is over (all ended, or a failure)."""
        now = time.monotonic()
        for child in self.children.values():
            if child.restart_at is not None and now >= child.restart_at:
                child.restart_at = None
                child.restarts += 1
                self.log(f"restarting {child.node_id} ({child.restarts}/{child.spec['max_restarts']})")
                self._spawn(child)
                continue
            if child.proc is None or child.restart_at is not None or child.proc.poll() is None:
                continue
            code = child.proc.returncode
            if code == 0:
                continue
            reason = f"killed by {signal.Signals(-code).name}" if code < 0 else f"exit code {code}"
            if child.spec["restart"] == "on-failure" and child.restarts < child.spec["max_restarts"]:
                delay = child.spec["restart_backoff_s"] * (2 ** child.restarts)
                self.log(f"node {child.node_id} crashed ({reason}); restart in {delay:.2f} s")
                child.restart_at = now + delay
                continue
            self.log(f"node {child.node_id} crashed ({reason})")
            self.failed.append(child.node_id)
            return True
        return all(c.proc is not None and c.restart_at is None and c.proc.poll() == 0
                   for c in self.children.values())

    def _stop_all(self) -> None:
        alive = [c for c in self.children.values() if c.proc is not None and c.proc.poll() is None]
        for c in alive:
            c.proc.send_signal(signal.SIGTERM)
        deadline = time.monotonic() + self.kill_timeout
        for c in alive:
            try:
                c.proc.wait(max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                self.log(f"node {c.node_id} did not stop within {self.kill_timeout:g} s of SIGTERM; "
                         f"sending SIGKILL (pid {c.proc.pid})")
                _kill_group(c.proc)
                self.failed.append(c.node_id)
        for c in alive:
            # -SIGTERM: the node was still starting (no handler yet) when we stopped it; that is clean
            if c.proc.returncode not in (0, -signal.SIGTERM) and c.node_id not in self.failed:
                self.log(f"node {c.node_id} exited with code {c.proc.returncode} while stopping")
                self.failed.append(c.node_id)
        for c in self.children.values():
            for t in c.threads:
                t.join(1.0)
