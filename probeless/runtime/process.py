"""One node process: ``python -m probeless.runtime.process RUN_DIR NODE_ID``.

Lifecycle: load the resolved graph spec from RUN_DIR, build the node, ``setup()``, bind outputs,
connect inputs, wait until every expected subscriber of every output is connected (readiness
barrier), report ready to the launcher, wait for start, then run callbacks on this thread until
the inputs end, the node stops itself, or SIGINT/SIGTERM. ``close()`` always runs; outputs get an
end-of-stream marker on a normal end. Exit code 0 on a clean end, 1 after an error.
"""

from __future__ import annotations

import faulthandler
import json
import logging
import os
import signal
import sys
import threading
import time
import traceback
from pathlib import Path
from typing import Any, Callable

import zmq

from probeless.errors import TransportError
from probeless.messages.base import Message
from probeless.messages.diagnostics import InputCounters, NodeStatus
from probeless.messages.header import Header, Tick
from probeless.runtime.node import Node, output_type
from probeless.runtime.params import load_params
from probeless.runtime.queues import InputQueue
from probeless.runtime.registry import resolve_node
from probeless.runtime.stats import Timings
from probeless.runtime.timers import TimerSet
from probeless.runtime.transport import InputWire, Publisher, Receiver

DIAGNOSTICS_PERIOD_NS = 1_000_000_000


class NodeRuntime:
    """Runs one node; implements the :class:`~probeless.runtime.node.Context` it is given."""

    def __init__(self, spec: dict[str, Any], control: str | None, wake_endpoint: str):
        self.spec = spec
        self.node_id: str = spec["id"]
        self.log = logging.getLogger(self.node_id)
        self.control_endpoint = control
        self.wake_endpoint = wake_endpoint
        self.started_at = time.monotonic()
        self.timings = Timings()
        self.timers = TimerSet()
        self.cond = threading.Condition()
        self.stop_requested = False
        self.state = "starting"
        self.zctx = zmq.Context()
        self.queues = {i["name"]: InputQueue(i["name"], i["policy"], i["queue_size"])
                       for i in spec["inputs"] if "topic" in i}
        self.open_inputs = set(self.queues)
        self.callback_names = {name: f"on_input:{name}" for name in self.queues}
        self.topics = {name: out["topic"] for name, out in spec["outputs"].items()}
        self.node: Node | None = None
        self.node_cls = resolve_node(spec["node"])

    # -- Context API -------------------------------------------------------
    def publish(self, output: str, msg: Message) -> None:
        topic = self.topics.get(output)
        if topic is None:
            declared, _ = output_type(self.node_cls, output)
            if not declared:
                raise ValueError(f"node {self.node_id!r} has no output {output!r}")
            topic = self.topics[output] = f"{self.node_id}/{output}"
        self.publisher.publish(topic, msg, lambda: self.stop_requested)

    def create_timer(self, period_s: float, callback: Callable[[], None], name: str | None = None):
        name = name or f"timer:{getattr(callback, '__name__', 'callback')}"
        return self.timers.add(int(period_s * 1e9), name, lambda missed: callback(),
                               time.monotonic_ns())

    def now_ns(self) -> int:
        return time.time_ns()

    def stop(self) -> None:
        self.stop_requested = True

    def timed(self, stage: str):
        return self.timings.time(stage)

    # -- lifecycle -----------------------------------------------------------
    def run(self) -> int:
        ok = False
        try:
            params = load_params(self.node_cls.Params, self.spec.get("params"), node_id=self.node_id,
                                 file=self.spec.get("file"), line=self.spec.get("line"))
            self.publisher = Publisher(self.zctx, self.spec["endpoint"], self.node_id)
            self.node = self.node_cls(self, params)
            with self.timed("setup"):
                self.node.setup()
            self.receiver = self._start_receiver()
            if not self._barrier():
                return self._finish(eos=False, code=0)
            self._add_builtin_timers()
            self.state = "running"
            self._loop()
            ok = True
        except TransportError as exc:
            if not self.stop_requested:
                self.log.error("%s", exc)
        except Exception:
            self.log.error("node crashed:\n%s", traceback.format_exc().rstrip())
        return self._finish(eos=ok, code=0 if ok or self.stop_requested else 1)

    def _start_receiver(self) -> Receiver:
        wires = [InputWire(i["name"], i["endpoint"], i["topic"], i.get("type_name"))
                 for i in self.spec["inputs"] if "topic" in i]
        receiver = Receiver(self.zctx, wires, self.queues, self.cond, self.wake_endpoint)
        self.wake_tx = self.zctx.socket(zmq.PAIR)
        self.wake_tx.connect(self.wake_endpoint)
        receiver.start()
        return receiver

    def _barrier(self) -> bool:
        """Wait for all expected subscribers, report ready, wait for start. False if stopped first."""
        expected = {out["topic"]: out["subscribers"] for out in self.spec["outputs"].values()}
        last_note = time.monotonic()
        while not self.stop_requested:
            self.publisher.poll_subscriptions(50)
            missing = {t: n for t, n in expected.items() if self.publisher.subscriptions[t] < n}
            if not missing:
                break
            if time.monotonic() - last_note > 5:
                last_note = time.monotonic()
                self.log.info("waiting for subscribers: %s",
                              ", ".join(f"{t} ({self.publisher.subscriptions[t]}/{n})" for t, n in missing.items()))
        if self.stop_requested or not self.control_endpoint:
            return not self.stop_requested
        ctl = self.zctx.socket(zmq.DEALER)
        ctl.setsockopt(zmq.IDENTITY, self.node_id.encode())
        ctl.setsockopt(zmq.LINGER, 0)
        ctl.connect(self.control_endpoint)
        ctl.send(b"ready")
        try:
            while not self.stop_requested:
                if ctl.poll(100) and ctl.recv() == b"start":
                    return True
            return False
        finally:
            ctl.close()

    def _add_builtin_timers(self) -> None:
        now = time.monotonic_ns()
        for i in self.spec["inputs"]:
            if "timer_period_ns" in i:
                self.timers.add(i["timer_period_ns"], f"on_input:{i['name']}",
                                self._tick_fn(i["name"], i["timer_period_ns"]), now - i["timer_period_ns"])
        self.timers.add(DIAGNOSTICS_PERIOD_NS, "_diagnostics", lambda missed: self._publish_diagnostics(), now)

    def _tick_fn(self, name: str, period_ns: int) -> Callable[[int], None]:
        def fire(missed: int) -> None:
            self.node.on_input(name, Tick(Header(self.now_ns(), "timer"), period_ns, missed))
        return fire

    def _loop(self) -> None:
        while not self.stop_requested:
            now = time.monotonic_ns()
            for timer, missed in self.timers.pop_due(now):
                if timer.name == "_diagnostics":
                    timer.fire(missed)
                else:
                    with self.timings.time(timer.name):
                        timer.fire(missed)
                if self.stop_requested:
                    return
            name, msg, closed = self._next_message()
            if name is not None:
                t0 = time.perf_counter()
                self.node.on_input(name, msg)
                self.timings.add(self.callback_names[name], time.perf_counter() - t0)
            for c in closed:
                self.node.on_input_closed(c)
            if self.queues and not self.open_inputs:
                return

    def _next_message(self):
        """Pop the oldest queued message across inputs, or wait until one arrives or a timer is due."""
        with self.cond:
            best = None
            for q in self.queues.values():
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
                if was_full:
                    self.wake_tx.send(b"")
                return best.name, msg, closed
            if not closed:
                deadline = self.timers.next_deadline()
                wait = 0.1 if deadline is None else max(0.0, (deadline - time.monotonic_ns()) / 1e9)
                if wait > 0:
                    self.cond.wait(min(wait, 0.1))
            return None, None, closed

    def _publish_diagnostics(self) -> None:
        with self.cond:
            inputs = tuple(InputCounters(q.name, self._input_topic(q.name), q.policy, q.queue_size,
                                         len(q.items), q.received, q.dropped, q.seq_gaps, q.invalid)
                           for q in self.queues.values())
        self.publisher.poll_subscriptions(0)
        status = NodeStatus(Header(self.now_ns(), self.node_id), self.node_id, self.state,
                            time.monotonic() - self.started_at, self.timings.report(), inputs,
                            tuple(f"{t}={n}" for t, n in self.publisher.published.items()))
        self.publisher.publish(f"{self.node_id}/diagnostics", status, lambda: self.stop_requested)

    def _input_topic(self, name: str) -> str:
        return next(i["topic"] for i in self.spec["inputs"] if i["name"] == name)

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
        self.zctx.term()
        return code


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    run_dir, node_id = Path(argv[0]), argv[1]
    graph = json.loads((run_dir / "graph.json").read_text())
    spec = graph["nodes"][node_id]
    logging.basicConfig(level=os.environ.get("PROBELESS_LOG", "INFO"), stream=sys.stderr,
                        format="%(levelname)s %(name)s: %(message)s")
    runtime = NodeRuntime(spec, graph.get("control"), f"inproc://wake-{spec['index']}")

    def on_signal(signum, frame):
        runtime.stop_requested = True

    faulthandler.register(signal.SIGUSR1, all_threads=True)  # `kill -USR1 PID` dumps every thread's stack
    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    return runtime.run()


if __name__ == "__main__":
    sys.exit(main())
