"""``probeless eval glossy``: glossy ring sampling vs a Monte Carlo Phong-lobe integral (paper 002, Fig. 6).

The compute is :func:`probeless.pano.glossy_eval.evaluate_glossy` (metric: that module's doc), the
table :func:`probeless.pano.glossy_report.format_table`, the figure
:func:`probeless.pano.glossy_figure.glossy_figure`. Old spelling: ``probeless pano glossy``.
"""

from __future__ import annotations

import argparse
import sys

from probeless.eval.harness import add_common_options, emit


def add_arguments(p: argparse.ArgumentParser) -> None:
    """``probeless eval glossy [--json] [--figure OUT.png] [--panorama FILE ...]``."""
    from probeless.pano.glossy_eval import DEFAULT_GLOB

    p.add_argument("--panorama", nargs="+", action="extend", metavar="FILE",
                   help=f"HDR panoramas (default: {DEFAULT_GLOB} relative to the repository)")
    add_common_options(p, figure=("--figure", "write the Figure 6 row (ring over MC) of the first panorama"))
    p.add_argument("--figure-size", type=int, default=128, help="sphere size in the figure [px] (default 128)")
    p.add_argument("--figure-mc-samples", type=int, default=512, help="MC samples per figure pixel (default 512)")
    p.add_argument("--dirs", type=int, default=128, help="random reflection directions (default 128)")
    p.add_argument("--mc-samples", type=int, default=8192, help="Monte Carlo samples per direction (default 8192)")
    p.add_argument("--seed", type=int, default=0, help="seed of the directions and the first MC estimate")


def run(ns: argparse.Namespace) -> int:
    """Run :func:`evaluate_glossy` (and :func:`glossy_figure`), print the table or one JSON object."""
    from probeless.pano.glossy_eval import default_panoramas, evaluate_glossy
    from probeless.pano.glossy_figure import glossy_figure
    from probeless.pano.glossy_report import format_table

    res = evaluate_glossy(ns.panorama, n_dirs=ns.dirs, mc_samples=ns.mc_samples, seed=ns.seed,
                          show_progress=not ns.no_progress)
    if ns.figure:
        glossy_figure((ns.panorama or default_panoramas())[0], ns.figure, size=ns.figure_size,
                      mc_samples=ns.figure_mc_samples, seed=ns.seed)
        res["figure"] = ns.figure
        print(f"wrote {ns.figure}", file=sys.stderr)
    return emit(ns, res, format_table, places=6)
