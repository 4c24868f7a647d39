"""``probeless coarse preview``: pictures of the coarse room model.

Its accuracy is ``probeless eval coarse`` (:mod:`probeless.eval.coarse`); the command line adds its
old spelling ``probeless coarse eval`` to this group (:func:`probeless.eval.harness.add_old_spellings`).
"""

from __future__ import annotations

import argparse
from typing import Any


def add_coarse_parser(sub: Any) -> Any:
    """Add the ``coarse`` command group to the top-level subparsers; returns its subparsers."""
    coarse = sub.add_parser("coarse", help="coarse room model: preview pictures, accuracy on synthetic scenes")
    cmds = coarse.add_subparsers(dest="coarse_cmd", required=True)
    p = cmds.add_parser("preview", help="texture the room from a scene or recording and write PNGs")
    p.add_argument("source", metavar="BAG_OR_SCENE", help="scene file (.yaml) or rig recording (.mcap) with "
                                                          "fisheye, fisheye/camera_info, gt/fisheye_pose, floorplan")
    p.add_argument("-o", "--out", required=True, metavar="DIR", help="output folder for the PNGs")
    p.add_argument("--duration", type=float, metavar="S", help="scene: render this much scene time [s]")
    p.add_argument("--atlas-size", type=int, default=1024, help="atlas side [texels] (default 1024)")
    p.add_argument("--snapshots", type=int, default=4, help="atlas snapshots in filling.png (default 4)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_preview)
    return cmds


def cmd_preview(ns: argparse.Namespace) -> int:
    from probeless.coarse.preview import preview

    written = preview(ns.source, ns.out, duration=ns.duration, atlas_size=ns.atlas_size, snapshots=ns.snapshots,
                      show_progress=not ns.no_progress)
    for path in written:
        print(path)
    return 0
