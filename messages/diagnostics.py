"""Diagnostics: per-callback timings and per-input queue counters, published at 1 Hz by every node."""

from __future__ import annotations

from dataclasses import dataclass

from probeless.errors import SchemaError
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
    queued_bytes: int = 0        # payload bytes waiting now [bytes]
    publisher_restarts: int = 0  # times the publisher's seq started again (it restarted) [count]


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
    rss_bytes: int = 0                          # resident memory of the node's process now [bytes]
    warnings: tuple[str, ...] = ()              # health problems now, e.g. memory rising without bound


TRACKING_STATES = ("initializing", "ok", "lost", "invalid_input")


@message("diagnostics/TrackingState", version=1)
@dataclass(frozen=True)
class TrackingState(Message):
    """Camera tracking health, published by a SLAM node for every frame it processes.

    Counters are cumulative since the node started; every received frame ends up in exactly one
    of tracked, lost, invalid or skipped, or was dropped before the node saw it.
    """

    header: Header                  # stamp = the RGB-D frame this state is about; frame_id = the camera frame
    state: str                      # initializing (no frame mapped yet) | ok | lost | invalid_input
    reason: str = ""                # why the frame was not tracked, e.g. "fitness 0.12 < 0.3"; "" when ok
    frames_tracked: int = 0         # frames tracked and mapped, including the first [count]
    frames_lost: int = 0            # frames whose tracking failed (solver, fitness, NaN, motion) [count]
    frames_invalid: int = 0         # frames rejected before tracking (no depth, bad size) [count]
    frames_skipped: int = 0         # messages the node left unpaired (rgb/depth sync failures) [count]
    # rgb frames that never reached the node (header.seq gaps: queue policy, upstream) [count]
    frames_dropped: int = 0
    consecutive_failures: int = 0   # lost + invalid frames since the last tracked one [count]
    last_good_stamp_ns: int = 0     # stamp of the last tracked frame; 0 = none yet [ns]
    fitness: float = 0.0            # inlier fraction of the last tracking, nan when not tracked [0..1]
    step_ms: float = 0.0            # processing time of this frame (track + map) [ms]

    def validate(self) -> None:
        if self.state not in TRACKING_STATES:
            raise SchemaError(f"TrackingState.state: {self.state!r} is not one of {TRACKING_STATES}")
