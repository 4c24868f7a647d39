"""``probeless sweep report DIR``: the results table aggregated (mean ± std over seeds) and plotted.

For each reported value: a table with one row per ``rows`` label (joined with every axis that is neither
aggregated nor the column axis) and one column per ``columns`` label, each cell the mean ± standard
deviation (n - 1) over the ``over`` axes (default ``seed``) of the runs that finished; and a grouped bar
chart with those standard deviations as error bars. Both go to ``DIR/report/`` (``report.md``, one PNG per
value), and the tables are printed.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from probeless.errors import SweepError
from probeless.sweep.spec import short_label
from probeless.sweep.table import read_table


@dataclass
class Layout:
    """Which axes are rows, columns and aggregated, and which values are reported."""

    rows: list[str]
    column: str | None
    over: list[str]
    values: list[str]


def layout(meta: dict[str, Any]) -> Layout:
    """The report's layout from ``sweep.json`` (the sweep file's ``report`` section, else defaults)."""
    axes, cfg = meta["axes"], meta.get("report") or {}
    over = list(cfg.get("over") or [a for a in axes if a == "seed"])
    free = [a for a in axes if a not in over]
    row = cfg.get("rows") or (free[0] if free else None)
    column = cfg.get("columns") or next((a for a in free if a != row), None)
    rows = [row] + [a for a in free if a not in (row, column)] if row else []
    return Layout(rows, column, over, list(cfg.get("values") or meta["collect"]))


def mean_std(values: list[float]) -> tuple[float, float, int]:
    """(mean, sample standard deviation or 0 for one value, n)."""
    n = len(values)
    mean = sum(values) / n
    std = math.sqrt(sum((v - mean) ** 2 for v in values) / (n - 1)) if n > 1 else 0.0
    return mean, std, n


def aggregate(rows: list[dict], lay: Layout, value: str) -> tuple[list[str], list[str], dict]:
    """(row labels, column labels, {(row, column): (mean, std, n)}) of one value over finished runs."""
    groups: dict[tuple[str, str], list[float]] = {}
    row_labels: list[str] = []
    col_labels: list[str] = []
    for r in rows:
        rl = " / ".join(short_label(r[a]) for a in lay.rows)
        cl = short_label(r[lay.column]) if lay.column else value
        row_labels += [rl] if rl not in row_labels else []
        col_labels += [cl] if cl not in col_labels else []
        v = r.get(value)
        if r.get("status") == "ok" and isinstance(v, float) and math.isfinite(v):
            groups.setdefault((rl, cl), []).append(v)
    return row_labels, col_labels, {k: mean_std(v) for k, v in groups.items()}


def format_cell(cell: tuple[float, float, int] | None) -> str:
    if cell is None:
        return "-"
    mean, std, n = cell
    return f"{mean:.3f} ± {std:.3f}" if n > 1 else f"{mean:.3f}"


def markdown_table(value: str, lay: Layout, row_labels, col_labels, cells) -> str:
    """One value's aggregated table in Markdown."""
    head = " / ".join(lay.rows) or "run"
    lines = [f"| {head} | " + " | ".join(col_labels) + " |", "|---" * (len(col_labels) + 1) + "|"]
    for rl in row_labels:
        lines.append(f"| {rl} | " + " | ".join(format_cell(cells.get((rl, cl))) for cl in col_labels) + " |")
    return "\n".join(lines)


def plot(value: str, lay: Layout, row_labels, col_labels, cells, path: Path) -> None:
    """Grouped bars: one group per column label, one bar per row label, std error bars."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    width = 0.8 / max(1, len(row_labels))
    bars = len(col_labels) * max(1, len(row_labels))
    fig, ax = plt.subplots(figsize=(min(12.0, max(6.0, 0.18 * bars + 3.5)), 4.5))
    for i, rl in enumerate(row_labels):
        xs = [j + (i - (len(row_labels) - 1) / 2) * width for j in range(len(col_labels))]
        got = [cells.get((rl, cl)) for cl in col_labels]
        ax.bar(xs, [c[0] if c else math.nan for c in got], width, yerr=[c[1] if c else 0 for c in got],
               capsize=3, label=rl)
    ax.set_xticks(range(len(col_labels)), col_labels, rotation=20, ha="right")
    ax.set_ylabel(value)
    over = f" (mean ± std over {', '.join(lay.over)})" if lay.over else ""
    ax.set_title(f"{value} by {' / '.join(lay.rows)}{' and ' + lay.column if lay.column else ''}{over}")
    ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def report(out_dir: str | Path, plots: bool = True) -> str:
    """Aggregate and plot a sweep's results (module doc); returns the Markdown text (also in report.md)."""
    out_dir = Path(out_dir)
    try:
        meta = json.loads((out_dir / "sweep.json").read_text())
    except (OSError, ValueError) as exc:
        raise SweepError(f"not a sweep results directory (sweep.json: {exc})", file=str(out_dir)) from None
    if not (out_dir / "results.csv").is_file():
        raise SweepError("no results.csv: run the sweep first", file=str(out_dir))
    lay = layout(meta)
    rows = read_table(out_dir, numeric=set(meta["collect"]) | {"wall_s"})
    done = sum(r["status"] == "ok" for r in rows)
    failed = [r for r in rows if r["status"] == "failed"]
    parts = [f"# sweep {meta['name']}: {done} of {len(rows)} runs finished, {len(failed)} failed"]
    (out_dir / "report").mkdir(exist_ok=True)
    for value in lay.values:
        row_labels, col_labels, cells = aggregate(rows, lay, value)
        parts.append(f"\n## {value}\n\n" + markdown_table(value, lay, row_labels, col_labels, cells))
        if plots:
            png = out_dir / "report" / f"{value}.png"
            plot(value, lay, row_labels, col_labels, cells, png)
            parts.append(f"\n![{value}]({png.name})")
    if failed:
        parts.append("\n## failed runs\n\n" + "\n".join(f"- {r['run_id']}: {r['error']}" for r in failed))
    text = "\n".join(parts) + "\n"
    (out_dir / "report" / "report.md").write_text(text)
    return text
