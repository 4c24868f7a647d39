"""The ``probeless topic {list,echo,hz,info}`` command line."""

from __future__ import annotations

import argparse
import os
import sys
from typing import Any

from probeless.errors import ProbelessError
from probeless.topics.catalog import list_topics
from probeless.topics.discovery import RunningGraph, select_graph
from probeless.topics.echo import echo
from probeless.topics.hz import hz
from probeless.topics.info import print_info, topic_info
from probeless.topics.signals import cli_signals


def _graph(ns: argparse.Namespace) -> RunningGraph:
    return select_graph(ns.graph_dir)


def _quiet_broken_pipe() -> int:
    """stdout went away (``| head``): stop quietly, like other Unix tools."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass
    return 0


def cmd_topic_list(ns: argparse.Namespace) -> int:
    try:
        with cli_signals():
            list_topics(_graph(ns), verbose=ns.verbose)
    except BrokenPipeError:
        return _quiet_broken_pipe()
    return 0


def cmd_topic_echo(ns: argparse.Namespace) -> int:
    count = 1 if ns.once else ns.count
    try:
        with cli_signals(suspend=True):
            echo(_graph(ns), ns.topic, count=count, arrays=not ns.no_arrays, queue_size=ns.queue_size)
    except BrokenPipeError:
        return _quiet_broken_pipe()
    return 0


def cmd_topic_hz(ns: argparse.Namespace) -> int:
    try:
        with cli_signals(suspend=True):
            hz(_graph(ns), ns.topic, window=ns.window, duration=ns.duration, queue_size=ns.queue_size)
    except BrokenPipeError:
        return _quiet_broken_pipe()
    return 0


def cmd_topic_info(ns: argparse.Namespace) -> int:
    try:
        with cli_signals():
            print_info(topic_info(_graph(ns), ns.topic, timeout=ns.timeout))
    except BrokenPipeError:
        return _quiet_broken_pipe()
    return 0


def _positive_int(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError("must be >= 1")
    return value


def _positive_float(text: str) -> float:
    value = float(text)
    if not value > 0:
        raise argparse.ArgumentTypeError("must be > 0")
    return value


def add_topic_parser(sub: Any) -> argparse.ArgumentParser:
    """Add ``topic {list,echo,hz,info}`` to an argparse subparsers object; each sets ``func``."""
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--graph-dir", metavar="RUN_DIR",
                        help="the run directory of the graph to inspect (default: the most recently "
                             "started running graph under $PROBELESS_RUN_DIR or $TMPDIR/probeless-<uid>)")
    p = sub.add_parser("topic", help="inspect the topics of a running graph: list, echo, hz, info",
                       description="Inspect the topics of a running graph. The tools never slow the graph "
                                   "down: they drop (and count) what they cannot keep up with.")
    tsub = p.add_subparsers(dest="topic_command", required=True, metavar="{list,echo,hz,info}")

    c = tsub.add_parser("list", parents=[common], help="topics with type, publisher and subscriber count")
    c.add_argument("-v", "--verbose", action="store_true", help="also show endpoints and each subscriber's input")
    c.set_defaults(func=cmd_topic_list)

    c = tsub.add_parser("echo", parents=[common], help="print the messages of a topic")
    c.add_argument("topic")
    c.add_argument("-n", "--count", type=_positive_int, help="stop after N messages")
    c.add_argument("--once", action="store_true", help="print one message and stop (same as -n 1)")
    c.add_argument("--no-arrays", action="store_true", help="show arrays as dtype and shape only, no statistics")
    c.add_argument("--queue-size", type=_positive_int, default=100,
                   help="messages buffered while printing (drop_oldest; default 100)")
    c.set_defaults(func=cmd_topic_echo)

    c = tsub.add_parser("hz", parents=[common], help="publishing rate of a topic, once per second")
    c.add_argument("topic")
    c.add_argument("--window", type=_positive_int, default=100, help="messages in the sliding window (default 100)")
    c.add_argument("--duration", type=_positive_float, help="stop after S seconds")
    c.add_argument("--queue-size", type=_positive_int, default=1000, help="tool queue (drop_oldest; default 1000)")
    c.set_defaults(func=cmd_topic_hz)

    c = tsub.add_parser("info", parents=[common], help="type, publisher, subscribers and their drop counters")
    c.add_argument("topic")
    c.add_argument("--timeout", type=_positive_float, default=2.5,
                   help="seconds to wait for the nodes' diagnostics (default 2.5)")
    c.set_defaults(func=cmd_topic_info)
    return p


def topic_main(argv: list[str] | None = None) -> int:
    """``probeless topic ...`` on its own (``python -m probeless.topics list``); the exit code."""
    parser = argparse.ArgumentParser(prog="probeless")
    add_topic_parser(parser.add_subparsers(dest="command", required=True))
    argv = sys.argv[1:] if argv is None else list(argv)
    if not argv or argv[0] != "topic":
        argv = ["topic", *argv]
    ns = parser.parse_args(argv)
    try:
        return ns.func(ns)
    except ProbelessError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 0
