"""The ``probeless bench`` command: one sub-command per entry of :data:`probeless.bench.BENCHMARKS`.

A benchmark's module is imported only when that benchmark is parsed (run or ``--help``), so building
the ``probeless`` parser stays cheap.
"""

from __future__ import annotations

import argparse
import importlib
from types import ModuleType

from probeless.bench import BENCHMARKS
from probeless.bench.common import add_common_arguments, add_own_arguments, run_benchmark


class _BenchmarkParser(argparse.ArgumentParser):
    """A benchmark's parser; its module's ``add_arguments`` runs the first time it parses or prints help."""

    def __init__(self, *args, bench_module: str | None = None, **kwargs):
        super().__init__(*args, **kwargs)
        self._bench_module = bench_module

    def _load(self) -> None:
        if self._bench_module is not None:
            module, self._bench_module = importlib.import_module(self._bench_module), None
            add_common_arguments(self)
            add_own_arguments(module, self)

    def parse_known_args(self, args=None, namespace=None):
        self._load()
        return super().parse_known_args(args, namespace)

    def format_help(self) -> str:
        self._load()
        return super().format_help()

    def format_usage(self) -> str:
        self._load()
        return super().format_usage()


def _module_of(name: str) -> ModuleType:
    return importlib.import_module(BENCHMARKS[name][0])


def build_benchmark_parser(module_name: str, prog: str | None = None) -> tuple[argparse.ArgumentParser, ModuleType]:
    """(parser with the shared and the benchmark's own options, the module) of a benchmark module."""
    module = importlib.import_module(module_name)
    helps = {m: h for m, h in BENCHMARKS.values()}
    parser = argparse.ArgumentParser(prog=prog, description=helps.get(module_name, module.__doc__))
    add_common_arguments(parser)
    add_own_arguments(module, parser)
    return parser, module


def list_benchmarks() -> str:
    """The benchmarks and their one-line helps, as ``probeless bench`` prints them."""
    width = max(map(len, BENCHMARKS))
    lines = ["benchmarks (probeless bench NAME [--json] [--quick]; NAME --help for its own options):"]
    lines += [f"  {name:<{width}}  {help_}" for name, (_, help_) in BENCHMARKS.items()]
    return "\n".join(lines)


def cmd_bench(ns: argparse.Namespace) -> int:
    """Run the benchmark ``ns.what``; without one, list them."""
    if ns.what is None:
        print(list_benchmarks())
        return 0
    return run_benchmark(_module_of(ns.what), ns)


def add_bench_parser(sub) -> argparse.ArgumentParser:
    """The ``bench`` command and its per-benchmark sub-commands on the ``probeless`` sub-parsers ``sub``."""
    p = sub.add_parser("bench", help="run a benchmark and print its figures",
                       description="Run a benchmark and print its figures (a table, or one JSON object with "
                                   "--json). Without NAME: list the benchmarks.")
    benches = p.add_subparsers(dest="what", metavar="NAME", parser_class=_BenchmarkParser)
    for name, (module, help_) in BENCHMARKS.items():
        benches.add_parser(name, help=help_, description=help_, bench_module=module)
    p.set_defaults(func=cmd_bench, what=None)
    return p
