"""Node runtime: the process loop, sockets, queues, timers and diagnostics that nodes never touch."""

from probeless.runtime.node import Context, Node, NoParams
from probeless.runtime.params import param

__all__ = ["Context", "Node", "NoParams", "param"]
