"""The ``probeless`` command: launch, check, graph, bench."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from probeless.bag.run import add_record_options, add_replay_options
from probeless.errors import GraphError, GraphErrors, ProbelessError


def parse_overrides(items: list[str]) -> dict[str, Any]:
    """``name:=value`` pairs; values are parsed as YAML scalars (numbers, booleans, strings)."""
    from probeless.launch.yamlload import load_yaml_text

    out = {}
    for item in items:
        name, sep, value = item.partition(":=")
        if not sep or not name:
            raise GraphError(f"argument {item!r} is not of the form name:=value")
        out[name] = load_yaml_text(value, f"argument {name}") if value else ""
    return out


def cmd_check(ns: argparse.Namespace) -> int:
    from probeless.launch.launcher import load_checked

    graph = load_checked(ns.graph, parse_overrides(ns.args))
    for warning in graph.warnings:
        print(f"warning: {warning.format()}", file=sys.stderr)
    print(f"{ns.graph}: OK ({len(graph.nodes)} nodes{f', {len(graph.warnings)} warning(s)' if graph.warnings else ''})")
    return 0


def cmd_launch(ns: argparse.Namespace) -> int:
    from probeless.bag.run import prepare_graph
    from probeless.launch.launcher import Launcher

    if ns.show_args:
        from probeless.launch.args import describe_args

        print(describe_args(ns.graph))
        return 0
    graph, clock = prepare_graph(ns, parse_overrides(ns.args))
    for warning in graph.warnings:
        print(f"warning: {warning.format()}", file=sys.stderr)
    launcher = Launcher(graph, only=ns.only, duration=ns.duration, ready_timeout=ns.ready_timeout, clock_node=clock)
    return launcher.run()


def cmd_bag(ns: argparse.Namespace) -> int:
    from probeless.bag import run

    if ns.bag_command == "record":
        return run.cmd_record(ns, parse_overrides(ns.args))
    if ns.bag_command == "play":
        return run.cmd_play(ns)
    from probeless.bag import cli as bag_cli

    return bag_cli.cmd_info(ns) if ns.bag_command == "info" else bag_cli.cmd_export(ns)


def cmd_test(ns: argparse.Namespace) -> int:
    from probeless.bag.run import cmd_test as run_test

    return run_test(ns, parse_overrides(ns.args))



def cmd_graph(ns: argparse.Namespace) -> int:
    from probeless.launch.draw import draw
    from probeless.launch.launcher import load_checked

    graph = load_checked(ns.graph, parse_overrides(ns.args))
    text = draw(graph, ns.format, ns.out)
    if ns.out is None:
        print(text)
    else:
        print(f"wrote {ns.out}")
    return 0


def _add_bag_parsers(sub) -> None:
    from probeless.bag.cli import add_export_parser, add_import_parser, add_info_parser

    bag = sub.add_parser("bag", help="record, replay and inspect MCAP recordings")
    bags = bag.add_subparsers(dest="bag_command", required=True)
    c = bags.add_parser("record", help="record topics of a running graph, or launch a graph and record it")
    c.add_argument("topics", nargs="*", metavar="TOPIC", help="topics to record (default: all)")
    c.add_argument("-o", "--output", required=True, metavar="OUT.mcap")
    c.add_argument("--all", action="store_true", help="record every topic (the default without TOPICs)")
    c.add_argument("--graph", "--graph-dir", dest="graph", metavar="RUN_ID|G.yaml",
                   help="a running graph to record (its run id from `probeless runs`, or run directory), or a "
                        "graph file to launch and record; default: the only running graph (with several, it asks)")
    c.add_argument("--duration", type=float, help="stop after S seconds")
    c.add_argument("--arg", dest="args", action="append", default=[], metavar="name:=value",
                   help="graph argument (with --graph)")
    add_record_options(c)
    c.set_defaults(func=cmd_bag)
    c = bags.add_parser("play", help="publish a recording with its original timing")
    c.add_argument("bag")
    c.add_argument("--topics", nargs="+", metavar="TOPIC", help="recorded topics to play (default: all)")
    add_replay_options(c)
    c.set_defaults(func=cmd_bag)
    add_info_parser(bags).set_defaults(func=cmd_bag)
    add_export_parser(bags, {"rerun": _export_rerun}).set_defaults(func=cmd_bag)
    add_import_parser(bags)  # `bag import`: ROS bags (probeless[ros]); sets its own func


def _export_rerun(*args, **kwargs):
    """``bag export --format rerun``: a recording as a Rerun .rrd (probeless.viz sits above probeless.bag)."""
    from probeless.viz.rerun_export import export_rerun

    return export_rerun(*args, **kwargs)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="probeless", description=__doc__)
    sub = p.add_subparsers(dest="command", required=True)

    c = sub.add_parser("check", help="validate a launch graph without starting anything")
    c.add_argument("graph")
    c.add_argument("args", nargs="*", metavar="name:=value")
    c.set_defaults(func=cmd_check)

    c = sub.add_parser("launch", help="run a launch graph, one process per node")
    c.add_argument("graph")
    c.add_argument("args", nargs="*", metavar="name:=value")
    c.add_argument("--duration", type=float, help="stop the graph cleanly S seconds after it started (all nodes ready)")
    c.add_argument("--only", metavar="HOST", help="start only the nodes of this host (name or ADDRESS:PORT)")
    c.add_argument("--ready-timeout", type=float, default=60.0, help="seconds to wait for all nodes to be ready")
    c.add_argument("--show-args", action="store_true", help="list the graph's arguments (default, range, doc); "
                                                           "start nothing")
    g = c.add_argument_group("record and replay")
    g.add_argument("--record", metavar="OUT.mcap", help="record every topic (or --record-topics) to an MCAP file")
    g.add_argument("--record-topics", dest="topics", nargs="+", metavar="TOPIC", help="topics to record")
    g.add_argument("--replay", metavar="IN.mcap", help="recorded topics stand in for the nodes that produced them")
    g.add_argument("--replace", metavar="ID1,ID2", help="nodes to replace by the replay (default: every node "
                                                        "whose outputs are all in the recording, except nodes "
                                                        "whose type differs from the recorded one and what they feed)")
    g.add_argument("--keep", metavar="ID1,ID2", help="nodes that run live although the recording has their outputs "
                                                     "(and so do the nodes they feed)")
    add_replay_options(g, prefix="replay-")
    add_record_options(g)
    c.set_defaults(func=cmd_launch)

    _add_bag_parsers(sub)

    from probeless.runtime.keys import add_keys_parser

    add_keys_parser(sub)

    c = sub.add_parser("test", help="lockstep replay through a graph; compare its outputs with a golden recording")
    c.add_argument("graph")
    c.add_argument("args", nargs="*", metavar="name:=value")
    c.add_argument("--bag", required=True, metavar="IN.mcap", help="recorded inputs")
    c.add_argument("--golden", required=True, metavar="OUT.mcap", help="expected outputs (written if missing)")
    c.add_argument("--replace", metavar="ID1,ID2", help="nodes the recording stands in for (default: every node "
                                                        "whose outputs are all in the recording)")
    c.add_argument("--keep", metavar="ID1,ID2", help="nodes that run live although the recording has their outputs")
    c.add_argument("--tolerance", type=float, default=1e-6, help="absolute tolerance for float values")
    c.add_argument("--rtol", type=float, default=0.0, help="relative tolerance for float values")
    c.add_argument("--update-golden", action="store_true", help="overwrite the golden recording")
    c.set_defaults(func=cmd_test)

    from probeless.launch.node_types import add_nodes_parser

    add_nodes_parser(sub)

    from probeless.topics import add_topic_parser
    from probeless.topics.cli import add_node_parsers

    add_topic_parser(sub)
    add_node_parsers(sub)  # node list|info, param get|set, runs

    from probeless.scene.cli import add_scene_parser

    add_scene_parser(sub)

    from probeless.cameras.calibrate_cli import add_calibrate_parser

    add_calibrate_parser(sub)

    from probeless.datasets.cli import add_dataset_parser

    add_dataset_parser(sub)

    from probeless.eval import add_eval_parser, add_old_spellings
    from probeless.tracking.slam_cli import add_slam_parser

    add_eval_parser(sub)
    add_slam_parser(sub)

    from probeless.sweep.cli import add_sweep_parser

    add_sweep_parser(sub)

    from probeless.hdr.cli import add_hdr_parser

    add_hdr_parser(sub)

    from probeless.pbgi.cli import add_pbgi_parser

    add_pbgi_parser(sub)

    from probeless.coarse.cli import add_coarse_parser

    # old spellings of evaluations: `coarse eval` (beside `coarse preview`), `pano glossy|diffuse|itmo`
    add_old_spellings(sub, {"coarse": add_coarse_parser(sub)})

    c = sub.add_parser("graph", help="draw a launch graph: nodes, topics, message types")
    c.add_argument("graph")
    c.add_argument("args", nargs="*", metavar="name:=value")
    c.add_argument("--out", help="output file (.png, .svg, .dot, .mmd); default: print text")
    c.add_argument("--format", choices=("png", "svg", "dot", "mermaid"), help="default: from --out suffix")
    c.set_defaults(func=cmd_graph)

    from probeless.bench.cli import add_bench_parser

    add_bench_parser(sub)
    return p


def split_overrides(argv: list[str]) -> tuple[list[str], list[str]]:
    """Separate graph arguments ``name:=value`` (allowed anywhere on the line) from the rest.

    The value of an option that itself takes ``from:=to`` (``--remap``, ``--arg``, ``--graph-arg``) stays put.
    """
    rest, overrides = [], []
    for i, token in enumerate(argv):
        takes_pair = i > 0 and argv[i - 1] in ("--remap", "--arg", "--graph-arg")
        if ":=" in token and not token.startswith("-") and not takes_pair:
            overrides.append(token)
        else:
            rest.append(token)
    return rest, overrides


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    rest, overrides = split_overrides(argv)
    ns = build_parser().parse_args(rest)
    if hasattr(ns, "args"):
        ns.args = list(ns.args or []) + overrides
    elif overrides:
        print(f"error: graph arguments {overrides} are not accepted by this command", file=sys.stderr)
        return 2
    try:
        return ns.func(ns)
    except GraphErrors as exc:
        for e in exc.errors:
            print(f"error: {e.format()}", file=sys.stderr)
        print(f"{len(exc.errors)} error(s)", file=sys.stderr)
        return 2
    except ProbelessError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except ValueError as exc:  # malformed option values (e.g. --remap without :=)
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
