"""Small helpers of the dense SLAM node: the initial pose param, the TUM trajectory file, model colours."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from probeless.errors import ParamError
from probeless.messages.geometry import matrix_from_quat, transform_from
from probeless.tracking.tum import HEADER


def pose_param(values: tuple[float, ...], node_id: str) -> np.ndarray:
    """world_from_rgbd from ``tx ty tz qx qy qz qw`` (TUM order); identity for an empty tuple."""
    if not values:
        return np.eye(4)
    if len(values) != 7 or not np.all(np.isfinite(values)) or np.linalg.norm(values[3:]) < 1e-9:
        raise ParamError(f"needs 7 finite numbers tx ty tz qx qy qz qw with a non-zero quaternion, got {list(values)}",
                         node_id=node_id, key="initial_pose")
    return transform_from(matrix_from_quat(np.asarray(values[3:])), np.asarray(values[:3]))


def open_trajectory(path: str, node_id: str):
    """The TUM trajectory file, created with its parent folders and header line."""
    try:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        f = open(path, "w")
    except OSError as exc:
        raise ParamError(f"cannot write {path}: {exc.strerror}", node_id=node_id, key="trajectory_out") from None
    f.write(HEADER + "\n")
    return f


def srgb8(colors: np.ndarray) -> np.ndarray:
    """Open3D's 0..1 float colours (sRGB values of the images) as uint8 sRGB."""
    return np.clip(np.round(colors * 255.0), 0, 255).astype(np.uint8)
