"""The results table of a sweep: one row per run, axes as columns, then the collected keys.

``results.csv`` always (the csv module); ``results.parquet`` as well when pyarrow is importable.
:func:`collect` picks the collected keys out of a run's JSON.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Any

FIXED = ("run_id", "status")
TRAILING = ("wall_s", "error", "key")


def _lookup(obj: Any, parts: list[str]) -> list[Any]:
    if not parts:
        return [obj]
    head, rest = parts[0], parts[1:]
    if isinstance(obj, dict):
        if head == "*":
            return [v for k in obj for v in _lookup(obj[k], rest)]
        return _lookup(obj[head], rest) if head in obj else []
    if isinstance(obj, list):
        if head == "*":
            return [v for item in obj for v in _lookup(item, rest)]
        if head.lstrip("-").isdigit() and -len(obj) <= int(head) < len(obj):
            return _lookup(obj[int(head)], rest)
    return []


def collect_value(result: Any, path: str) -> Any:
    """The value at dotted ``path`` in ``result``; ``*`` matches every key (or list item) at its level and
    the matches' numbers are averaged (nulls skipped); None when nothing matches."""
    found = _lookup(result, path.split("."))
    if "*" not in path.split("."):
        return found[0] if found else None
    numbers = [float(v) for v in found if isinstance(v, (int, float)) and not isinstance(v, bool)]
    numbers = [v for v in numbers if math.isfinite(v)]
    return sum(numbers) / len(numbers) if numbers else None


def collect(result: Any, paths: dict[str, str]) -> dict[str, Any]:
    """Column -> value of every collected key."""
    return {name: collect_value(result, path) for name, path in paths.items()}


def columns(axes: list[str], keys: list[str]) -> list[str]:
    """The table's columns, in order."""
    return [*FIXED, *axes, *keys, *TRAILING]


def row(record: dict[str, Any], axes: list[str], keys: list[str]) -> dict[str, Any]:
    """A run record (run.json) as a table row."""
    out = {"run_id": record["run_id"], "status": record["status"]}
    out.update({a: record["labels"].get(a) for a in axes})
    out.update({k: (record.get("collected") or {}).get(k) for k in keys})
    out.update({"wall_s": record.get("wall_s"), "error": record.get("error"), "key": record.get("key")})
    return out


def _cell(v: Any) -> Any:
    return json.dumps(v) if isinstance(v, (list, dict)) else v


def write_table(rows: list[dict[str, Any]], cols: list[str], out_dir: Path) -> list[Path]:
    """Write results.csv (and results.parquet with pyarrow); returns the files written."""
    out_dir = Path(out_dir)
    path = out_dir / "results.csv"
    with path.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=cols)
        w.writeheader()
        for r in rows:
            w.writerow({c: "" if r.get(c) is None else _cell(r.get(c)) for c in cols})
    written = [path]
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return written
    data = {c: [_cell(r.get(c)) for r in rows] for c in cols}
    table = pa.table({c: pa.array(v, type=_arrow_type(pa, v)) for c, v in data.items()})
    pq.write_table(table, out_dir / "results.parquet")
    return written + [out_dir / "results.parquet"]


def _arrow_type(pa, values: list[Any]):
    present = [v for v in values if v is not None]
    if present and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in present):
        return pa.float64()
    return pa.string() if all(isinstance(v, str) for v in present) else None


def read_table(out_dir: str | Path, numeric: set[str]) -> list[dict[str, Any]]:
    """The rows of ``results.csv``: the ``numeric`` columns as floats, the others as text; empty cells None."""
    rows = []
    with (Path(out_dir) / "results.csv").open(newline="") as f:
        for r in csv.DictReader(f):
            rows.append({k: _parse(v) if k in numeric else (v if v != "" else None) for k, v in r.items()})
    return rows


def _parse(text: str) -> Any:
    if text == "":
        return None
    try:
        return float(text)
    except ValueError:
        return text
