"""The node interface. A node is a small class; the runtime owns the loop and never lets it touch ZeroMQ.

::

    class Blur(Node):
        INPUTS = {"image": Image}
        OUTPUTS = {"image": Image}

        @dataclass(frozen=True)
        class Params:
            ksize: int = param(5, min=1)

        def on_input(self, name, msg):
            self.ctx.publish("image", replace(msg, data=blur(msg.data, self.params.ksize)))

``INPUTS`` maps input names to message classes (``None`` = any type; key ``"*"`` = any name).
``OUTPUTS`` maps output names to message classes; a key ending in ``/*`` declares a family
(``"envmap/*"`` allows ``envmap/sphere``), and ``"*"`` allows any name (a bag player).
``RAW_INPUTS = True`` delivers :class:`~probeless.runtime.receiver.RawMessage` (the frames as
received, envelope peeked, nothing decoded): for recorders. Every node also has the implicit output
``diagnostics`` (NodeStatus at 1 Hz).
"""

from __future__ import annotations

import fnmatch
import logging
from dataclasses import dataclass
from typing import Any, Callable, ClassVar, Protocol

from probeless.messages.base import Message


@dataclass(frozen=True)
class NoParams:
    """Params of a node that takes none."""


class TimerHandle(Protocol):
    def cancel(self) -> None: ...


class Context(Protocol):
    """What the runtime gives a node: publishing, timers, time, logging and stopping."""

    node_id: str
    log: logging.Logger

    def publish(self, output: str, msg: Message) -> None:
        """Publish on one of the node's outputs; the runtime sets header.seq."""

    def create_timer(self, period_s: float, callback: Callable[[], None], name: str | None = None) -> TimerHandle:
        """Call ``callback`` every ``period_s`` seconds on the node's thread (after the graph starts)."""

    def now_ns(self) -> int:
        """Current time [ns]: wall clock live, recorded time on replay."""

    simulated_time: bool  # True while following a replay's recorded clock

    def stop(self) -> None:
        """Finish after the current callback: close, end-of-stream on outputs, exit 0."""

    def timed(self, stage: str) -> Any:
        """Context manager timing a named stage for diagnostics."""

    def publish_raw(self, output: str, frames: list) -> None:
        """Publish recorded wire frames unchanged (for players: bit-exact replay)."""

    def wait_quiescent(self) -> bool:
        """Block until every other node is idle with nothing in flight (for lockstep players)."""

    plan: dict  # the resolved launch plan of the graph (recorders store it)


class Node:
    """Base class of every node. Override what you need; all hooks run on the node's one thread."""

    INPUTS: ClassVar[dict[str, type[Message] | None]] = {}
    OUTPUTS: ClassVar[dict[str, type[Message] | None]] = {}
    RAW_INPUTS: ClassVar[bool] = False
    Params: ClassVar[type] = NoParams

    def __init__(self, ctx: Context, params: Any):
        self.ctx = ctx
        self.params = params

    def setup(self) -> None:
        """Acquire resources (GL contexts, files, devices). Runs before the graph starts."""

    def on_input(self, name: str, msg: Message) -> None:
        """Handle one message from input ``name``."""

    def on_param(self, key: str, value: Any) -> None:
        """A ``dynamic`` param was changed at run time (``probeless param set``); ``self.params`` already holds
        the new value. Raise ProbelessError or ValueError to refuse it (the old params are kept)."""

    def on_input_closed(self, name: str) -> None:
        """Input ``name`` reached end of stream. The node stops when all its inputs have."""

    def close(self) -> None:
        """Release resources. Always runs, on normal end, on signals and after errors in callbacks."""


def input_type(cls: type[Node], name: str) -> tuple[bool, type[Message] | None]:
    """(declared, type) of input ``name`` of a node class (type None = any)."""
    if name in cls.INPUTS:
        return True, cls.INPUTS[name]
    if "*" in cls.INPUTS:
        return True, cls.INPUTS["*"]
    return False, None


def output_type(cls: type[Node], name: str) -> tuple[bool, type[Message] | None]:
    """(declared, type) of output ``name`` of a node class, matching ``family/*`` declarations."""
    from probeless.messages.diagnostics import NodeStatus

    if name == "diagnostics":
        return True, NodeStatus
    if name in cls.OUTPUTS:
        return True, cls.OUTPUTS[name]
    if "*" in cls.OUTPUTS:
        return True, cls.OUTPUTS["*"]
    for pattern, typ in cls.OUTPUTS.items():
        if pattern.endswith("/*") and fnmatch.fnmatchcase(name, pattern) and "/" not in name[len(pattern) - 1:]:
            return True, typ
    return False, None
