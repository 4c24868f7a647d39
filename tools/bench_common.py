"""Helpers shared by the ``probeless bench`` scripts: logging to stderr, robust medians, JSON rounding."""

from __future__ import annotations

import math
import statistics
import sys
from typing import Any


def log(text: str) -> None:
    """Progress line on stderr (stdout is reserved for the table or the one JSON object)."""
    print(f"[bench] {text}", file=sys.stderr, flush=True)


def finite_median(vals: list[float]) -> float:
    """Median of the finite values, NaN when there are none."""
    vals = [v for v in vals if math.isfinite(v)]
    return float(statistics.median(vals)) if vals else float("nan")


def rounded(obj: Any, places: int = 4) -> Any:
    """Floats rounded to ``places`` (non-finite -> None), recursively through dicts and lists."""
    if isinstance(obj, float):
        return round(obj, places) if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: rounded(v, places) for k, v in obj.items()}
    if isinstance(obj, list):
        return [rounded(v, places) for v in obj]
    return obj


def emit(result: dict, json_out: bool, print_table) -> None:
    """Print the benchmark's result: exactly one JSON object line with ``json_out``, else ``print_table(result)``."""
    if json_out:
        import json

        sys.stdout.write(json.dumps(result) + "\n")
        sys.stdout.flush()
    else:
        print_table(result)


def run_cli(main, description: str) -> None:
    """``python -m probeless.tools.bench_X [--json] [--quick]``: parse, run ``main``, exit with its code."""
    import argparse

    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--quick", action="store_true", help="short run (smoke test)")
    ns = ap.parse_args()
    sys.exit(main(json_out=ns.json, quick=ns.quick))
