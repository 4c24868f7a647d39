"""Small helpers of the dense SLAM node: the initial pose param and the TUM trajectory file."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from probeless.errors import ParamError
from probeless.geom.rotation import matrix_from_quat, transform_from
from probeless.tracking.tum import HEADER


def pose_problem(values: tuple[float, ...]) -> str | None:
    """The ``initial_pose`` param's rule (a param check): empty, or 7 finite numbers with a non-zero quaternion."""
    if not values:
        return None
    if len(values) != 7 or not np.all(np.isfinite(values)) or np.linalg.norm(values[3:]) < 1e-9:
        return f"needs 7 finite numbers tx ty tz qx qy qz qw with a non-zero quaternion, got {list(values)}"
    return None


def pose_param(values: tuple[float, ...], node_id: str) -> np.ndarray:
    """world_from_rgbd from ``tx ty tz qx qy qz qw`` (TUM order); identity for an empty tuple."""
    problem = pose_problem(values)
    if problem:
        raise ParamError(problem, node_id=node_id, key="initial_pose")
    if not values:
        return np.eye(4)
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
