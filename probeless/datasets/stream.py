"""Frames on disk -> the messages a player publishes for them (pure: no timing, no node).

RGB-D outputs per frame, in this order: ``rgbd/camera_info`` (with every frame, so a late
subscriber or a synchroniser always has one, stamped like the colour image), ``rgb`` (rgb8, colour
stamp), ``depth`` (uint16 as stored, depth stamp, the dataset's depth scale) and, where the frame
has one, ``gt/rgbd_pose`` (world_from_camera at the colour stamp, frame "world").
"""

from __future__ import annotations

from typing import Iterator

import numpy as np

from probeless.datasets.base import RgbdSequence, camera_info, read_color, read_depth
from probeless.datasets.playback import Group
from probeless.errors import DatasetError
from probeless.messages.geometry import PoseStamped
from probeless.messages.header import Header
from probeless.messages.sensor import DepthImage, Image


def loop_period_ns(stamps_ns: list[int], rate_hz: float) -> int:
    """Stamp offset between two passes of a looped sequence: its span plus one frame interval
    (the median interval, or 1 / rate_hz for a single frame)."""
    if len(stamps_ns) >= 2:
        step = int(np.median(np.diff(np.asarray(stamps_ns, dtype=np.int64))))
    else:
        step = round(1e9 / rate_hz) if rate_hz > 0 else 0
    return stamps_ns[-1] - stamps_ns[0] + max(step, 1)


def rgbd_groups(seq: RgbdSequence, frame_id: str = "rgbd", offset_ns: int = 0) -> Iterator[Group]:
    """One group per frame of ``seq`` (outputs as in the module docstring), stamps shifted by ``offset_ns``."""
    intr = seq.intrinsics
    for f in seq.frames:
        stamp, dstamp = f.stamp_ns + offset_ns, f.depth_stamp_ns + offset_ns
        rgb, depth = read_color(f.rgb_path), read_depth(f.depth_path, seq.depth_invalid)
        if rgb.shape[:2] != (intr.height, intr.width):
            raise DatasetError(f"{f.rgb_path}: image is {rgb.shape[1]}x{rgb.shape[0]}, "
                               f"the sequence is {intr.width}x{intr.height}")
        if depth.shape != (intr.height, intr.width):
            raise DatasetError(f"{f.depth_path}: depth is {depth.shape[1]}x{depth.shape[0]}, "
                               f"the sequence is {intr.width}x{intr.height}")
        msgs = [("rgbd/camera_info", camera_info(intr, stamp, frame_id)),
                ("rgb", Image(Header(stamp, frame_id), rgb, "rgb8")),
                ("depth", DepthImage(Header(dstamp, frame_id), depth, seq.depth_scale))]
        if f.pose is not None:
            msgs.append(("gt/rgbd_pose", PoseStamped(Header(stamp, "world"), frame_id, f.pose)))
        yield stamp, msgs

