"""Which RGB-D format a folder holds, and one entry point that opens any of them."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from probeless.datasets.base import RgbdSequence
from probeless.datasets.textfiles import IntrinsicsOverride
from probeless.errors import DatasetError

FORMATS = ("tum", "redwood", "7scenes")
LOOKED_FOR = ("TUM (rgb.txt and depth.txt)", "7-Scenes (frame-NNNNNN.color.png/jpg files)",
              "Redwood/Open3D (image/ or color/ or rgb/ folder, and depth/ folder)")


def detect_format(path: str | Path) -> str:
    """``tum``, ``7scenes`` or ``redwood``; DatasetError for a missing folder or an unknown layout."""
    from probeless.datasets.redwood import color_dir
    from probeless.datasets.sevenscenes import _COLOR

    root = Path(path)
    if not root.is_dir():
        raise DatasetError(f"{root}: no such dataset folder")
    if (root / "rgb.txt").is_file() and (root / "depth.txt").is_file():
        return "tum"
    if any(_COLOR.match(p.name) for p in root.iterdir()):
        return "7scenes"
    if color_dir(root) is not None and (root / "depth").is_dir():
        return "redwood"
    raise DatasetError(f"{root}: unknown dataset format; looked for {'; '.join(LOOKED_FOR)}")


def open_rgbd(path: str | Path, format: str = "auto", *, max_dt_s: float = 0.02, fps: float = 30.0,
              intrinsics: IntrinsicsOverride | None = None, depth_scale: float = 0.0,
              trajectory: str | None = None) -> RgbdSequence:
    """Read an RGB-D folder of ``format`` (``auto`` = :func:`detect_format`).

    ``max_dt_s`` applies to TUM association, ``fps`` to formats without stamps, ``trajectory`` to
    Redwood; ``depth_scale`` > 0 replaces the format's depth units per metre.
    """
    from probeless.datasets.redwood import load_redwood
    from probeless.datasets.sevenscenes import load_7scenes
    from probeless.datasets.tum import load_tum

    intrinsics = intrinsics or IntrinsicsOverride()
    fmt = detect_format(path) if format == "auto" else format
    if fmt not in FORMATS:
        raise DatasetError(f"unknown dataset format {format!r}; expected auto or one of {FORMATS}")
    if not Path(path).is_dir():
        raise DatasetError(f"{path}: no such dataset folder")
    if fps <= 0:
        raise DatasetError(f"fps must be > 0, got {fps}")
    if fmt == "tum":
        seq = load_tum(Path(path), max_dt_s=max_dt_s, intrinsics=intrinsics)
    elif fmt == "redwood":
        seq = load_redwood(Path(path), fps=fps, intrinsics=intrinsics, trajectory=trajectory)
    else:
        seq = load_7scenes(Path(path), fps=fps, intrinsics=intrinsics)
    return dataclasses.replace(seq, depth_scale=depth_scale) if depth_scale > 0 else seq


def select(seq: RgbdSequence, start: int = 0, max_frames: int = 0) -> RgbdSequence:
    """The frames ``start`` .. ``start + max_frames`` (0 = to the end) of ``seq``."""
    if start < 0 or max_frames < 0:
        raise DatasetError(f"start ({start}) and max_frames ({max_frames}) must be >= 0")
    if start >= len(seq.frames):
        raise DatasetError(f"{seq.root}: start={start} but the sequence has {len(seq.frames)} frames")
    end = start + max_frames if max_frames else None
    return dataclasses.replace(seq, frames=seq.frames[start:end])


def describe(seq: RgbdSequence) -> dict:
    """The facts ``probeless dataset info`` prints, as a JSON-ready dict."""
    i = seq.intrinsics
    stamps = [f.stamp_ns for f in seq.frames]
    return {
        "path": str(seq.root), "format": seq.format, "frames": len(seq.frames),
        "duration_s": (stamps[-1] - stamps[0]) / 1e9, "rate_hz": round(seq.rate_hz, 3),
        "width": i.width, "height": i.height, "fx": i.fx, "fy": i.fy, "cx": i.cx, "cy": i.cy,
        "intrinsics_source": seq.intrinsics_source, "depth_scale": seq.depth_scale,
        "has_ground_truth": seq.has_poses, "frames_with_pose": sum(f.pose is not None for f in seq.frames),
        "pose_source": seq.pose_source, "notes": list(seq.notes),
    }
