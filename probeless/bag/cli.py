"""``probeless bag info``, ``export`` and ``import``: parsers and commands, wired in by probeless.cli.

Each command returns the exit status: 0 on success, 2 after printing ``error: ...`` to stderr
for a BagError (not an MCAP file, missing file, would overwrite, ...).
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any, Callable

from probeless.errors import BagError


def add_info_parser(sub: Any) -> argparse.ArgumentParser:
    """Add ``info`` to the subparsers ``sub`` of ``probeless bag``."""
    p = sub.add_parser("info", help="show what a recording holds: topics, rates, sizes, graph, gaps")
    p.add_argument("paths", nargs="+", metavar="FILE",
                   help="MCAP file(s); the name of a split recording (run.mcap for run_000.mcap, ...) works too")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--digest", action="store_true",
                   help="also compute content_digest: SHA-256 of all messages except diagnostics (reads "
                        "every message; equal for two lockstep replays of the same run)")
    p.set_defaults(func=cmd_info)
    return p


def add_export_parser(sub: Any, exporters: dict[str, Callable] | None = None) -> argparse.ArgumentParser:
    """Add ``export`` to the subparsers ``sub`` of ``probeless bag``. ``exporters`` adds formats that live in
    packages above this one (name -> ``f(paths, out, force=, topics=, progress=) -> ExportSummary``)."""
    from probeless.bag.export import FORMATS

    exporters = {"ros2": _export_ros2, **(exporters or {})}
    p = sub.add_parser("export", help="convert a recording: Foxglove MCAP (JSON), a directory of PNGs"
                       + "".join(f", {name}" for name in exporters))
    p.add_argument("paths", nargs="+", metavar="FILE", help="MCAP file(s) or the name of a split recording")
    p.add_argument("--format", choices=FORMATS + tuple(exporters), default="foxglove", help="default: foxglove")
    p.add_argument("-o", "--out", required=True,
                   help="output .mcap file (foxglove), directory (png-dir, ros2: a rosbag2 folder) or .rrd file "
                        "(rerun)")
    p.add_argument("--topic", action="append", dest="topics", metavar="TOPIC", help="only this topic (repeatable)")
    p.add_argument("--force", action="store_true", help="overwrite the output")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_export, exporters=exporters)
    return p


def cmd_info(ns: argparse.Namespace) -> int:
    """Print the info report of ``ns.paths`` (text, or one JSON object with ``ns.json``)."""
    from probeless.bag.info import format_info, info_report

    try:
        report = info_report(ns.paths)
        if getattr(ns, "digest", False):
            from probeless.bag.compare import content_digest
            from probeless.bag.writer import recording_paths

            report["content_digest"] = [content_digest(str(p)) for p in recording_paths(ns.paths)]
    except BagError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if getattr(ns, "json", False):
        print(json.dumps(report, indent=2))
    else:
        print(format_info(report))
        for digest in report.get("content_digest", []):
            print(f"content digest: {digest}")
    return 0


def cmd_export(ns: argparse.Namespace) -> int:
    """Export ``ns.paths`` to ``ns.out`` in ``ns.format``; prints what was written and skipped."""
    from probeless.bag.export import export_foxglove, export_png_dir

    run = {"png-dir": export_png_dir, "foxglove": export_foxglove, **(getattr(ns, "exporters", None) or {})}[ns.format]
    progress = not getattr(ns, "no_progress", False) and sys.stderr.isatty()
    try:
        summary = run(ns.paths, ns.out, force=ns.force, topics=getattr(ns, "topics", None), progress=progress)
    except BagError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for w in summary.warnings:
        print(f"WARNING: {w}", file=sys.stderr)
    for topic, what in sorted(summary.schemas.items()):
        count = summary.written.get(topic) or summary.skipped.get(topic, 0)
        print(f"  {topic}: {count} message(s) {'-> ' + what if topic in summary.written else what}")
    for note in summary.notes:
        print(f"note: {note}")
    print(f"wrote {ns.out}: {sum(summary.written.values())} message(s), "
          f"{sum(summary.skipped.values())} skipped")
    return 0


def _export_ros2(*args: Any, **kwargs: Any) -> Any:
    """``bag export --format ros2``: a rosbag2 folder (MCAP, CDR) through rosbags (``probeless[ros]``)."""
    from probeless.bag.ros_export import export_ros2

    return export_ros2(*args, **kwargs)


def add_import_parser(sub: Any) -> argparse.ArgumentParser:
    """Add ``import`` (a ROS bag -> a probeless recording) to the subparsers ``sub`` of ``probeless bag``."""
    from probeless.bag.ros_topics import PRESET_NAMES

    p = sub.add_parser("import", help="convert a ROS 1 bag, a rosbag2 folder or one .mcap/.db3 into a recording "
                                      "(needs probeless[ros])")
    p.add_argument("src", metavar="SRC", help=".bag file, rosbag2 folder, or a single .mcap/.db3")
    p.add_argument("-o", "--out", required=True, metavar="OUT.mcap", help="probeless recording to write")
    p.add_argument("--preset", choices=PRESET_NAMES,
                   help="topic names of realsense-ros (and the RealSense Viewer), usb_cam, TUM RGB-D bags, or "
                        "probeless (a bag written by `bag export --format ros2`)")
    p.add_argument("--map", dest="maps", action="append", default=[], metavar="ROS_TOPIC=TOPIC",
                   help="convert ROS_TOPIC onto TOPIC, e.g. /cam/image_raw=rig/fisheye (repeatable)")
    p.add_argument("--start", type=float, default=0.0, metavar="S", help="skip the first S seconds")
    p.add_argument("--duration", type=float, default=0.0, metavar="D", help="import only D seconds; 0 = all")
    p.add_argument("--force", action="store_true", help="overwrite OUT")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_import)
    return p


def cmd_import(ns: argparse.Namespace) -> int:
    """Import ``ns.src`` into ``ns.out``; prints what was written and which ROS topics were skipped."""
    from probeless.bag.ros_import import import_bag

    progress = not getattr(ns, "no_progress", False) and sys.stderr.isatty()
    try:
        summary = import_bag(ns.src, ns.out, preset=ns.preset, maps=ns.maps, start_s=ns.start,
                             duration_s=ns.duration, force=ns.force, progress=progress)
    except BagError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for topic, n in sorted(summary.written.items()):
        print(f"  {topic}: {n} message(s)")
    for topic, why in sorted(summary.skipped.items()):
        print(f"  skipped {topic} ({why})")
    print(f"wrote {ns.out}: {sum(summary.written.values())} message(s)")
    return 0
