"""``probeless topic echo``: print the messages of a topic."""

from __future__ import annotations

import sys
from typing import IO

from probeless.runtime.security import tool_curve
from probeless.topics.catalog import _import_publisher, find_topic
from probeless.topics.discovery import RunningGraph, _launcher_gone
from probeless.topics.formatting import format_message
from probeless.topics.reader import TopicReader, wait_for_start
from probeless.topics.signals import _suspend_point


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
    with TopicReader([(topic.name, topic.endpoint)], policy=policy, queue_size=queue_size,
                     curve=tool_curve(graph.plan)) as reader:
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
