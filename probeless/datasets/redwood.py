"""Redwood / Open3D RGB-D folders: ``image/`` (or ``color/``) and ``depth/`` paired in name order,
an optional intrinsics JSON (Open3D ``PinholeCameraIntrinsic``) and an optional ``.log`` trajectory.

The ``.log`` format holds per frame a line ``i j n`` (i = frame index, 0-based) and a 4x4
camera-to-world matrix (world_from_camera). Several logs in a folder: one whose name contains
``groundtruth`` is preferred (ground truth over a reconstruction); otherwise name one with the
``trajectory`` argument. Frames the log does not cover have no pose.

Without an intrinsics JSON the Redwood/Open3D convention applies: Open3D's PrimeSenseDefault
(fx = fy = 525, cx = 319.5, cy = 239.5, 640x480); the source says so and a warning is logged.
Depth scale 1000 unless the JSON has ``depth_scale``. No stamps: frame k is at k / fps.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from probeless.datasets.base import (
    Intrinsics,
    RgbdFrame,
    RgbdSequence,
    check_intrinsics,
    image_size,
    list_images,
    orthonormalize,
)
from probeless.datasets.textfiles import (
    IntrinsicsOverride,
    data_lines,
    find_intrinsics_json,
    parse_floats,
    read_open3d_intrinsics,
)
from probeless.errors import DatasetError

COLOR_DIRS = ("image", "color", "rgb")
DEPTH_SCALE = 1000.0
PRIMESENSE_DEFAULT = Intrinsics(640, 480, 525.0, 525.0, 319.5, 239.5)
log = logging.getLogger(__name__)


def color_dir(root: Path) -> Path | None:
    """The colour folder of a Redwood layout, or None."""
    return next((root / d for d in COLOR_DIRS if (root / d).is_dir()), None)


def read_log(path: Path) -> dict[int, np.ndarray]:
    """Frame index -> world_from_camera (rotation orthonormalised) of a Redwood ``.log`` file."""
    lines = list(data_lines(path))
    if len(lines) % 5:
        raise DatasetError(f"{path}: {len(lines)} data lines is not a multiple of 5 "
                           "(one 'i j n' line + 4 matrix rows per frame)")
    poses: dict[int, np.ndarray] = {}
    for k in range(0, len(lines), 5):
        n, head = lines[k]
        meta = parse_floats(head, path, n, 3)
        if not all(float(v).is_integer() and v >= 0 for v in meta):
            raise DatasetError(f"{path}:{n}: expected three frame indices 'i j n', got {' '.join(head)!r}")
        T = np.array([parse_floats(tok, path, m, 4) for m, tok in lines[k + 1:k + 5]])
        index = int(meta[0])
        if index in poses:
            raise DatasetError(f"{path}:{n}: frame {index} appears twice")
        poses[index] = orthonormalize(T, f"{path}:{lines[k + 1][0]}")
    return poses


def choose_log(root: Path, trajectory: str | None) -> Path | None:
    """The trajectory log to use (rule in the module docstring)."""
    if trajectory:
        path = Path(trajectory) if Path(trajectory).is_absolute() else root / trajectory
        if not path.is_file():
            raise DatasetError(f"{path}: trajectory log is missing")
        return path
    logs = sorted(root.glob("*.log"))
    preferred = [p for p in logs if "groundtruth" in p.name.lower()]
    if len(preferred) == 1:
        return preferred[0]
    if len(logs) <= 1:
        return logs[0] if logs else None
    raise DatasetError(f"{root}: several trajectory logs {[p.name for p in logs]}; choose one with 'trajectory'")


def redwood_intrinsics(root: Path, override: IntrinsicsOverride, width: int,
                       height: int) -> tuple[Intrinsics, str, float]:
    """(intrinsics, source, depth scale) by the rule in the module docstring."""
    js = find_intrinsics_json(root)
    scale = DEPTH_SCALE
    if js is not None:
        intr, obj = read_open3d_intrinsics(js)
        scale = float(obj.get("depth_scale", DEPTH_SCALE))
    if override.given:
        return override.apply(width, height), "parameters fx, fy, cx, cy", scale
    if js is not None:
        return intr, str(js), scale
    log.warning("%s: no intrinsics JSON; using Open3D PrimeSenseDefault (fx=fy=525, cx=319.5, cy=239.5)", root)
    return PRIMESENSE_DEFAULT, "default: Open3D PrimeSenseDefault (no intrinsics JSON in the folder)", scale


def load_redwood(root: Path, *, fps: float = 30.0, intrinsics: IntrinsicsOverride | None = None,
                 trajectory: str | None = None) -> RgbdSequence:
    """Read a Redwood / Open3D folder (see the module docstring)."""
    root, intrinsics = Path(root), intrinsics or IntrinsicsOverride()
    cdir, ddir = color_dir(root), root / "depth"
    if cdir is None or not ddir.is_dir():
        raise DatasetError(f"{root}: Redwood layout needs {'/, '.join(COLOR_DIRS)}/ (one of) and depth/ folders")
    colors, depths = list_images(cdir), list_images(ddir)
    if len(colors) != len(depths) or not colors:
        raise DatasetError(f"{root}: {cdir.name}/ has {len(colors)} image(s) and depth/ has {len(depths)}; "
                           "need the same non-zero count")
    log_path = choose_log(root, trajectory)
    poses = read_log(log_path) if log_path is not None else {}
    beyond = [i for i in poses if i >= len(colors)]
    if beyond:
        raise DatasetError(f"{log_path}: pose for frame {max(beyond)} but the folder has only {len(colors)} frames")
    w, h = image_size(colors[0])
    intr, source, scale = redwood_intrinsics(root, intrinsics, w, h)
    check_intrinsics(intr, colors[0])
    frames = tuple(RgbdFrame(k, round(k * 1e9 / fps), round(k * 1e9 / fps), c, d, poses.get(k))
                   for k, (c, d) in enumerate(zip(colors, depths)))
    return RgbdSequence("redwood", root, frames, intr, source, scale, fps,
                        str(log_path) if log_path is not None else None)
