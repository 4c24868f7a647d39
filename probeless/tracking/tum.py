"""Trajectories in the TUM RGB-D format: ``timestamp tx ty tz qx qy qz qw`` per line.

``timestamp`` is in seconds with all nine decimals (exact nanoseconds), the pose is
world_from_camera (translation [m], unit quaternion ``[x, y, z, w]`` with w >= 0), as the TUM
benchmark tools (``evaluate_ate.py``, ``evaluate_rpe.py``, ``associate.py``) read them. Lines
starting with ``#`` are comments.
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterable, Sequence, TextIO

import numpy as np

from probeless.errors import ProbelessError
from probeless.geom.rotation import quat_from_matrix

HEADER = "# timestamp tx ty tz qx qy qz qw"


def format_stamp(stamp_ns: int) -> str:
    """Seconds with nine decimals, exact for any integer nanoseconds (no float rounding)."""
    stamp_ns = int(stamp_ns)
    sign = "-" if stamp_ns < 0 else ""
    s, ns = divmod(abs(stamp_ns), 1_000_000_000)
    return f"{sign}{s}.{ns:09d}"


def tum_line(stamp_ns: int, world_from_camera: np.ndarray) -> str:
    """One trajectory line (no newline); ProbelessError for a non-finite pose."""
    T = np.asarray(world_from_camera, dtype=np.float64)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise ProbelessError(f"TUM line at {stamp_ns} ns: pose is not a finite 4x4 matrix")
    q = quat_from_matrix(T[:3, :3])
    return " ".join([format_stamp(stamp_ns), *(f"{v:.9f}" for v in T[:3, 3]), *(f"{v:.9f}" for v in q)])


def write_tum_lines(f: TextIO, stamps_ns: Iterable[int], poses: Iterable[np.ndarray | None]) -> int:
    """Write the lines of the frames that have a pose (None = untracked, skipped); returns how many."""
    n = 0
    for stamp, T in zip(stamps_ns, poses):
        if T is not None:
            f.write(tum_line(stamp, T) + "\n")
            n += 1
    return n


def write_tum(path: str | Path, stamps_ns: Sequence[int], poses: Sequence[np.ndarray | None]) -> Path:
    """Write a TUM trajectory file (header comment + one line per pose that is not None); returns the path."""
    if len(stamps_ns) != len(poses):
        raise ProbelessError(f"{path}: {len(stamps_ns)} stamps but {len(poses)} poses")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w") as f:
        f.write(HEADER + "\n")
        write_tum_lines(f, stamps_ns, poses)
    return path


def read_tum(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """(stamps_ns int64 (N,), poses (N, 4, 4) world_from_camera) of a TUM trajectory, in stamp order."""
    from probeless.datasets.tum import read_groundtruth

    return read_groundtruth(Path(path))
