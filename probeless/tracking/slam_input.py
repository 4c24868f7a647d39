"""Checking and subsampling one RGB-D frame before it is loaded into the SLAM model (pure numpy)."""

from __future__ import annotations

import cv2
import numpy as np

from probeless.tracking.slam_math import clean_depth
from probeless.tracking.slam_params import SlamParams


def prepare_frame(rgb: np.ndarray, depth: np.ndarray, depth_scale: float, width: int, height: int, n: int,
                  p: SlamParams) -> tuple[str, np.ndarray | None, np.ndarray | None]:
    """(why, rgb, depth): ``why`` is "" and the frame subsampled to 1/n (depth ``[::n, ::n]`` as
    uint16, colour area-averaged to the same size, both C-contiguous), or why the frame is
    unusable (wrong size or type, non-positive scale, too few depths in [depth_min, depth_max])
    and None, None."""
    if rgb.shape != (height, width, 3) or rgb.dtype != np.uint8:
        return f"rgb is {rgb.dtype} {rgb.shape}, expected uint8 ({height}, {width}, 3)", None, None
    if depth.shape != (height, width):
        return f"depth is {depth.shape}, expected ({height}, {width})", None, None
    if not depth_scale > 0:
        return f"depth_scale {depth_scale} is not > 0", None, None
    if depth.dtype != np.uint16 and not np.issubdtype(depth.dtype, np.floating):
        return f"depth is {depth.dtype}, expected uint16 (or float in the same units)", None, None
    depth = clean_depth(depth)[::n, ::n]
    valid = np.count_nonzero((depth >= p.depth_min * depth_scale) & (depth <= p.depth_max * depth_scale))
    if valid < p.min_valid_fraction * depth.size:
        return f"{valid / depth.size:.1%} valid depth pixels in [{p.depth_min}, {p.depth_max}] m", None, None
    if n > 1:
        rgb = cv2.resize(rgb, (depth.shape[1], depth.shape[0]), interpolation=cv2.INTER_AREA)
    return "", np.array(depth, order="C"), np.array(rgb, order="C")
