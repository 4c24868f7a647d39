"""The ``probeless topic {list,echo,hz,info,pub}``, ``node {list,info}``, ``param {get,set}`` and ``runs`` command
lines."""

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
    return select_graph(getattr(ns, "graph", None))


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
    common = graph_option_parser()
    p = sub.add_parser("topic", help="inspect the topics of a running graph: list, echo, hz, info, pub",
                       description="Inspect the topics of a running graph. The tools never slow the graph "
                                   "down: they drop (and count) what they cannot keep up with.")
    tsub = p.add_subparsers(dest="topic_command", required=True, metavar="{list,echo,hz,info,pub}")

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

    c = tsub.add_parser("pub", parents=[common], help="publish messages on a topic of the running graph")
    c.add_argument("topic")
    c.add_argument("type", metavar="TYPE", help="message type, e.g. core/Tick (must match the topic's)")
    c.add_argument("yaml", metavar="YAML", help="the fields as YAML, e.g. '{period_ns: 1000, missed: 0}'")
    c.add_argument("--rate", type=_positive_float, metavar="HZ", help="publish repeatedly at HZ (until Ctrl-C "
                                                                      "or -n); default: once")
    c.add_argument("-n", "--count", type=_positive_int, help="stop after N messages")
    c.set_defaults(func=cmd_topic_pub)
    return p


def yaml_value(text: str, what: str) -> Any:
    """A command-line YAML value (``0.5``, ``[1, 2]``, ``{a: 1}``); ProbelessError naming ``what`` when invalid."""
    import yaml

    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ProbelessError(f"{what} is not valid YAML: {str(exc).splitlines()[0]}") from None


def graph_option_parser() -> argparse.ArgumentParser:
    """The ``--graph RUN_ID|GRAPH_FILE`` option of every tool that attaches to a running graph."""
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--graph", "--graph-dir", dest="graph", metavar="RUN_ID|GRAPH_FILE",
                        help="the running graph: its run id (`probeless runs`), run directory or graph file "
                             "(default: the only running graph; with several, the tool asks)")
    return common


def cmd_topic_pub(ns: argparse.Namespace) -> int:
    from probeless.topics.pub import publish

    doc = yaml_value(ns.yaml, "the message YAML")
    with cli_signals():
        publish(_graph(ns), ns.topic, ns.type, doc, rate_hz=ns.rate, count=ns.count)
    return 0


def cmd_node(ns: argparse.Namespace) -> int:
    from probeless.topics import nodes

    graph = _graph(ns)
    if ns.node_command == "list":
        nodes.list_nodes(graph)
    else:
        nodes.print_node_info(nodes.node_info(graph, ns.node))
    return 0


def cmd_param(ns: argparse.Namespace) -> int:
    from probeless.topics import nodes

    graph = _graph(ns)
    if ns.param_command == "get":
        got = nodes.param_get(graph, ns.node, ns.key)
        for k, v in got["params"].items():
            print(f"{k}: {v!r}{'  (dynamic)' if k in got['dynamic'] and ns.key is None else ''}")
        return 0
    value = nodes.param_set(graph, ns.node, ns.key, yaml_value(ns.value, f"the value of {ns.key}"))
    print(f"{ns.node}: {ns.key} = {value!r}")
    return 0


def cmd_runs(ns: argparse.Namespace) -> int:
    from probeless.topics.nodes import print_runs

    print_runs()
    return 0


def add_node_parsers(sub: Any) -> None:
    """Add ``node {list,info}``, ``param {get,set}`` and ``runs`` (see probeless.topics.nodes)."""
    common = graph_option_parser()
    p = sub.add_parser("node", help="the nodes of a running graph: pid, state, rates, queues, params")
    nsub = p.add_subparsers(dest="node_command", required=True)
    c = nsub.add_parser("list", parents=[common], help="one line per node: pid, state, output rate, queues")
    c.set_defaults(func=cmd_node)
    c = nsub.add_parser("info", parents=[common], help="everything one node reports: inputs, outputs, params")
    c.add_argument("node", metavar="NODE")
    c.set_defaults(func=cmd_node)

    p = sub.add_parser("param", help="read and set the params of a running node (set: params declared dynamic)")
    psub = p.add_subparsers(dest="param_command", required=True)
    c = psub.add_parser("get", parents=[common], help="the current value of a param (all params without KEY)")
    c.add_argument("node", metavar="NODE")
    c.add_argument("key", metavar="KEY", nargs="?")
    c.set_defaults(func=cmd_param)
    c = psub.add_parser("set", parents=[common], help="set a dynamic param, checked like `probeless check`")
    c.add_argument("node", metavar="NODE")
    c.add_argument("key", metavar="KEY")
    c.add_argument("value", metavar="VALUE", help="a YAML value: 0.5, true, [1, 2], text")
    c.set_defaults(func=cmd_param)

    c = sub.add_parser("runs", help="the running graphs and their run ids (what --graph takes)")
    c.set_defaults(func=cmd_runs)


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
