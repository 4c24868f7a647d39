"""One node process: ``python -m probeless.runtime.process RUN_DIR NODE_ID``.

Lifecycle: load the resolved graph plan from RUN_DIR, build the node, ``setup()``, bind outputs,
connect inputs, wait until every expected subscriber of every output is connected (readiness
barrier), report ready to the launcher, wait for start, then run callbacks on this thread until
the inputs end, the node stops itself, or SIGINT/SIGTERM. ``close()`` always runs; outputs get an
end-of-stream marker on a normal end. Exit code 0 on a clean end, 1 after an error. An error of
ours (:class:`~probeless.errors.ProbelessError`: a bad param, a missing scene file, a dead camera...)
is logged as one line naming the node; anything else with its traceback (a bug).
"""

from __future__ import annotations

import faulthandler
import gc
import json
import logging
import os
import signal
import sys
import threading
import time
import traceback
from collections import deque
from pathlib import Path
from typing import Any, Callable

import msgpack
import zmq

from probeless.errors import GraphError, ProbelessError, TransportError
from probeless.messages.base import Message
from probeless.messages.diagnostics import InputCounters, NodeStatus
from probeless.messages.header import Header, Tick
from probeless.runtime import control as tool_control
from probeless.runtime.clock import NodeClock
from probeless.runtime.latching import is_latched
from probeless.runtime.memwatch import MemoryWatch, rss_bytes
from probeless.runtime.node import Node, output_type
from probeless.runtime.params import load_params
from probeless.runtime.queues import QUEUE_MAX_BYTES, InputQueue
from probeless.runtime.receiver import InputWire, Receiver, hello_topic
from probeless.runtime.registry import resolve_node
from probeless.runtime.security import node_curve
from probeless.runtime.stats import Timings
from probeless.runtime.timers import TimerSet
from probeless.runtime.transport import Publisher

DIAGNOSTICS_PERIOD_NS = 1_000_000_000
LATCH_POLL_S = 0.02   # how often a node holding latched messages looks for late joiners [s]
CLOCK_INPUT = "__clock__"


class NodeRuntime:
    """Runs one node; implements the :class:`~probeless.runtime.node.Context` it is given."""

    def __init__(self, plan: dict[str, Any], node_id: str, wake_endpoint: str):
        self.plan = plan
        self.spec = spec = plan["nodes"][node_id]
        self.node_id = node_id
        self.log = logging.getLogger(node_id)
        self.control_endpoint = plan.get("control")
        self.wake_endpoint = wake_endpoint
        self.started_at = time.monotonic()
        self.timings = Timings()
        self.timers, self.wall_timers = TimerSet(), TimerSet()
        self.clock = NodeClock()
        self.cond = threading.Condition()
        self.stop_requested = False
        self.busy = False
        self.state = "starting"
        self.zctx = zmq.Context()
        self.curve = node_curve(plan, node_id)  # None unless the graph asks for CURVE
        self.node_cls = resolve_node(spec["node"], base=Path(spec["file"]).parent if spec.get("file") else None)
        self.wires = [InputWire(i["name"], i["endpoint"], i["topic"], i.get("type_name"),
                                raw=getattr(self.node_cls, "RAW_INPUTS", False))
                      for i in spec["inputs"] if "topic" in i]
        if spec.get("clock"):
            self.wires.append(InputWire(CLOCK_INPUT, spec["clock"]["endpoint"], spec["clock"]["topic"], "core/Clock"))
        self.queues = {w.name: InputQueue(w.name, *self._policy(w.name)) for w in self.wires}
        self.open_inputs = set(self.queues) - {CLOCK_INPUT}
        # a node ends when its inputs have ended; feedback inputs (loops) don't keep it alive
        self.lifetime_inputs = {i["name"] for i in spec["inputs"] if not i.get("feedback")} & self.open_inputs
        self.callback_names = {name: f"on_input:{name}" for name in self.queues}
        self.topics = {name: out["topic"] for name, out in spec["outputs"].items()}
        self.latched = {out["topic"] for out in spec["outputs"].values() if out.get("latched")}
        self.next_latch_poll = 0.0
        self.node: Node | None = None
        self.memory, self.memory_warned = MemoryWatch(), False
        # the tools' channel (control.py): node info, run-time params
        self.params = None
        self.param_updates: deque = deque()
        self.rates: dict[tuple[str, str], float] = {}   # ("in", input) / ("out", topic) -> messages per second
        self.last_counts: tuple[float, dict] | None = None
        self.last_timings: list[dict] = []
        self.memory_last = 0

    def uptime_s(self) -> float:
        return time.monotonic() - self.started_at

    def _policy(self, name: str) -> tuple[str, int, int]:
        """(policy, queue_size, max_bytes) of an input; ``max_bytes`` from the plan, else the default bound."""
        if name == CLOCK_INPUT:
            return "block", 64, QUEUE_MAX_BYTES
        spec = next(i for i in self.spec["inputs"] if i["name"] == name)
        return spec["policy"], spec["queue_size"], int(spec.get("max_bytes", QUEUE_MAX_BYTES))

    # -- Context API -------------------------------------------------------
    def publish(self, output: str, msg: Message) -> None:
        self.publisher.publish(self._topic(output), msg, lambda: self.stop_requested)

    def publish_raw(self, output: str, frames: list) -> None:
        """Publish recorded frames unchanged (replay); ``output`` must be declared."""
        self.publisher.publish_raw(self._topic(output), frames, lambda: self.stop_requested)

    def _topic(self, output: str) -> str:
        topic = self.topics.get(output)
        if topic is None:
            if not output_type(self.node_cls, output)[0]:
                raise ValueError(f"node {self.node_id!r} has no output {output!r}")
            topic = self.topics[output] = f"{self.node_id}/{output}"
            if is_latched(output, self.spec.get("latched")):  # an output the plan does not list (a family's)
                self.publisher.latched.add(topic)
        return topic

    def create_timer(self, period_s: float, callback: Callable[[], None], name: str | None = None):
        name = name or f"timer:{getattr(callback, '__name__', 'callback')}"
        return self.timers.add(int(period_s * 1e9), name, lambda missed: callback(), self.clock.monotonic_ns())

    def now_ns(self) -> int:
        return self.clock.now_ns()

    @property
    def simulated_time(self) -> bool:
        """True while following a replay's recorded clock."""
        return self.clock.simulated

    def stop(self) -> None:
        self.stop_requested = True

    def timed(self, stage: str):
        return self.timings.time(stage)

    def wait_quiescent(self) -> bool:
        """Block until the launcher reports every other node idle with nothing in flight (lockstep)."""
        self.receiver.quiet.clear()
        published = dict(self.publisher.published)
        self.receiver.send_control(b"quiesce", msgpack.packb(published), wake_tx=self.wake_tx)
        while not self.stop_requested:
            if self.receiver.quiet.wait(0.1):
                return True
        return False

    # -- lifecycle -----------------------------------------------------------
    def run(self) -> int:
        ok = False
        try:
            params = self.params = load_params(self.node_cls.Params, self.spec.get("params"), node_id=self.node_id,
                                               file=self.spec.get("file"), line=self.spec.get("line"))
            self.publisher = Publisher(self.zctx, self.spec["endpoint"], self.node_id, self.clock.now_ns,
                                       curve=self.curve, latched=self.latched)
            self.node = self.node_cls(self, params)
            with self.timed("setup"):
                self.node.setup()
            gc.freeze()  # set-up's objects (modules, models) leave the collector's view: shorter GC pauses
            self._start_receiver()
            if not self._barrier():
                return self._finish(eos=False, code=0)
            self._add_builtin_timers()
            self.state = "running"
            self._loop()
            ok = True
        except TransportError as exc:
            if not self.stop_requested:
                self.log.error("%s", exc)
        except ProbelessError as exc:  # our own errors say what is wrong: one line, no traceback
            self.log.error("%s", self._one_line(exc))
        except Exception:
            self.log.error("node crashed:\n%s", traceback.format_exc().rstrip())
        return self._finish(eos=ok, code=0 if ok or self.stop_requested else 1)

    def _one_line(self, exc: ProbelessError) -> str:
        """``node 'ID': ErrorType: message`` (a GraphError/ParamError names the node itself)."""
        if isinstance(exc, GraphError) and exc.node_id:
            return f"{type(exc).__name__}: {exc}"
        return f"node '{self.node_id}': {type(exc).__name__}: {exc}"

    def _start_receiver(self) -> None:
        control = (self.control_endpoint, self.node_id) if self.control_endpoint else None
        tools = ((self.spec["ctl_endpoint"], lambda req, ident: tool_control.handle(self, req, ident))
                 if self.spec.get("ctl_endpoint") else None)
        self.receiver = Receiver(self.zctx, self.wires, self.queues, self.cond, self.wake_endpoint,
                                 control=control, status=self._status, node_id=self.node_id, curve=self.curve,
                                 tools=tools)
        self.wake_tx = self.zctx.socket(zmq.PAIR)
        self.wake_tx.connect(self.wake_endpoint)
        self.receiver.start()

    def _status(self) -> dict:
        """Snapshot for the launcher's lockstep quiescence check (runs on the receiver thread)."""
        with self.cond:
            queued = sum(len(q.items) for q in self.queues.values()) + len(self.receiver.pending)
            received = {n: q.received + q.invalid for n, q in self.queues.items()}
            return {"busy": self.busy, "queued": queued, "received": received,
                    "published": dict(self.publisher.published)}

    def _barrier(self) -> bool:
        """Wait for all expected subscribers, report ready, wait for start. False if stopped first."""
        expected = [(out["topic"], sub) for out in self.spec["outputs"].values()
                    for sub in out.get("subscriber_ids", [])]
        last_note = time.monotonic()
        while not self.stop_requested:
            self.publisher.poll_subscriptions(50)
            subs = self.publisher.subscriptions
            missing = [(t, sub) for t, sub in expected if subs[hello_topic(*sub).decode()] < 1 or subs[t] < 1]
            if not missing:
                break
            if time.monotonic() - last_note > 5:
                last_note = time.monotonic()
                self.log.info("waiting for subscribers: %s",
                              ", ".join(f"{node}.{inp} on {t}" for t, (node, inp) in missing))
        if self.stop_requested or not self.control_endpoint:
            return not self.stop_requested
        self.receiver.send_control(b"ready", wake_tx=self.wake_tx)
        while not self.stop_requested:
            if self.receiver.started.wait(0.1):
                return True
        return False

    def _add_builtin_timers(self) -> None:
        now = self.clock.monotonic_ns()
        for i in self.spec["inputs"]:
            if "timer_period_ns" in i:
                self.timers.add(i["timer_period_ns"], f"on_input:{i['name']}",
                                self._tick_fn(i["name"], i["timer_period_ns"]), now - i["timer_period_ns"])
        self.wall_timers.add(DIAGNOSTICS_PERIOD_NS, "_diagnostics", lambda missed: self._publish_diagnostics(),
                             time.monotonic_ns())

    def _tick_fn(self, name: str, period_ns: int) -> Callable[[int], None]:
        def fire(missed: int) -> None:
            self.node.on_input(name, Tick(Header(self.now_ns(), "timer"), period_ns, missed))
        return fire

    def _loop(self) -> None:
        while not self.stop_requested:
            if self.param_updates:
                tool_control.apply_updates(self)
            if self.publisher.last and time.monotonic() >= self.next_latch_poll:
                self.next_latch_poll = time.monotonic() + LATCH_POLL_S
                self.publisher.serve_late_joiners(lambda: self.stop_requested)
            for timer, missed in self.wall_timers.pop_due(time.monotonic_ns()):
                timer.fire(missed)
            for timer, missed in self.timers.pop_due(self.clock.monotonic_ns()):
                t0 = time.perf_counter()
                timer.fire(missed)
                self.timings.add(timer.name, time.perf_counter() - t0)
                if self.stop_requested:
                    return
            name, msg, closed = self._next_message()
            if name == CLOCK_INPUT:
                self._on_clock(msg)
            elif name is not None:
                t0 = time.perf_counter()
                self.node.on_input(name, msg)
                self.timings.add(self.callback_names[name], time.perf_counter() - t0)
            self.busy = False
            for c in closed:
                self.node.on_input_closed(c)
            if self.queues.keys() - {CLOCK_INPUT} and not (self.open_inputs & self.lifetime_inputs):
                return

    def _on_clock(self, msg) -> None:
        if self.clock.update(msg):
            self.timers.reset(self.clock.monotonic_ns())
            hook = getattr(self.node, "on_time_reset", None)
            if hook is not None:
                hook()

    def _next_message(self):
        """Pop the oldest queued message across inputs, or wait until one arrives or a timer is due."""
        with self.cond:
            best = None
            waiting_for_clock = CLOCK_INPUT in self.queues and not self.clock.simulated
            for q in self.queues.values():
                if waiting_for_clock and q.name != CLOCK_INPUT:
                    continue  # on replay, nothing is dispatched before the first recorded time is known
                head = q.head_arrival()
                if head is not None and (best is None or head < best.head_arrival()):
                    best = q
            closed = ()
            if self.receiver.eos_seen:
                closed = [n for n in self.open_inputs if self.queues[n].eos and not self.queues[n].items]
                self.open_inputs.difference_update(closed)
            if best is not None:
                was_full = best.policy == "block" and best.full
                msg = best.pop()
                self.busy = True  # under the lock: a status snapshot never sees popped-but-idle
                if was_full:
                    self.wake_tx.send(b"")
                return best.name, msg, closed
            if not closed:
                self.cond.wait(self._wait_s())
            return None, None, closed

    def _wait_s(self) -> float:
        deadlines = [d for d in (self.wall_timers.next_deadline(),) if d is not None]
        wall = [(d - time.monotonic_ns()) / 1e9 for d in deadlines]
        nxt = self.timers.next_deadline()
        if nxt is not None and not self.clock.simulated:
            wall.append((nxt - time.monotonic_ns()) / 1e9)
        return max(0.0, min(wall + [0.1]))

    def _publish_diagnostics(self) -> None:
        with self.cond:
            inputs = tuple(InputCounters(q.name, self._input_topic(q.name), q.policy, q.queue_size,
                                         len(q.items), q.received, q.dropped, q.seq_gaps, q.invalid,
                                         q.queued_bytes, q.restarts)
                           for q in self.queues.values() if q.name != CLOCK_INPUT)
        self.publisher.poll_subscriptions(0)
        self._update_rates()
        rss = self.memory_last = rss_bytes()
        self.memory.sample(rss)
        warnings = (self.memory.describe(),) if self.memory.growing else ()
        if warnings and not self.memory_warned:
            self.memory_warned = True
            self.log.warning("%s", warnings[0])
        timings = self.timings.report()
        self.last_timings = [{"name": t.name, "count": t.count, "p50_ms": t.p50_ms, "max_ms": t.max_ms}
                             for t in timings if t.count]
        status = NodeStatus(Header(self.now_ns(), self.node_id), self.node_id, self.state,
                            time.monotonic() - self.started_at, timings, inputs,
                            tuple(f"{t}={n}" for t, n in self.publisher.published.items()), rss, warnings)
        self.publisher.publish(f"{self.node_id}/diagnostics", status, lambda: self.stop_requested)

    def _update_rates(self) -> None:
        """Messages per second of each input and output since the last diagnostics (for ``node info``)."""
        now = time.monotonic()
        with self.cond:
            counts = {("in", q.name): q.received for q in self.queues.values()}
        counts.update({("out", t): n for t, n in self.publisher.published.items()})
        if self.last_counts is not None and now > self.last_counts[0]:
            t0, before = self.last_counts
            self.rates = {k: (n - before.get(k, 0)) / (now - t0) for k, n in counts.items()}
        self.last_counts = (now, counts)

    def _input_topic(self, name: str) -> str:
        return next(w.topic for w in self.wires if w.name == name)

    def _end_streams(self) -> None:
        """Final status, end-of-stream on every output, then wait for subscribers to drain.

        A signal during the wait shortens it to a grace period, so a stopping graph never hangs.
        """
        signalled = self.stop_requested
        self.stop_requested = False
        grace = time.monotonic() + 2.0
        stop = lambda: (self.stop_requested or signalled) and time.monotonic() > grace  # noqa: E731
        try:
            self._publish_diagnostics()
            for topic in self.topics.values():
                self.publisher.send_eos(topic, stop)
            self.publisher.wait_drained(list(self.topics.values()), stop,
                                        lambda busy: self.log.info("waiting for subscribers to drain: %s", busy))
        except TransportError:
            self.log.warning("end of stream not delivered to every subscriber before shutdown")

    def _finish(self, eos: bool, code: int) -> int:
        self.state = "stopping"
        if self.node is not None:
            try:
                self.node.close()
            except TransportError as exc:  # a last publish from close() cut short by the shutdown: not a failure
                self.log.warning("close(): %s", exc)
            except ProbelessError as exc:
                self.log.error("close() failed: %s", self._one_line(exc))
                code = 1
            except Exception:
                self.log.error("close() failed:\n%s", traceback.format_exc().rstrip())
                code = 1
        if eos and hasattr(self, "publisher"):
            self._end_streams()
        if hasattr(self, "receiver"):
            self.receiver.stop(self.wake_tx)
            self.receiver.join(2.0)
            self.wake_tx.close(0)
        if hasattr(self, "publisher"):
            self.publisher.close()
        if self.curve is not None:
            self.curve.stop()
        self.zctx.term()
        return code


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    run_dir, node_id = Path(argv[0]), argv[1]
    plan = json.loads((run_dir / "graph.json").read_text())
    logging.basicConfig(level=os.environ.get("PROBELESS_LOG", "INFO"), stream=sys.stderr,
                        format="%(levelname)s %(name)s: %(message)s")
    runtime = NodeRuntime(plan, node_id, f"inproc://wake-{plan['nodes'][node_id]['index']}")

    def on_signal(signum, frame):
        runtime.stop_requested = True

    faulthandler.register(signal.SIGUSR1, all_threads=True)  # `kill -USR1 PID` dumps every thread's stack
    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    return runtime.run()


if __name__ == "__main__":
    sys.exit(main())
