"""Diagnostics: per-callback timings and per-input queue counters, published at 1 Hz by every node."""

from __future__ import annotations

from dataclasses import dataclass

from probeless.messages.base import Message, Struct, message
from probeless.messages.header import Header


@dataclass(frozen=True)
class StageTiming(Struct):
    """Timing of one callback or named stage over the last reporting window."""

    name: str           # "on_input:<input>", "timer:<name>", or a stage a node times itself
    count: int          # calls in the window [count]
    total_count: int    # calls since the node started [count]
    mean_ms: float      # mean duration in the window [ms]
    p50_ms: float       # median duration in the window [ms]
    p99_ms: float       # 99th percentile duration in the window [ms]
    max_ms: float       # longest duration in the window [ms]


@dataclass(frozen=True)
class InputCounters(Struct):
    """Queue and loss counters of one subscribed input, cumulative since start."""

    name: str           # input name in the node
    topic: str          # topic it is wired to, "<node_id>/<output>"
    policy: str         # latest | drop_oldest | block
    queue_size: int     # configured queue capacity [messages]
    queued: int         # messages waiting now [messages]
    received: int       # messages taken off the socket [count]
    dropped: int        # messages discarded by the queue policy here [count]
    seq_gaps: int       # messages missing upstream, from header.seq gaps [count]
    invalid: int        # frames that failed schema checks and were discarded [count]


@message("diagnostics/NodeStatus", version=1)
@dataclass(frozen=True)
class NodeStatus(Message):
    """Health of one node, published on "<node_id>/diagnostics" once a second."""

    header: Header
    node_id: str                                # the node's id in the graph
    state: str                                  # starting | running | stopping
    uptime_s: float                             # since the process started [s]
    timings: tuple[StageTiming, ...] = ()       # one entry per callback/stage
    inputs: tuple[InputCounters, ...] = ()      # one entry per subscribed input
    published: tuple[str, ...] = ()             # "<output>=<count>" messages published per output
