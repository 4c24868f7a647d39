"""``probeless dataset info`` and ``probeless dataset convert``, wired in by probeless.cli.

Both return the exit status: 0 on success, 2 after printing ``error: ...`` for a DatasetError.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from probeless.errors import DatasetError


def add_dataset_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``dataset`` (with ``info`` and ``convert``) to the top-level subparsers."""
    from probeless.datasets.detect import FORMATS

    p = subparsers.add_parser("dataset", help="inspect RGB-D dataset folders and convert them to TUM format")
    sub = p.add_subparsers(dest="dataset_command", required=True)
    c = sub.add_parser("info", help="detected format, frames, rate, intrinsics, ground truth of a folder")
    c.add_argument("path", help="dataset folder (TUM, Redwood/Open3D or 7-Scenes)")
    c.add_argument("--json", action="store_true", help="print one JSON object")
    _add_read_options(c, FORMATS)
    c.set_defaults(func=cmd_info)
    c = sub.add_parser("convert", help="write an RGB-D folder as a TUM RGB-D folder")
    c.add_argument("src", help="dataset folder to read")
    c.add_argument("dst", help="TUM folder to write")
    c.add_argument("--format", dest="out_format", choices=("tum",), default="tum", help="output format (tum)")
    c.add_argument("--start", type=int, default=0, help="first frame to convert")
    c.add_argument("--max-frames", type=int, default=0, help="frames to convert; 0 = all")
    c.add_argument("--force", action="store_true", help="write into a non-empty folder")
    _add_read_options(c, FORMATS)
    c.set_defaults(func=cmd_convert)
    return p


def _add_read_options(c: argparse.ArgumentParser, formats: tuple[str, ...]) -> None:
    c.add_argument("--input-format", default="auto", choices=("auto", *formats), help="input layout (default: auto)")
    c.add_argument("--fps", type=float, default=30.0, help="rate of formats without stamps [Hz] (default 30)")
    c.add_argument("--max-dt", type=float, default=0.02, help="TUM colour-depth association limit [s]")
    c.add_argument("--trajectory", help="Redwood: the .log of poses (default: groundtruth*.log, or the only one)")
    c.add_argument("--intrinsics", nargs=4, type=float, metavar=("FX", "FY", "CX", "CY"),
                   help="pinhole intrinsics for folders without them [px]")


def _open(ns: argparse.Namespace, path: str):
    from probeless.datasets.detect import open_rgbd
    from probeless.datasets.textfiles import IntrinsicsOverride

    intr = IntrinsicsOverride(*ns.intrinsics) if ns.intrinsics else IntrinsicsOverride()
    return open_rgbd(path, ns.input_format, max_dt_s=ns.max_dt, fps=ns.fps, intrinsics=intr,
                     trajectory=ns.trajectory)


def format_info(info: dict) -> str:
    """Human-readable lines of :func:`probeless.datasets.detect.describe`'s dict."""
    lines = [f"path:          {info['path']}",
             f"format:        {info['format']}",
             f"frames:        {info['frames']} ({info['duration_s']:.2f} s at {info['rate_hz']:g} Hz)",
             f"image size:    {info['width']}x{info['height']}",
             f"intrinsics:    fx={info['fx']:g} fy={info['fy']:g} cx={info['cx']:g} cy={info['cy']:g}",
             f"  from         {info['intrinsics_source']}",
             f"depth scale:   {info['depth_scale']:g} units per metre",
             "ground truth:  " + (f"yes, {info['frames_with_pose']} frame(s) from {info['pose_source']}"
                                   if info["has_ground_truth"] else "no")]
    lines += [f"note:          {n}" for n in info["notes"]]
    return "\n".join(lines)


def cmd_info(ns: argparse.Namespace) -> int:
    """Print what the folder holds (text, or JSON with ``--json``)."""
    from probeless.datasets.detect import describe

    try:
        info = describe(_open(ns, ns.path))
    except DatasetError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(json.dumps(info, indent=2) if ns.json else format_info(info))
    return 0


def cmd_convert(ns: argparse.Namespace) -> int:
    """Convert ``ns.src`` to a TUM folder ``ns.dst``."""
    from probeless.datasets.convert import convert_to_tum
    from probeless.datasets.detect import select

    try:
        seq = select(_open(ns, ns.src), ns.start, ns.max_frames)
        summary = convert_to_tum(seq, ns.dst, force=ns.force)
    except DatasetError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {summary['frames']} frame(s), {summary['poses']} pose(s) from {summary['source']} "
          f"({summary['source_format']}) to {summary['destination']} (tum)")
    return 0
