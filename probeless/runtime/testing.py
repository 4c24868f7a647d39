"""Run a node without a bus: feed inputs, collect what it publishes. For unit tests of nodes."""

from __future__ import annotations

import logging
import time
from typing import Any, Callable, Iterable

from probeless.messages.base import Message
from probeless.runtime.node import Node, output_type
from probeless.runtime.params import load_params
from probeless.runtime.stats import Timings


class RecordingContext:
    """A :class:`~probeless.runtime.node.Context` that records publications and fires timers by hand."""

    def __init__(self, node_id: str = "node", node_cls: type[Node] | None = None, clock_ns: int = 0):
        self.node_id = node_id
        self.log = logging.getLogger(node_id)
        self.node_cls = node_cls
        self.published: list[tuple[str, Message]] = []
        self.timers: list[tuple[float, Callable[[], None]]] = []
        self.clock_ns = clock_ns
        self.stopped = False
        self.timings = Timings()
        self.plan: dict = {}
        self.simulated_time = False
        self.raw_published: list[tuple[str, list]] = []
        self.publish_times: list[tuple[str, float]] = []  # (output, time.monotonic()) of every publish

    def publish(self, output: str, msg: Message) -> None:
        if self.node_cls is not None and not output_type(self.node_cls, output)[0]:
            raise ValueError(f"{self.node_cls.__name__} has no output {output!r}")
        if not isinstance(msg, Message):
            raise TypeError(f"publish({output!r}): {type(msg).__name__} is not a Message")
        self.published.append((output, msg))
        self.publish_times.append((output, time.monotonic()))

    def publish_raw(self, output: str, frames: list) -> None:
        self.raw_published.append((output, list(frames)))

    def wait_quiescent(self) -> bool:
        return True

    def create_timer(self, period_s: float, callback: Callable[[], None], name: str | None = None):
        self.timers.append((period_s, callback))
        return self

    def cancel(self) -> None:
        pass

    def now_ns(self) -> int:
        return self.clock_ns

    def stop(self) -> None:
        self.stopped = True

    def timed(self, stage: str):
        return self.timings.time(stage)

    def outputs(self, name: str) -> list[Message]:
        """Messages published on output ``name``, in order."""
        return [m for o, m in self.published if o == name]

    def times(self, name: str | None = None) -> list[float]:
        """``time.monotonic()`` of each publish on output ``name`` (all outputs when None)."""
        return [t for o, t in self.publish_times if name is None or o == name]


def run_node(node_cls: type[Node], inputs: Iterable[tuple[str, Message]], params: dict[str, Any] | None = None,
             node_id: str = "node") -> RecordingContext:
    """setup, feed ``(input, message)`` pairs (stopping early if the node stops), close; return the context."""
    ctx = RecordingContext(node_id, node_cls)
    node = node_cls(ctx, load_params(node_cls.Params, params or {}, node_id=node_id))
    node.setup()
    try:
        for name, msg in inputs:
            if ctx.stopped:
                break
            node.on_input(name, msg)
    finally:
        node.close()
    return ctx
