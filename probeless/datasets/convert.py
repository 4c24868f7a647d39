"""Write any readable RGB-D folder as a TUM RGB-D folder.

Output: ``rgb/<stamp>.<ext>`` (the colour files copied byte for byte), ``depth/<stamp>.png``
(uint16 rescaled to TUM's 5000 units per metre, exact for millimetre sources), ``rgb.txt`` and
``depth.txt`` (``timestamp filename``), ``groundtruth.txt`` (``timestamp tx ty tz qx qy qz qw``,
world_from_camera, only frames with a pose) and ``intrinsics.json`` (Open3D format). Stamps are
written in seconds with 6 decimals, as TUM does.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import cv2
import numpy as np

from probeless.datasets.base import RgbdSequence, read_depth
from probeless.datasets.textfiles import write_open3d_intrinsics
from probeless.datasets.tum import DEPTH_SCALE
from probeless.errors import DatasetError
from probeless.geom.rotation import quat_from_matrix


def tum_stamp(stamp_ns: int) -> str:
    """Seconds with 6 decimals, rounded to the microsecond, from integer ns (no float rounding)."""
    us = (stamp_ns + 500) // 1000
    return f"{us // 1_000_000}.{us % 1_000_000:06d}"


def rescale_depth(depth: np.ndarray, scale: float, path: Path) -> np.ndarray:
    """uint16 depth from ``scale`` to TUM's 5000 units per metre; DatasetError when it would overflow."""
    if scale == DEPTH_SCALE:
        return depth
    out = np.rint(depth.astype(np.float64) * (DEPTH_SCALE / scale))
    if out.max(initial=0) > np.iinfo(np.uint16).max:
        raise DatasetError(f"{path}: depth {depth.max() / scale:.2f} m does not fit uint16 at 5000 units per metre")
    return out.astype(np.uint16)


def _prepare(dst: Path, force: bool) -> None:
    if dst.exists() and any(dst.iterdir()) and not force:
        raise DatasetError(f"{dst}: output folder exists and is not empty (use --force to write into it)")
    for sub in ("rgb", "depth"):
        (dst / sub).mkdir(parents=True, exist_ok=True)


def convert_to_tum(seq: RgbdSequence, dst: str | Path, *, force: bool = False) -> dict:
    """Write ``seq`` as a TUM folder at ``dst``; return a summary (frames, poses, paths)."""
    dst = Path(dst)
    _prepare(dst, force)
    head = f"# converted by probeless from {seq.format} folder {seq.root}\n"
    rgb_lines = [head, "# color images\n", "# timestamp filename\n"]
    depth_lines = [head, "# depth maps\n", "# timestamp filename\n"]
    gt_lines = [head, "# ground truth trajectory (world_from_camera)\n", "# timestamp tx ty tz qx qy qz qw\n"]
    written: set[str] = set()
    for f in seq.frames:
        s, ds = tum_stamp(f.stamp_ns), tum_stamp(f.depth_stamp_ns)
        if s in written or "d" + ds in written:
            raise DatasetError(f"{f.rgb_path}: two frames share the stamp {s if s in written else ds} "
                               "at microsecond precision")
        written.update((s, "d" + ds))
        rgb_name = f"rgb/{s}{f.rgb_path.suffix.lower()}"
        if not f.rgb_path.is_file():
            raise DatasetError(f"{f.rgb_path}: image file is missing")
        shutil.copyfile(f.rgb_path, dst / rgb_name)
        depth = rescale_depth(read_depth(f.depth_path, seq.depth_invalid), seq.depth_scale, f.depth_path)
        if not cv2.imwrite(str(dst / f"depth/{ds}.png"), depth):
            raise DatasetError(f"{dst / f'depth/{ds}.png'}: cannot write")
        rgb_lines.append(f"{s} {rgb_name}\n")
        depth_lines.append(f"{ds} depth/{ds}.png\n")
        if f.pose is not None:
            t, q = f.pose[:3, 3], quat_from_matrix(f.pose[:3, :3])
            gt_lines.append(f"{s} " + " ".join(f"{v:.9f}" for v in (*t, *q)) + "\n")
    (dst / "rgb.txt").write_text("".join(rgb_lines))
    (dst / "depth.txt").write_text("".join(depth_lines))
    poses = len(gt_lines) - 3
    if poses:
        (dst / "groundtruth.txt").write_text("".join(gt_lines))
    write_open3d_intrinsics(dst / "intrinsics.json", seq.intrinsics)
    return {"source": str(seq.root), "source_format": seq.format, "destination": str(dst),
            "frames": len(seq.frames), "poses": poses}
