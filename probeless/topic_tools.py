"""``probeless topic list | echo | hz | info``: look at the topics of a running graph.

A running graph is found through its run directory (``$PROBELESS_RUN_DIR`` or
``$TMPDIR/probeless-<uid>``, one sub-directory per launch) holding the launcher's ``graph.json``
plan, whose ``launcher_pid`` must still be alive.

The tools subscribe through the runtime's own :class:`~probeless.runtime.transport.Receiver`: its
thread drains the SUB socket continuously and applies a dropping queue policy, so a tool that is
slow (a slow terminal) or not reading never pushes back on the graph; publishers are XPUBs with
NODROP and would wait for a subscriber whose pipe is full. Tool-side drops are counted and
reported separately from messages lost upstream (``header.seq`` gaps). On end of stream the
receiver closes the socket at once (publishers wait for that before they exit), and every socket
is opened with linger 0.

Python API (``out``/``err`` are text streams; every function raises ProbelessError on a user error)::

    g = select_graph()                            # or select_graph("/tmp/probeless-1000/1203-ab")
    graph_topics(g)                               # {topic: Topic}
    list_topics(g, verbose=False, out=sys.stdout)
    echo(g, "src/image", count=3, arrays=True)    # -> number of messages printed
    hz(g, "src/image", window=100, duration=3.0)  # -> final statistics (dict)
    topic_info(g, "src/image", timeout=2.5)       # -> dict; print_info(info) prints it
    topic_main(["echo", "src/image", "-n", "3"])  # the CLI without probeless.cli, -> exit code
"""

from __future__ import annotations

import argparse
import contextlib
import difflib
import json
import math
import os
import signal
import sys
import tempfile
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from itertools import count as _counter
from pathlib import Path
from typing import IO, Any, Iterable

import numpy as np
import zmq

from probeless.errors import ProbelessError
from probeless.messages.base import Message, Struct, schema_of
from probeless.runtime.queues import InputQueue
from probeless.runtime.receiver import InputWire, Receiver

NO_GRAPH_HINT = "start one with `probeless launch GRAPH`, or pass --graph-dir RUN_DIR"
_reader_ids = _counter()


# -- discovery ---------------------------------------------------------------------------------
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
        return f"{self.plan.get('file', '?')} (run dir {self.run_dir}, launcher pid {self.launcher_pid}, started {started})"


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


# -- topics of a graph ---------------------------------------------------------------------------
@dataclass
class Subscriber:
    node: str
    input: str
    policy: str
    queue_size: int


@dataclass
class Topic:
    name: str                   # "<node_id>/<output>"
    type_name: str | None       # registered message type, None when unknown
    publisher: str              # node id
    node_type: str              # the publisher's ``node:`` entry
    endpoint: str               # the publisher's endpoint
    subscribers: list[Subscriber] = field(default_factory=list)
    declared: bool = True       # False for a topic guessed from "<node>/<output>" (dynamic family output)
    expected: int = 0           # subscribers the publisher's readiness barrier waits for


def _class_output_type(node_type: str, output: str) -> str | None:
    from probeless.runtime.node import output_type
    from probeless.runtime.registry import resolve_node

    try:
        _, typ = output_type(resolve_node(node_type), output)
    except Exception:  # unimportable node module here: the type is simply unknown
        return None
    return getattr(typ, "TYPE_NAME", None) or None


def graph_topics(graph: RunningGraph) -> dict[str, Topic]:
    """Every topic of the graph: node outputs and each node's ``<id>/diagnostics``, in node order."""
    from probeless.messages.diagnostics import NodeStatus

    nodes = graph.plan["nodes"]
    wired: dict[str, list[dict]] = {}
    for nid, node in nodes.items():
        for inp in node.get("inputs", []):
            if "topic" in inp:
                wired.setdefault(inp["topic"], []).append(dict(inp, node_id=nid))
        clock = node.get("clock")
        if clock:  # replay: every node follows the player's clock (a block input of 64, see process.py)
            wired.setdefault(clock["topic"], []).append({"node_id": nid, "name": "(clock)", "policy": "block",
                                                         "queue_size": 64, "type_name": "core/Clock"})
    topics: dict[str, Topic] = {}
    for nid, node in nodes.items():
        outputs = dict(node.get("outputs", {}))
        outputs.setdefault("diagnostics", {"topic": f"{nid}/diagnostics"})
        for out, spec in outputs.items():
            name = spec.get("topic", f"{nid}/{out}")
            subs = wired.get(name, [])
            if out == "diagnostics":
                type_name = NodeStatus.TYPE_NAME
            else:
                type_name = next((s["type_name"] for s in subs if s.get("type_name")), None)
                type_name = type_name or spec.get("type_name") or _class_output_type(node["node"], out)
            topics[name] = Topic(name, type_name, nid, node["node"], node["endpoint"],
                                 [Subscriber(s["node_id"], s["name"], s["policy"], s["queue_size"]) for s in subs],
                                 expected=max(len(subs), int(spec.get("subscribers") or 0)))
    return topics


def find_topic(graph: RunningGraph, name: str) -> Topic:
    """The topic called ``name``; an undeclared output of a known node is allowed (family outputs)."""
    topics = graph_topics(graph)
    if name in topics:
        return topics[name]
    node_id, sep, output = name.rpartition("/")
    nodes = graph.plan["nodes"]
    while sep and node_id not in nodes and "/" in node_id:   # output names may contain '/'
        node_id, _, head = node_id.rpartition("/")
        output = f"{head}/{output}"
    if sep and node_id in nodes and output:
        from probeless.runtime.node import output_type
        from probeless.runtime.registry import resolve_node

        node = nodes[node_id]
        try:
            declared, typ = output_type(resolve_node(node["node"]), output)
        except Exception:
            declared, typ = True, None  # cannot check here: let the user try
        if declared:
            return Topic(name, getattr(typ, "TYPE_NAME", None), node_id, node["node"], node["endpoint"],
                         declared=False)
    close = difflib.get_close_matches(name, list(topics), n=3)
    hint = f"; did you mean {', '.join(close)}?" if close else f"; topics: {', '.join(topics)}"
    raise ProbelessError(f"no topic {name!r} in {graph.plan.get('file', 'the graph')}{hint}")


def _import_publisher(topic: Topic) -> None:
    """Import the publisher's node module so message types it registers can be decoded."""
    from probeless.runtime.registry import resolve_node

    try:
        resolve_node(topic.node_type)
    except Exception:
        pass


def list_topics(graph: RunningGraph, *, verbose: bool = False, out: IO[str] | None = None) -> list[Topic]:
    """Print one line per topic: topic, type, publisher, subscriber count (``verbose``: who and how)."""
    out = out or sys.stdout
    topics = list(graph_topics(graph).values())
    rows = [(t.name, t.type_name or "?", t.publisher, str(max(len(t.subscribers), t.expected))) for t in topics]
    heads = ("TOPIC", "TYPE", "PUBLISHER", "SUBSCRIBERS")
    widths = [max(len(r[i]) for r in rows + [heads]) for i in range(4)]
    print("  ".join(h.ljust(w) for h, w in zip(heads, widths)).rstrip(), file=out)
    for t, r in zip(topics, rows):
        print("  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip(), file=out)
        if verbose:
            print(f"    publisher {t.publisher} ({t.node_type}) at {t.endpoint}", file=out)
            for s in t.subscribers:
                print(f"    -> {s.node}.{s.input}  policy {s.policy}  queue_size {s.queue_size}", file=out)
    return topics


# -- subscribing -------------------------------------------------------------------------------------
class _TimedQueue(InputQueue):
    """An InputQueue that stores (receive time [ns, monotonic], message) for each message."""

    def push(self, arrival: int, msg: Any, seq: int | None = None) -> bool:
        return super().push(arrival, (time.monotonic_ns(), msg), seq)


class TopicReader:
    """Subscribes to topics through the runtime Receiver; its thread keeps draining the sockets.

    ``policy`` must be a dropping one (``drop_oldest`` or ``latest``): the reader may stop reading
    for any time without ever holding up a publisher; what it misses is counted in ``dropped``.
    """

    def __init__(self, topics: Iterable[tuple[str, str]], *, policy: str = "drop_oldest", queue_size: int = 100):
        if policy not in ("drop_oldest", "latest"):
            raise ValueError("a tool must never use the block policy: it would hold up the graph")
        self.wires = [InputWire(topic, endpoint, topic, None) for topic, endpoint in dict(topics).items()]
        self.cond = threading.Condition()
        self.queues = {w.name: _TimedQueue(w.name, policy, queue_size) for w in self.wires}
        self.zctx: zmq.Context | None = None
        self.suspended = False
        self._open()

    def _open(self) -> None:
        self.zctx = zmq.Context()
        self.receiver: Receiver | None = None
        self.wake_tx = None
        try:
            wake = f"inproc://probeless-topic-tool-{os.getpid()}-{next(_reader_ids)}"
            self.receiver = Receiver(self.zctx, self.wires, self.queues, self.cond, wake)
            self.wake_tx = self.zctx.socket(zmq.PAIR)
            self.wake_tx.setsockopt(zmq.LINGER, 0)
            self.wake_tx.connect(wake)
            self.receiver.start()
        except zmq.ZMQError as exc:
            self.close()
            raise ProbelessError(f"cannot subscribe: {exc}") from None

    def suspend(self) -> None:
        """Unsubscribe (e.g. before the process stops on Ctrl-Z); :meth:`resume` subscribes again."""
        if not self.suspended and self.zctx is not None:
            self.close()
            self.suspended = True

    def resume(self) -> None:
        """Subscribe again after :meth:`suspend`; what was published meanwhile is not counted as lost."""
        if self.suspended:
            self.suspended = False
            with self.cond:
                for q in self.queues.values():
                    q.last_seq = None
            self._open()

    def __enter__(self) -> "TopicReader":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def take(self, timeout: float) -> list[tuple[str, int, Message]]:
        """Everything queued now as (topic, receive ns, message), oldest first; waits up to ``timeout``
        when nothing is queued and some topic has not ended."""
        with self.cond:
            if not any(q.items for q in self.queues.values()) and not self._all_eos():
                self.cond.wait(timeout)
            items = []
            for q in self.queues.values():
                while q.items:
                    arrival, (recv_ns, msg) = q.items.popleft()
                    items.append((arrival, q.name, recv_ns, msg))
        items.sort(key=lambda i: i[0])
        return [i[1:] for i in items]

    def _all_eos(self) -> bool:
        return all(q.eos for q in self.queues.values())

    @property
    def ended(self) -> bool:
        """Every topic reached end of stream and nothing is left to take."""
        with self.cond:
            return self._all_eos() and not any(q.items for q in self.queues.values())

    def eos(self, topic: str) -> bool:
        with self.cond:
            return self.queues[topic].eos

    def counters(self, topic: str) -> dict[str, int]:
        """received (by the tool), dropped (by the tool's queue), seq_gaps (lost upstream), invalid."""
        with self.cond:
            q = self.queues[topic]
            return {"received": q.received, "dropped": q.dropped, "seq_gaps": q.seq_gaps, "invalid": q.invalid}

    def close(self) -> None:
        """Unsubscribe now (linger 0). Idempotent."""
        self.suspended = False
        if self.zctx is None:
            return
        stopped = True
        if self.receiver is not None:
            if self.receiver.is_alive():
                self.receiver.stop(self.wake_tx)
                self.receiver.join(3.0)
                stopped = not self.receiver.is_alive()
            else:  # never started: close its sockets here
                for s in list(self.receiver.socks) + [self.receiver.wake]:
                    s.close(0)
        if self.wake_tx is not None:
            self.wake_tx.close(0)
        if stopped:
            self.zctx.term()
        self.zctx = None


# -- not disturbing the start -------------------------------------------------------------------
SURELY_STARTED_S = 65.0  # past the launcher's default ready timeout (60 s): the barrier is over


def wait_for_start(graph: RunningGraph, *, timeout: float | None = None, err: IO[str] | None = None) -> bool:
    """Wait until the graph has passed its readiness barrier; False when it stopped or ``timeout`` passed.

    A node's barrier counts subscriptions per topic, so a tool subscribing to a wired topic while
    the graph starts would stand in for a real subscriber that has not connected yet, and that
    subscriber would miss the first messages. Nodes publish diagnostics only once started, so the
    wait listens to diagnostics topics no node subscribes to (subscribing to those is harmless).
    """
    if (time.time_ns() - graph.started_ns) / 1e9 > SURELY_STARTED_S:
        return True
    safe = [(t.name, t.endpoint) for t in graph_topics(graph).values()
            if t.name.endswith("/diagnostics") and not t.expected]
    if not safe:
        return True  # every node is monitored: nothing harmless to listen to; accept the small race
    t0 = time.monotonic()
    noted = False
    with TopicReader(safe, policy="latest", queue_size=1) as reader:
        while True:
            if reader.take(0.1):
                return True
            waited = time.monotonic() - t0
            if reader.ended or not graph.alive or (timeout is not None and waited > timeout):
                return False
            if not noted and waited > 1.5 and err is not None:
                print("waiting for the graph to start (subscribing earlier could make its nodes miss "
                      "their first messages)", file=err, flush=True)
                noted = True


# -- echo ----------------------------------------------------------------------------------------------
def summarize_array(a: np.ndarray, stats: bool = True) -> str:
    """``ndarray uint8 (480, 640, 3) min 0 max 255``; floats add the mean; empty arrays say so."""
    text = f"ndarray {a.dtype.name} {tuple(a.shape)}"
    if not stats:
        return text
    if a.size == 0:
        return f"{text} empty"
    kind = a.dtype.kind
    if kind == "b":
        return f"{text} true {int(np.count_nonzero(a))} of {a.size}"
    if kind == "c":
        return f"{text} mean {complex(a.mean(dtype=np.complex128)):.6g} max |x| {float(np.abs(a).max()):.6g}"
    if kind == "f":
        finite = a[np.isfinite(a)].astype(np.float64)
        bad = a.size - finite.size
        if finite.size == 0:
            return f"{text} no finite values ({bad} nan/inf)"
        text += f" min {finite.min():.6g} max {finite.max():.6g} mean {finite.mean():.6g}"
        return text + (f" nan/inf {bad}" if bad else "")
    return f"{text} min {a.min()} max {a.max()}"


_PLAIN = set("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_./-+=@")
MAX_INLINE_ITEMS = 32


def _scalar(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else {"inf": ".inf", "-inf": "-.inf"}.get(repr(v), ".nan")
    if isinstance(v, str):
        plain = v and set(v) <= _PLAIN and v not in ("true", "false", "null", "~") and not _looks_numeric(v)
        return v if plain else json.dumps(v)
    return str(v)


def _looks_numeric(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def format_message(msg: Struct, *, arrays: bool = True, indent: str = "") -> list[str]:
    """YAML-like lines for a message or struct: scalars, nested structs, tuples, array summaries."""
    lines = []
    for spec in schema_of(type(msg)):
        lines += _format_field(spec.name, getattr(msg, spec.name), arrays, indent)
    return lines


def _format_field(name: str, value: Any, arrays: bool, indent: str) -> list[str]:
    if isinstance(value, np.ndarray):
        return [f"{indent}{name}: {summarize_array(value, arrays)}"]
    if isinstance(value, Struct):
        return [f"{indent}{name}:", *format_message(value, arrays=arrays, indent=indent + "  ")]
    if isinstance(value, tuple):
        if not value:
            return [f"{indent}{name}: []"]
        if not any(isinstance(v, (Struct, np.ndarray)) for v in value):
            shown = ", ".join(_scalar(v) for v in value[:MAX_INLINE_ITEMS])
            more = f", ... ({len(value) - MAX_INLINE_ITEMS} more)" if len(value) > MAX_INLINE_ITEMS else ""
            return [f"{indent}{name}: [{shown}{more}]"]
        lines = [f"{indent}{name}:"]
        for v in value:
            if isinstance(v, Struct):
                sub = format_message(v, arrays=arrays, indent=indent + "    ")
                lines += [f"{indent}  - {sub[0].lstrip()}", *sub[1:]] if sub else [f"{indent}  - {{}}"]
            else:
                lines.append(f"{indent}  - {summarize_array(v, arrays)}")
        return lines
    return [f"{indent}{name}: {_scalar(value)}"]


_suspend_requested = False


def _on_tstp(signum, frame) -> None:
    global _suspend_requested
    _suspend_requested = True


def _suspend_point(reader: TopicReader, err: IO[str]) -> bool:
    """After Ctrl-Z (CLI only): unsubscribe, stop the process, subscribe again on ``fg``/SIGCONT.

    A stopped process cannot drain its sockets, and publishers wait for a full subscriber (NODROP),
    so staying subscribed while stopped would hold up the graph. True when a suspension happened.
    """
    global _suspend_requested
    if not _suspend_requested:
        return False
    _suspend_requested = False
    reader.suspend()
    print("\n[suspended: unsubscribed so the graph is not held up; resubscribes on fg]", file=err, flush=True)
    os.kill(os.getpid(), signal.SIGSTOP)  # SIGSTOP: unlike SIGTSTP it also stops an orphaned process group
    reader.resume()
    print("[resumed: subscribed again; messages published meanwhile were not received]", file=err, flush=True)
    return True


@contextlib.contextmanager
def cli_signals(suspend: bool = False):
    """For the CLI: SIGINT and SIGTERM end a tool cleanly (sockets closed); with ``suspend``, Ctrl-Z
    unsubscribes before stopping (see :func:`_suspend_point`). A no-op outside the main thread."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    global _suspend_requested
    _suspend_requested = False
    wanted = {signal.SIGINT: interrupt, signal.SIGTERM: interrupt}
    if suspend:
        wanted[signal.SIGTSTP] = _on_tstp
    old = {}
    try:
        for sig, handler in wanted.items():
            old[sig] = signal.signal(sig, handler)
        yield
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)


def _launcher_gone(graph: RunningGraph, state: dict) -> bool:
    """True once the launcher has exited (checked at most once a second)."""
    now = time.monotonic()
    if now - state.get("t", 0.0) < 1.0:
        return False
    state["t"] = now
    return not graph.alive


def echo(graph: RunningGraph, topic_name: str, *, count: int | None = None, arrays: bool = True,
         queue_size: int = 100, policy: str = "drop_oldest", out: IO[str] | None = None,
         err: IO[str] | None = None) -> int:
    """Print messages of a topic until ``count``, end of stream, the graph's end or Ctrl-C; the count printed."""
    out, err = out or sys.stdout, err or sys.stderr
    topic = find_topic(graph, topic_name)
    _import_publisher(topic)
    if not topic.declared:
        print(f"note: {topic.name} is not declared in the plan; subscribing to {topic.publisher} anyway", file=err)
    printed = 0
    check: dict = {}
    reason = None
    try:
        if topic.expected and not wait_for_start(graph, err=err):
            print(f"{topic.name}: the graph stopped before it started", file=err)
            return 0
    except KeyboardInterrupt:
        return 0
    with TopicReader([(topic.name, topic.endpoint)], policy=policy, queue_size=queue_size) as reader:
        try:
            while reason is None and (count is None or printed < count):
                _suspend_point(reader, err)
                for _, _, msg in reader.take(0.2):
                    seq = getattr(getattr(msg, "header", None), "seq", None)
                    lines = [f"--- {topic.name} {msg.TYPE_NAME}" + (f" seq {seq}" if seq is not None else ""),
                             *format_message(msg, arrays=arrays)]
                    out.write("\n".join(lines) + "\n")
                    out.flush()
                    printed += 1
                    if count is not None and printed >= count:
                        break
                else:
                    if reader.ended:
                        reason = "end of stream"
                    elif _launcher_gone(graph, check):
                        reason = "the graph stopped"
        except KeyboardInterrupt:
            reason = "interrupted"
        counters = reader.counters(topic.name)
    if reason in ("end of stream", "the graph stopped"):
        print(f"{topic.name}: {reason} after {printed} message(s)", file=err)
    if counters["dropped"]:
        print(f"note: skipped {counters['dropped']} message(s): printing could not keep up "
              f"(tool queue of {queue_size})", file=err)
    return printed


# -- hz ----------------------------------------------------------------------------------------------------
class RateStats:
    """Rate of a stream over a sliding window of messages, from header stamps, seq and receive times.

    The stamp rate uses the seq span, so messages the tool itself dropped do not lower it; period
    min/max/std use only consecutive pairs (seq + 1).
    """

    def __init__(self, window: int = 100):
        self.window = max(2, window)
        self.items: deque = deque(maxlen=self.window)   # (stamp_ns, recv_ns, seq)
        self.total = 0
        self.resets = 0

    def add(self, stamp_ns: int, recv_ns: int, seq: int | None) -> None:
        if self.items:
            last_stamp, _, last_seq = self.items[-1]
            if stamp_ns < last_stamp or (seq is not None and last_seq is not None and seq <= last_seq):
                self.items.clear()  # clock jumped back or the publisher restarted
                self.resets += 1
        self.items.append((stamp_ns, recv_ns, seq))
        self.total += 1

    def report(self) -> dict[str, Any]:
        items = list(self.items)
        rep: dict[str, Any] = {"count": self.total, "window": len(items), "rate_hz": None, "receive_hz": None,
                               "min_ms": None, "max_ms": None, "mean_ms": None, "std_ms": None}
        if len(items) < 2:
            return rep
        (s0, r0, q0), (s1, r1, q1) = items[0], items[-1]
        n_periods = (q1 - q0) if q0 is not None and q1 is not None and q1 > q0 else len(items) - 1
        if s1 > s0:
            rep["rate_hz"] = n_periods / ((s1 - s0) / 1e9)
            rep["mean_ms"] = (s1 - s0) / n_periods / 1e6
        if r1 > r0:
            rep["receive_hz"] = (len(items) - 1) / ((r1 - r0) / 1e9)
        periods = np.array([(b[0] - a[0]) / 1e6 for a, b in zip(items, items[1:])
                            if a[2] is None or b[2] is None or b[2] == a[2] + 1])
        if periods.size:
            rep.update(min_ms=float(periods.min()), max_ms=float(periods.max()), std_ms=float(periods.std()))
        return rep


def _fmt(v: float | None, spec: str) -> str:
    return "-" if v is None else format(v, spec)


def format_rate(rep: dict[str, Any]) -> str:
    return (f"rate {_fmt(rep['rate_hz'], '.3f')} Hz  period min {_fmt(rep['min_ms'], '.3f')} "
            f"max {_fmt(rep['max_ms'], '.3f')} std {_fmt(rep['std_ms'], '.3f')} ms  (stamps, window {rep['window']})"
            f"  receive {_fmt(rep['receive_hz'], '.3f')} Hz  seq gaps {rep['seq_gaps']}"
            f"  tool dropped {rep['tool_dropped']}  messages {rep['count']}")


def hz(graph: RunningGraph, topic_name: str, *, window: int = 100, duration: float | None = None,
       queue_size: int = 1000, interval: float = 1.0, out: IO[str] | None = None,
       err: IO[str] | None = None) -> dict[str, Any]:
    """Print the topic's rate once per ``interval`` until ``duration``, end of stream, the graph's end
    or Ctrl-C; return the final statistics (RateStats.report() plus seq_gaps, tool_dropped, reason)."""
    out, err = out or sys.stdout, err or sys.stderr
    topic = find_topic(graph, topic_name)
    _import_publisher(topic)
    stats = RateStats(window)
    try:
        if topic.expected and not wait_for_start(graph, err=err, timeout=duration):
            print(f"{topic.name}: the graph did not start", file=err)
            return dict(stats.report(), seq_gaps=0, tool_dropped=0, invalid=0, reason="not started")
    except KeyboardInterrupt:
        return dict(stats.report(), seq_gaps=0, tool_dropped=0, invalid=0, reason="interrupted")
    t0 = time.monotonic()
    next_print = t0 + interval
    last_total = 0
    check: dict = {}
    reason = None
    with TopicReader([(topic.name, topic.endpoint)], policy="drop_oldest", queue_size=queue_size) as reader:
        def report() -> dict[str, Any]:
            c = reader.counters(topic.name)
            return dict(stats.report(), seq_gaps=c["seq_gaps"], tool_dropped=c["dropped"], invalid=c["invalid"])

        try:
            while reason is None:
                if _suspend_point(reader, err):
                    stats.items.clear()  # receive times span the pause: start the window afresh
                now = time.monotonic()
                end = t0 + duration if duration is not None else math.inf
                for _, recv_ns, msg in reader.take(max(0.0, min(next_print, end) - now)):
                    header = getattr(msg, "header", None)
                    if header is not None:
                        stats.add(header.stamp_ns, recv_ns, header.seq)
                now = time.monotonic()
                if now >= end:
                    reason = "duration"
                elif reader.ended:
                    reason = "end of stream"
                elif _launcher_gone(graph, check):
                    reason = "the graph stopped"
                if now >= next_print and reason is None:
                    next_print += interval * max(1, math.floor((now - next_print) / interval) + 1)
                    if stats.total == last_total:
                        print(f"{topic.name}: no new messages", file=out, flush=True)
                    else:
                        print(f"{topic.name}: {format_rate(report())}", file=out, flush=True)
                    last_total = stats.total
        except KeyboardInterrupt:
            reason = "interrupted"
        final = dict(report(), reason=reason)
    print(f"{topic.name} ({reason}): {format_rate(final)}", file=out, flush=True)
    return final


# -- info ------------------------------------------------------------------------------------------------------
def topic_info(graph: RunningGraph, topic_name: str, *, timeout: float = 2.5) -> dict[str, Any]:
    """Type, publisher and subscribers of a topic, with each subscriber's counters for it read
    from its NodeStatus (up to ``timeout`` seconds of listening to the nodes' diagnostics)."""
    topic = find_topic(graph, topic_name)
    nodes = graph.plan["nodes"]
    watch = [topic.publisher] + [s.node for s in topic.subscribers]
    diag = {f"{n}/diagnostics": nodes[n]["endpoint"] for n in dict.fromkeys(watch)}
    statuses: dict[str, Any] = {}
    deadline = time.monotonic() + timeout
    topics = graph_topics(graph)
    if any(topics[t].expected for t in diag if t in topics):
        wait_for_start(graph, timeout=timeout)
    with TopicReader(diag.items(), policy="latest", queue_size=1) as reader:
        while len(statuses) < len(diag) and time.monotonic() < deadline:
            for name, _, msg in reader.take(min(0.1, max(0.0, deadline - time.monotonic()))):
                statuses[name.rpartition("/")[0]] = msg
            if reader.ended:
                break
    pub_status = statuses.get(topic.publisher)
    published = None
    if pub_status is not None:
        for entry in pub_status.published:
            t, _, n = entry.rpartition("=")
            if t == topic.name and n.isdigit():
                published = int(n)
    subs = []
    for s in topic.subscribers:
        st = statuses.get(s.node)
        counters = None
        if st is not None:
            c = next((c for c in st.inputs if c.topic == topic.name and c.name == s.input), None)
            c = c or next((c for c in st.inputs if c.topic == topic.name), None)
            if c is not None:
                counters = {"received": c.received, "dropped": c.dropped, "seq_gaps": c.seq_gaps,
                            "queued": c.queued, "invalid": c.invalid}
        subs.append({"node": s.node, "input": s.input, "policy": s.policy, "queue_size": s.queue_size,
                     "node_state": st.state if st is not None else None, "counters": counters})
    return {"topic": topic.name, "type": topic.type_name, "declared": topic.declared,
            "publisher": {"node": topic.publisher, "node_type": topic.node_type, "endpoint": topic.endpoint,
                          "state": pub_status.state if pub_status is not None else None, "published": published},
            "subscribers": subs, "timeout": timeout}


def print_info(info: dict[str, Any], out: IO[str] | None = None) -> None:
    out = out or sys.stdout
    p = info["publisher"]
    print(f"topic: {info['topic']}", file=out)
    print(f"type: {info['type'] or '? (unknown)'}", file=out)
    extra = "" if p["state"] is None else f"  state {p['state']}"
    extra += "" if p["published"] is None else f"  published {p['published']}"
    if p["state"] is None:
        extra += f"  (no diagnostics within {info['timeout']:g} s)"
    print(f"publisher: {p['node']} ({p['node_type']}) at {p['endpoint']}{extra}", file=out)
    print(f"subscribers: {len(info['subscribers'])}", file=out)
    for s in info["subscribers"]:
        line = f"  {s['node']}.{s['input']}  policy {s['policy']}  queue_size {s['queue_size']}"
        c = s["counters"]
        if c is not None:
            line += (f"  received {c['received']}  dropped {c['dropped']}  seq_gaps {c['seq_gaps']}"
                     f"  queued {c['queued']}  invalid {c['invalid']}")
        elif s["node_state"] is None:
            line += f"  (no diagnostics within {info['timeout']:g} s)"
        else:
            line += "  (no counters for this topic in its diagnostics)"
        print(line, file=out)


# -- command line -----------------------------------------------------------------------------------------------
def _graph(ns: argparse.Namespace) -> RunningGraph:
    return select_graph(ns.graph_dir)


def _quiet_broken_pipe() -> int:
    """stdout went away (``| head``): stop quietly, like other Unix tools."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass
    return 0


def cmd_topic_list(ns: argparse.Namespace) -> int:
    try:
        with cli_signals():
            list_topics(_graph(ns), verbose=ns.verbose)
    except BrokenPipeError:
        return _quiet_broken_pipe()
    return 0


def cmd_topic_echo(ns: argparse.Namespace) -> int:
    count = 1 if ns.once else ns.count
    try:
        with cli_signals(suspend=True):
            echo(_graph(ns), ns.topic, count=count, arrays=not ns.no_arrays, queue_size=ns.queue_size)
    except BrokenPipeError:
        return _quiet_broken_pipe()
    return 0


def cmd_topic_hz(ns: argparse.Namespace) -> int:
    try:
        with cli_signals(suspend=True):
            hz(_graph(ns), ns.topic, window=ns.window, duration=ns.duration, queue_size=ns.queue_size)
    except BrokenPipeError:
        return _quiet_broken_pipe()
    return 0


def cmd_topic_info(ns: argparse.Namespace) -> int:
    try:
        with cli_signals():
            print_info(topic_info(_graph(ns), ns.topic, timeout=ns.timeout))
    except BrokenPipeError:
        return _quiet_broken_pipe()
    return 0


def _positive_int(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError("must be >= 1")
    return value


def _positive_float(text: str) -> float:
    value = float(text)
    if not value > 0:
        raise argparse.ArgumentTypeError("must be > 0")
    return value


def add_topic_parser(sub: Any) -> argparse.ArgumentParser:
    """Add ``topic {list,echo,hz,info}`` to an argparse subparsers object; each sets ``func``."""
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--graph-dir", metavar="RUN_DIR",
                        help="the run directory of the graph to inspect (default: the most recently "
                             "started running graph under $PROBELESS_RUN_DIR or $TMPDIR/probeless-<uid>)")
    p = sub.add_parser("topic", help="inspect the topics of a running graph: list, echo, hz, info",
                       description="Inspect the topics of a running graph. The tools never slow the graph "
                                   "down: they drop (and count) what they cannot keep up with.")
    tsub = p.add_subparsers(dest="topic_command", required=True, metavar="{list,echo,hz,info}")

    c = tsub.add_parser("list", parents=[common], help="topics with type, publisher and subscriber count")
    c.add_argument("-v", "--verbose", action="store_true", help="also show endpoints and each subscriber's input")
    c.set_defaults(func=cmd_topic_list)

    c = tsub.add_parser("echo", parents=[common], help="print the messages of a topic")
    c.add_argument("topic")
    c.add_argument("-n", "--count", type=_positive_int, help="stop after N messages")
    c.add_argument("--once", action="store_true", help="print one message and stop (same as -n 1)")
    c.add_argument("--no-arrays", action="store_true", help="show arrays as dtype and shape only, no statistics")
    c.add_argument("--queue-size", type=_positive_int, default=100,
                   help="messages buffered while printing (drop_oldest; default 100)")
    c.set_defaults(func=cmd_topic_echo)

    c = tsub.add_parser("hz", parents=[common], help="publishing rate of a topic, once per second")
    c.add_argument("topic")
    c.add_argument("--window", type=_positive_int, default=100, help="messages in the sliding window (default 100)")
    c.add_argument("--duration", type=_positive_float, help="stop after S seconds")
    c.add_argument("--queue-size", type=_positive_int, default=1000, help="tool queue (drop_oldest; default 1000)")
    c.set_defaults(func=cmd_topic_hz)

    c = tsub.add_parser("info", parents=[common], help="type, publisher, subscribers and their drop counters")
    c.add_argument("topic")
    c.add_argument("--timeout", type=_positive_float, default=2.5,
                   help="seconds to wait for the nodes' diagnostics (default 2.5)")
    c.set_defaults(func=cmd_topic_info)
    return p


def topic_main(argv: list[str] | None = None) -> int:
    """``probeless topic ...`` on its own (``python -m probeless.topic_tools list``); the exit code."""
    parser = argparse.ArgumentParser(prog="probeless")
    add_topic_parser(parser.add_subparsers(dest="command", required=True))
    argv = sys.argv[1:] if argv is None else list(argv)
    if not argv or argv[0] != "topic":
        argv = ["topic", *argv]
    ns = parser.parse_args(argv)
    try:
        return ns.func(ns)
    except ProbelessError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 0


if __name__ == "__main__":
    sys.exit(topic_main())
