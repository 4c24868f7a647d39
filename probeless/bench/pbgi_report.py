"""The figure and the printed tables of ``probeless bench pbgi`` (see :mod:`probeless.bench.pbgi`)."""

from __future__ import annotations

import numpy as np

from probeless.bench.pbgi_scenes import FIGURE_CONFIG, SCENES, VARIANTS, Renderers, Scene, Settings, camera, render_once


def write_figure(path: str, images: dict, rows: list) -> None:
    """The Hybrid images (one per scene and view) above bars of each variant's time per configuration."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from probeless.color import to_srgb8
    from probeless.pbgi.cli import _auto_exposure

    keys = sorted(images)
    timed = sorted((r for r in rows if not r.get("skipped")),
                   key=lambda r: (SCENES.index(r["scene"]), r["view"], r["viewport"], r["micro"]))
    fig = plt.figure(figsize=(max(8, 2.6 * len(keys)), 7.5))
    grid = fig.add_gridspec(2, max(len(keys), 1), height_ratios=(1, 1.2))
    for i, key in enumerate(keys):
        out = images[key]
        ax = fig.add_subplot(grid[0, i])
        ax.imshow(to_srgb8(out.color * _auto_exposure(out.color, out.mask)))
        ax.set_title(f"{key[0]} View{key[1]} (Hybrid {FIGURE_CONFIG[0]}², {FIGURE_CONFIG[1]}²)", fontsize=8)
        ax.axis("off")
    ax = fig.add_subplot(grid[1, :])
    x = np.arange(len(timed))
    for j, v in enumerate(VARIANTS):
        ms = [r["variants"][v].get("ms") or 0.0 for r in timed]
        ax.bar(x + (j - 1) * 0.27, ms, 0.27, label=v)
    ax.set_xticks(x, [f"{r['scene'][:4]} V{r['view']} {r['viewport']}/{r['micro']}" for r in timed], fontsize=6,
                  rotation=90)
    ax.set_yscale("log")
    ax.set_ylabel("PBGI time [ms] (llvmpipe, 2 cores)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, axis="y")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def missing_figure_images(st: Settings, scenes: dict, renderers: Renderers, images: dict) -> None:
    """Render the figure's Hybrid images that the table did not (a reduced grid, or a skipped configuration)."""
    size, micro = FIGURE_CONFIG
    for name in st.scenes:
        for view in st.views:
            if isinstance(scenes.get(name), Scene) and (name, view) not in images:
                _, out = render_once(renderers.get(scenes[name], micro), camera(scenes[name], view, size), size,
                                     "hybrid")
                if out is not None:
                    images[(name, view)] = out


# -- run -------------------------------------------------------------------------------------------------------------


def _cell(fig: dict | None, key: str, fmt: str) -> str:
    v = (fig or {}).get(key)
    return "x" if v is None else format(v, fmt)


def _grid_table(r: dict, title: str, variants, key: str, fmt: str):
    """Rows variant x viewport, columns scene/view x micro (the paper's Table 3 layout)."""
    from rich.markup import escape
    from rich.table import Table

    s = r["settings"]
    cols = [(sc, v) for sc in s["scenes"] for v in s["views"]]
    cells = {(x["scene"], x["view"], x["viewport"], x["micro"]): x for x in r["table3"]}
    t = Table(title=escape(title))
    t.add_column("variant")
    t.add_column("viewport", justify="right")
    for sc, v in cols:
        for m in s["micro"]:
            t.add_column(f"{sc} V{v}\n{m}x{m}", justify="right")
    for var in variants:
        for n in s["viewports"]:
            row = [var if n == s["viewports"][0] else "", f"{n}x{n}"]
            for sc, v in cols:
                for m in s["micro"]:
                    row.append(_cell(cells.get((sc, v, n, m), {}).get("variants", {}).get(var), key, fmt))
            t.add_row(*row)
    return t


def print_table(r: dict) -> None:
    """The BSH table, Table 3 (time, extra memory, micro-buffer storage), the same-work gate, the sweep."""
    import sys

    from rich.console import Console
    from rich.table import Table

    console = Console(file=sys.stdout)
    if not console.is_terminal:
        console = Console(file=sys.stdout, width=200)
    b = r["bsh"]
    t = Table(title=f"BSH build (tc {b['tc']}, tn {b['tn']}; numba warm-up {b['numba_warmup_s']:.1f} s)")
    for c in ("cloud", "points", "nodes", "clustered nodes", "clusters", "build s"):
        t.add_column(c, justify="left" if c == "cloud" else "right")
    for row in b["rows"]:
        if "skipped" in row:
            t.add_row(row["cloud"], row["skipped"], "", "", "", "")
        else:
            t.add_row(row["cloud"], f"{row['points']:,}", f"{row['nodes']:,}", f"{row['nodes_clustered']:,}",
                      f"{row['clusters']:,}", f"{row['build_s']:.2f}")
    console.print(t)
    console.print(_grid_table(r, f"PBGI time [ms] on {r['device']} ({r['cpu_cores']} cores); x = error or skipped",
                              VARIANTS, "ms", ".1f"))
    console.print(_grid_table(r, "extra memory [MB] (pair buffers)", ("mipmapped", "hybrid"), "extra_mb", ".1f"))
    console.print(_grid_table(r, "micro-buffer storage [MB]", ("classic",), "micro_mb", ".1f"))
    h, m = r["hybrid_speedup"], r["mipmapped_speedup"]
    console.print(f"reference: {r['reference']}; images_equal={r['images_equal']} (gate rel RMS <= "
                  f"{r['settings']['gate_rel_rms']:g}); hybrid speedup max {_cell(h, 'max', '.2f')} median "
                  f"{_cell(h, 'median', '.2f')}; mipmapped speedup max {_cell(m, 'max', '.2f')} median "
                  f"{_cell(m, 'median', '.2f')} (by CPU time: hybrid max {_cell(h['cpu'], 'max', '.2f')} median "
                  f"{_cell(h['cpu'], 'median', '.2f')}); {r['configs_run']} configurations run, {r['configs_skipped']} "
                  f"skipped; {r['duration_s']:.0f} s")
    sw = r["hybrid_threshold_sweep"]
    if sw:
        console.print(f"Hybrid threshold ({sw['scene']} View{sw['view']} {sw['viewport']}², {sw['micro']}²; classic "
                      f"{_cell(sw, 'classic_ms', '.0f')} ms): " + ", ".join(
                          f"{p['factor']:g} omega {_cell(p, 'ms', '.0f')} ms" for p in sw["points"])
                      + f"; fastest {sw['fastest_factor']} (paper {sw['paper_factor']:g})")
