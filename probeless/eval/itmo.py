"""``probeless eval itmo``: paper 002's Figure 7 made quantitative (LDR vs inverse tone mapped vs true HDR).

The compute and the figure are :mod:`probeless.pano.itmo_eval`. Old spelling: ``probeless pano itmo``.
"""

from __future__ import annotations

import argparse

from probeless.eval.harness import add_common_options, emit

_SHORT = {"rel_rmse": "rel", "rel_rmse_scaled": "rel*", "psnr": "psnr"}


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``probeless eval itmo``."""
    from probeless.pano.itmo import EXPOSURE_PERCENTILE, EXPOSURE_TARGET

    add_common_options(p, figure=("--figure", "write the sphere grid"))
    p.add_argument("--panorama", nargs="+", metavar="FILE", help="true-HDR panoramas (default ../shared/data/hdri)")
    p.add_argument("--exposure-percentile", type=float, default=EXPOSURE_PERCENTILE,
                   help="camera metering: this solid-angle weighted luminance quantile ... "
                        f"(default {EXPOSURE_PERCENTILE})")
    p.add_argument("--exposure-target", type=float, default=EXPOSURE_TARGET,
                   help=f"... is exposed to this linear value (default {EXPOSURE_TARGET})")


def run(ns: argparse.Namespace) -> int:
    """Run the evaluation for the parsed ``ns``; JSON or tables on stdout."""
    from probeless.pano.itmo_eval import evaluate

    result = evaluate(ns.panorama, figure=ns.figure, show_progress=not ns.no_progress,
                      percentile=ns.exposure_percentile, target=ns.exposure_target)
    emit(ns, result, print_table)
    if ns.figure and not ns.json:
        print(f"\nwrote {ns.figure}")
    return 0


def print_table(result: dict) -> None:
    """The per-panorama tables and the winners, readable."""
    from probeless.pano.spheres import OBJECTS

    cols = [(o, k) for o in OBJECTS for k in ("rel_rmse", "rel_rmse_scaled", "psnr")]
    for r in result["panoramas"] + [result["overall"]]:
        if "exposure" in r:
            print(f"\n{r['name']}: exposure {r['exposure']:.4g}, camera clips {r['clipped_fraction']:.1%} of the "
                  f"sphere, LDR keeps {r['ldr_energy_fraction']:.1%} of the light")
        else:
            print(f"\n{r['name']}")
        print(f"  {'map':13s} " + " ".join(f"{o[:4] + ' ' + _SHORT[k]:>10s}" for o, k in cols))
        for m, objs in r["errors"].items():
            print(f"  {m:13s} " + " ".join(f"{objs[o][k]:10.3f}" for o, k in cols))
        for o, per in r["winners"].items():
            cells = []
            for k, w in per.items():
                unit = "x" if k.startswith("rel") else " dB"
                cells.append(f"{_SHORT[k]} {w['best']} ({w['margin_over_runner_up']:.2f}{unit} over "
                             f"{w['runner_up']}, {w['margin_over_ldr']:.2f}{unit} over ldr)")
            print(f"  best {o:8s}: " + "; ".join(cells))
    print("\n(rel = relative RMSE in linear camera units; rel* = after the least-squares scale; "
          "psnr = PSNR after clip + sRGB [dB])")
