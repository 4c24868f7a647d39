"""TUM RGB-D folders: ``rgb.txt``, ``depth.txt`` (``timestamp filename``), optional ``groundtruth.txt``
(``timestamp tx ty tz qx qy qz qw``, world_from_camera), depth scale 5000.

Association (as TUM's ``associate.py`` intends): each colour frame takes its nearest depth frame
within ``max_dt_s``; a depth frame claimed by several colour frames goes to the nearest one (ties:
the earlier). Colour frames left without depth are dropped and counted in the sequence's notes.
Poses are interpolated at the colour stamp (linear translation, slerp rotation) between the
ground-truth samples on either side when both lie within ``max_dt_s``; otherwise the frame has none.

Intrinsics: ``intrinsics.json`` (Open3D format, written by ``probeless dataset convert``), else the
published values of the Freiburg camera named in the folder name (``freiburg1/2/3``), else the
user's fx, fy, cx, cy; nothing else is guessed.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from probeless.datasets.base import Intrinsics, RgbdFrame, RgbdSequence, check_intrinsics, image_size, median_rate
from probeless.datasets.textfiles import (
    IntrinsicsOverride,
    data_lines,
    find_intrinsics_json,
    parse_floats,
    parse_stamp_ns,
    read_open3d_intrinsics,
)
from probeless.errors import DatasetError
from probeless.geom.rotation import matrix_from_quat, quat_from_matrix, slerp, transform_from

DEPTH_SCALE = 5000.0
# https://cvg.cit.tum.de/data/datasets/rgbd-dataset/file_formats (colour camera, 640x480)
FREIBURG_INTRINSICS = {
    "freiburg1": (517.3, 516.5, 318.6, 255.3),
    "freiburg2": (520.9, 521.0, 325.1, 249.7),
    "freiburg3": (535.4, 539.2, 320.1, 247.6),
}


def read_list(path: Path) -> list[tuple[int, str]]:
    """``timestamp filename`` lines -> [(stamp_ns, filename)] in stamp order."""
    items = []
    for n, tokens in data_lines(path):
        if len(tokens) != 2:
            raise DatasetError(f"{path}:{n}: expected 'timestamp filename', got {' '.join(tokens)!r}")
        items.append((parse_stamp_ns(tokens[0], path, n), tokens[1]))
    return sorted(items)


def read_groundtruth(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(stamps_ns int64 (N,), poses (N, 4, 4) world_from_camera) of a ``groundtruth.txt``."""
    stamps, poses = [], []
    for n, tokens in data_lines(path):
        if len(tokens) != 8:
            raise DatasetError(f"{path}:{n}: expected 'timestamp tx ty tz qx qy qz qw', got {' '.join(tokens)!r}")
        stamp = parse_stamp_ns(tokens[0], path, n)
        v = parse_floats(tokens[1:], path, n)
        q = np.array(v[3:])
        if abs(np.linalg.norm(q) - 1.0) > 1e-2:
            raise DatasetError(f"{path}:{n}: quaternion {v[3:]} is not unit length")
        stamps.append(stamp)
        poses.append(transform_from(matrix_from_quat(q), np.array(v[:3])))
    order = np.argsort(np.asarray(stamps, dtype=np.int64), kind="stable")
    return np.asarray(stamps, dtype=np.int64)[order], np.asarray(poses).reshape(-1, 4, 4)[order]


def associate(a_ns: np.ndarray, b_ns: np.ndarray, max_dt_ns: int) -> list[tuple[int, int]]:
    """Pairs (i, j), i ascending: a[i] with its nearest b[j] within max_dt_ns, each j used once (nearest a wins)."""
    a_ns, b_ns = np.asarray(a_ns, dtype=np.int64), np.asarray(b_ns, dtype=np.int64)
    if len(b_ns) == 0:
        return []
    hi = np.clip(np.searchsorted(b_ns, a_ns), 1, len(b_ns) - 1) if len(b_ns) > 1 else np.zeros(len(a_ns), int)
    lo = np.maximum(hi - 1, 0)
    pick = np.where(np.abs(b_ns[lo] - a_ns) <= np.abs(b_ns[hi] - a_ns), lo, hi)
    dt = np.abs(b_ns[pick] - a_ns)
    best: dict[int, int] = {}
    for i in np.flatnonzero(dt <= max_dt_ns):
        j = int(pick[i])
        if j not in best or dt[i] < dt[best[j]]:
            best[j] = int(i)
    return sorted((i, j) for j, i in best.items())


def slerp_pose(T0: np.ndarray, T1: np.ndarray, s: float) -> np.ndarray:
    """Pose a fraction ``s`` of the way from T0 to T1 (linear translation, quaternion slerp rotation)."""
    q = slerp(quat_from_matrix(T0[:3, :3]), quat_from_matrix(T1[:3, :3]), s)
    return transform_from(matrix_from_quat(q), (1 - s) * T0[:3, 3] + s * T1[:3, 3])


def pose_at(stamp_ns: int, gt_ns: np.ndarray, gt_poses: np.ndarray, max_dt_ns: int) -> np.ndarray | None:
    """Ground-truth pose at ``stamp_ns``: an exact sample, or interpolated between two within max_dt_ns."""
    j = int(np.searchsorted(gt_ns, stamp_ns))
    if j < len(gt_ns) and gt_ns[j] == stamp_ns:
        return gt_poses[j]
    if j == 0 or j == len(gt_ns) or stamp_ns - gt_ns[j - 1] > max_dt_ns or gt_ns[j] - stamp_ns > max_dt_ns:
        return None
    s = (stamp_ns - gt_ns[j - 1]) / (gt_ns[j] - gt_ns[j - 1])
    return slerp_pose(gt_poses[j - 1], gt_poses[j], s)


def tum_intrinsics(root: Path, first_rgb: Path, override: IntrinsicsOverride) -> tuple[Intrinsics, str]:
    """Intrinsics and their source, by the rule in the module docstring."""
    w, h = image_size(first_rgb)
    if override.given:
        return override.apply(w, h), "parameters fx, fy, cx, cy"
    js = find_intrinsics_json(root)
    if js is not None:
        return read_open3d_intrinsics(js)[0], str(js)
    match = re.search(r"(?<![a-z])(?:freiburg|fr)([123])(?!\d)", root.resolve().name.lower())
    if match:
        key = f"freiburg{match.group(1)}"
        fx, fy, cx, cy = FREIBURG_INTRINSICS[key]
        return Intrinsics(w, h, fx, fy, cx, cy), f"published TUM {key} intrinsics (folder name)"
    raise DatasetError(f"{root}: TUM folder without intrinsics.json and no freiburg1/2/3 in its name; "
                       "pass fx, fy, cx, cy")


def load_tum(root: Path, *, max_dt_s: float = 0.02, intrinsics: IntrinsicsOverride | None = None) -> RgbdSequence:
    """Read a TUM RGB-D folder (see the module docstring)."""
    root, intrinsics = Path(root), intrinsics or IntrinsicsOverride()
    rgb, depth = read_list(root / "rgb.txt"), read_list(root / "depth.txt")
    if not rgb or not depth:
        raise DatasetError(f"{root}: rgb.txt has {len(rgb)} and depth.txt {len(depth)} entries; need both non-empty")
    max_dt_ns = round(max_dt_s * 1e9)
    pairs = associate(np.array([s for s, _ in rgb]), np.array([s for s, _ in depth]), max_dt_ns)
    if not pairs:
        raise DatasetError(f"{root}: no colour frame has a depth frame within max_dt_s={max_dt_s}")
    gt_file = root / "groundtruth.txt"
    gt = read_groundtruth(gt_file) if gt_file.is_file() else None
    frames = []
    for i, j in pairs:
        pose = pose_at(rgb[i][0], gt[0], gt[1], max_dt_ns) if gt is not None else None
        frames.append(RgbdFrame(i, rgb[i][0], depth[j][0], root / rgb[i][1], root / depth[j][1], pose))
    intr, source = tum_intrinsics(root, frames[0].rgb_path, intrinsics)
    check_intrinsics(intr, frames[0].rgb_path)
    notes = (f"{len(rgb) - len(pairs)} of {len(rgb)} colour frame(s) without depth within {max_dt_s} s dropped",) \
        if len(pairs) < len(rgb) else ()
    return RgbdSequence("tum", root, tuple(frames), intr, source, DEPTH_SCALE,
                        median_rate([f.stamp_ns for f in frames]), str(gt_file) if gt is not None else None, notes)
