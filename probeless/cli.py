"""The ``probeless`` command: launch, check, graph, bench."""

from __future__ import annotations

import argparse
import sys
from typing import Any

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
    print(f"{ns.graph}: OK ({len(graph.nodes)} nodes)")
    return 0


def cmd_launch(ns: argparse.Namespace) -> int:
    from probeless.launch.launcher import Launcher, load_checked

    graph = load_checked(ns.graph, parse_overrides(ns.args))
    launcher = Launcher(graph, only=ns.only, duration=ns.duration, ready_timeout=ns.ready_timeout)
    return launcher.run()


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


def cmd_bench(ns: argparse.Namespace) -> int:
    if ns.what == "bus":
        from probeless.tools.bench_bus import main as bench_bus

        return bench_bus(json_out=ns.json, quick=ns.quick)
    raise ProbelessError(f"unknown benchmark {ns.what!r}")


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
    c.add_argument("--duration", type=float, help="stop the graph cleanly after S seconds")
    c.add_argument("--only", metavar="HOST", help="start only the nodes of this host (name or ADDRESS:PORT)")
    c.add_argument("--ready-timeout", type=float, default=60.0, help="seconds to wait for all nodes to be ready")
    c.set_defaults(func=cmd_launch)

    c = sub.add_parser("graph", help="draw a launch graph: nodes, topics, message types")
    c.add_argument("graph")
    c.add_argument("args", nargs="*", metavar="name:=value")
    c.add_argument("--out", help="output file (.png, .svg, .dot, .mmd); default: print text")
    c.add_argument("--format", choices=("png", "svg", "dot", "mermaid"), help="default: from --out suffix")
    c.set_defaults(func=cmd_graph)

    c = sub.add_parser("bench", help="run a benchmark and print its figures")
    c.add_argument("what", choices=("bus",))
    c.add_argument("--json", action="store_true", help="print one JSON object")
    c.add_argument("--quick", action="store_true", help="fewer messages (for smoke tests)")
    c.set_defaults(func=cmd_bench)
    return p


def main(argv: list[str] | None = None) -> int:
    ns = build_parser().parse_args(argv)
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
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
