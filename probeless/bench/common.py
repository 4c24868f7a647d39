"""Helpers shared by the benchmarks: logging to stderr, robust medians, JSON rounding, output, the CLI part
every benchmark shares (``--json``, ``--quick``) and ``python -m probeless.bench.NAME``."""

from __future__ import annotations

import argparse
import math
import statistics
import sys
from typing import Any, Callable

from probeless.jsonio import json_safe, print_json


def log(text: str) -> None:
    """Progress line on stderr (stdout is reserved for the table or the one JSON object)."""
    print(f"[bench] {text}", file=sys.stderr, flush=True)


def finite_median(vals: list[float]) -> float:
    """Median of the finite values, NaN when there are none."""
    vals = [v for v in vals if math.isfinite(v)]
    return float(statistics.median(vals)) if vals else float("nan")


def rounded(obj: Any, places: int = 4) -> Any:
    """Floats rounded to ``places`` (non-finite -> None), recursively through dicts and lists."""
    return json_safe(obj, places)


def emit(result: dict, json_out: bool, print_table: Callable[[dict], None]) -> None:
    """Print the benchmark's result: exactly one JSON object line with ``json_out`` (non-finite floats
    as null, :func:`probeless.jsonio.print_json`), else ``print_table(result)``."""
    if json_out:
        print_json(result)
    else:
        print_table(result)


def add_common_arguments(parser: argparse.ArgumentParser) -> None:
    """The options every benchmark takes."""
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--quick", action="store_true", help="short run (smoke test)")


def module_main(module_name: str, argv: list[str] | None = None) -> int:
    """``python -m probeless.bench.NAME [--json] [--quick] [own options]``: parse, run, its exit code."""
    from probeless.bench.cli import build_benchmark_parser

    parser, module = build_benchmark_parser(module_name, prog=f"python -m {module_name}")
    return run_benchmark(module, parser.parse_args(argv))


def run_benchmark(module, ns) -> int:
    """Run a benchmark module on parsed options: its ``run(ns)``, or by default ``main(json_out, quick)``."""
    run = getattr(module, "run", None)
    if run is not None:
        return run(ns)
    return module.main(json_out=ns.json, quick=ns.quick)


def add_own_arguments(module, parser) -> None:
    """The benchmark's own options (its ``add_arguments``, when it has any)."""
    add = getattr(module, "add_arguments", None)
    if add is not None:
        add(parser)
