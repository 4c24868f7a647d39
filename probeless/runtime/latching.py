"""Latched topics (ROS 2 "transient local" durability): the last message goes to every late joiner.

A latched output keeps its last message in the publishing process (``transport.Publisher``). When a
subscriber connects later (a node restarted after a crash, a graph reading it as an ``external:``
input, ``probeless topic echo``), the publisher sees the subscription (ZeroMQ XPUB reports each one)
and sends that message again, marked: its topic frame is the topic plus :data:`LATCH_MARK`. The
subscription's prefix match delivers it, but XPUB cannot address one peer, so every subscriber of
the topic gets it; a receiver (``receiver.Receiver``) keeps it only for an input that has had no
message of that topic yet, and drops it silently everywhere else. It works for any publisher,
``bag_player`` replays included (a latched recorded topic is cached by ``publish_raw`` as it plays),
and no node code changes.

Which outputs are latched: the names in :data:`DEFAULT_LATCHED` (matched against the output's last path
segment, so ``rgbd/camera_info`` and a replay's ``rig/floorplan`` are latched too), changed per node by
the graph's ``latched:`` key (a list of output names or globs to latch as well, or a mapping
``output: true|false``), validated by ``probeless check``.
"""

from __future__ import annotations

import fnmatch
from typing import Any

LATCH_MARK = b"\0latched"   # appended to the topic frame of a re-sent latched message
# floorplan (the room), fisheye_from_rgbd (the rig's extrinsics), camera_info (intrinsics): published once or
# seldom, and without them a late joiner can never start
DEFAULT_LATCHED = ("floorplan", "fisheye_from_rgbd", "camera_info")


def default_latched(output: str) -> bool:
    """True for an output whose last path segment is one of :data:`DEFAULT_LATCHED`."""
    return output.rsplit("/", 1)[-1] in DEFAULT_LATCHED


def is_latched(output: str, overrides: dict[str, bool] | None = None) -> bool:
    """Whether ``output`` is latched, given a node's ``latched:`` overrides (output name or glob -> bool).

    An exact name wins over a glob; among globs the longest pattern wins; without a match, the default.
    """
    overrides = overrides or {}
    if output in overrides:
        return bool(overrides[output])
    globs = sorted((p for p in overrides if any(c in p for c in "*?[") and fnmatch.fnmatchcase(output, p)),
                   key=len, reverse=True)
    return bool(overrides[globs[0]]) if globs else default_latched(output)


def parse_latched(value: Any) -> tuple[dict[str, bool], str | None]:
    """A graph's ``latched:`` value as {output or glob: bool}, or ({}, the problem)."""
    if isinstance(value, list):
        if all(isinstance(v, str) and v for v in value):
            return {v: True for v in value}, None
    elif isinstance(value, dict):
        if all(isinstance(k, str) and k and isinstance(v, bool) for k, v in value.items()):
            return {k: v for k, v in value.items()}, None
    return {}, ("'latched' must be a list of output names (or globs) to latch, or a mapping output: true|false "
                f"(latched by default: {', '.join(DEFAULT_LATCHED)}), got {value!r}")
