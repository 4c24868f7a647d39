"""Header and time messages shared by every family."""

from __future__ import annotations

from dataclasses import dataclass, replace

from probeless.messages.base import Message, Struct, message


@dataclass(frozen=True)
class Header(Struct):
    """Stamp, frame and sequence carried by every message (like ROS std_msgs/Header)."""

    stamp_ns: int       # capture time of the data [ns]; sensor clock, or recorded/simulated time on replay
    frame_id: str = ""  # coordinate frame the data is expressed in, e.g. "rgbd", "fisheye", "world"
    seq: int = 0        # per-topic sequence number; overwritten by the runtime on publish, gaps = drops


@message("core/Tick", version=1)
@dataclass(frozen=True)
class Tick(Message):
    """Event of a built-in timer input (``timer/hz/30``); header.stamp_ns is the scheduled time."""

    header: Header
    period_ns: int      # nominal timer period [ns]
    missed: int = 0     # ticks skipped because the node was busy past their deadline [count]


@message("core/Clock", version=1)
@dataclass(frozen=True)
class Clock(Message):
    """Simulated clock published on replay; header.stamp_ns is the current recorded time [ns]."""

    header: Header
    rate: float = 1.0   # playback speed factor (0 = as fast as possible) [ratio]
    epoch: int = 0      # incremented when time jumps backwards (replay loop) [count]


def shift_stamp(msg, offset_ns: int):
    """``msg`` (any message with a ``header``) with its header stamp moved by ``offset_ns``."""
    return replace(msg, header=replace(msg.header, stamp_ns=msg.header.stamp_ns + offset_ns))
