"""``probeless eval diffuse``: the fast diffuse maps (GPU, matmul, SH9) against the exact convolution of
the full-resolution frame: errors and timings.

The compute is :func:`probeless.pano.diffuse_eval.evaluate_diffuse`, the table and figure
:mod:`probeless.pano.diffuse_report`. Old spelling: ``probeless pano diffuse``.
"""

from __future__ import annotations

import argparse

from probeless.errors import ProbelessError
from probeless.eval.harness import add_common_options, emit


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``probeless eval diffuse``."""
    p.add_argument("--panorama", action="append", metavar="HDR", help="HDR panorama (repeatable); default: "
                                                                      "../shared/data/hdri/*.hdr")
    p.add_argument("--sizes", default="32x16,64x32,128x64", help="diffuse map sizes WxH, comma-separated")
    p.add_argument("--in-size", default="128x64", help="GPU input (area-averaged) size WxH (default 128x64)")
    add_common_options(p, figure=("--figure", "write a picture row per panorama (at the first size)"))


def parse_sizes(text: str) -> list[tuple[int, int]]:
    """``"32x16,64x32"`` -> ``[(32, 16), (64, 32)]``."""
    try:
        return [tuple(int(v) for v in s.lower().split("x")) for s in text.split(",")]  # type: ignore[misc]
    except ValueError:
        raise ProbelessError(f"sizes must look like 32x16,64x32, got {text!r}") from None


def run(ns: argparse.Namespace) -> int:
    """Evaluate, draw (``--figure``), print the table or one JSON object. Returns the exit status."""
    from probeless.pano.diffuse_eval import default_panoramas, evaluate_diffuse
    from probeless.pano.diffuse_report import diffuse_figure, format_table

    sizes = parse_sizes(ns.sizes)
    panoramas = ns.panorama or default_panoramas()
    result = evaluate_diffuse(panoramas, sizes, gpu_in_size=parse_sizes(ns.in_size)[0],
                              show_progress=not ns.no_progress)
    if ns.figure:
        result["figure"] = str(diffuse_figure(panoramas, ns.figure, sizes[0], parse_sizes(ns.in_size)[0]))
    return emit(ns, result, lambda r: format_table(r["summary"], sizes))
