"""Microsoft 7-Scenes folders: ``frame-NNNNNN.color.{png,jpg}``, ``frame-NNNNNN.depth.png`` (uint16 mm;
0 and 65535 = invalid, 65535 is read as 0), ``frame-NNNNNN.pose.txt`` (4x4 camera-to-world =
world_from_camera, rotation orthonormalised by SVD) and optionally ``camera-intrinsics.txt`` (3x3 K).

Without ``camera-intrinsics.txt`` the values published with 7-Scenes apply (fx = fy = 585,
cx = 320, cy = 240); the source says so. No stamps: frame N is at N / fps (30 Hz, Kinect).
"""

from __future__ import annotations

import re
from pathlib import Path

from probeless.datasets.base import Intrinsics, RgbdFrame, RgbdSequence, check_intrinsics, image_size, orthonormalize
from probeless.datasets.textfiles import IntrinsicsOverride, read_matrix
from probeless.errors import DatasetError

DEPTH_SCALE = 1000.0
INVALID_DEPTH = 65535  # 7-Scenes' "no measurement" value besides 0
PUBLISHED = (585.0, 585.0, 320.0, 240.0)
_COLOR = re.compile(r"^frame-(\d+)\.color\.(png|jpg|jpeg)$", re.IGNORECASE)


def color_files(root: Path) -> dict[int, Path]:
    """Frame number -> colour image of a 7-Scenes folder."""
    out = {}
    for p in root.iterdir():
        m = _COLOR.match(p.name)
        if m:
            n = int(m.group(1))
            if n in out:
                raise DatasetError(f"{root}: two colour images for frame {n}: {out[n].name}, {p.name}")
            out[n] = p
    return out


def sevenscenes_intrinsics(root: Path, override: IntrinsicsOverride, width: int,
                           height: int) -> tuple[Intrinsics, str]:
    """Intrinsics and their source (rule in the module docstring)."""
    if override.given:
        return override.apply(width, height), "parameters fx, fy, cx, cy"
    path = root / "camera-intrinsics.txt"
    if path.is_file():
        K = read_matrix(path, 3, 3)
        if K[0, 1] != 0 or K[1, 0] != 0 or list(K[2]) != [0, 0, 1] or K[0, 0] <= 0 or K[1, 1] <= 0:
            raise DatasetError(f"{path}: not a pinhole camera matrix [[fx,0,cx],[0,fy,cy],[0,0,1]]")
        return Intrinsics(width, height, K[0, 0], K[1, 1], K[0, 2], K[1, 2]), str(path)
    return Intrinsics(width, height, *PUBLISHED), "default: published 7-Scenes intrinsics (no camera-intrinsics.txt)"


def load_7scenes(root: Path, *, fps: float = 30.0, intrinsics: IntrinsicsOverride | None = None) -> RgbdSequence:
    """Read a 7-Scenes folder (see the module docstring)."""
    root, intrinsics = Path(root), intrinsics or IntrinsicsOverride()
    colors = color_files(root)
    if not colors:
        raise DatasetError(f"{root}: no frame-NNNNNN.color.png/jpg files")
    numbers = sorted(colors)
    depth = {n: root / f"frame-{n:06d}.depth.png" for n in numbers}
    pose = {n: root / f"frame-{n:06d}.pose.txt" for n in numbers}
    missing = [p.name for p in depth.values() if not p.is_file()]
    if missing:
        raise DatasetError(f"{root}: {len(missing)} colour frame(s) without depth, first: {missing[0]} is missing")
    have_pose = [n for n in numbers if pose[n].is_file()]
    if have_pose and len(have_pose) != len(numbers):
        absent = next(pose[n].name for n in numbers if not pose[n].is_file())
        raise DatasetError(f"{root}: {len(have_pose)} pose file(s) for {len(numbers)} frames; {absent} is missing")
    frames = []
    for n in numbers:
        T = orthonormalize(read_matrix(pose[n], 4, 4), str(pose[n])) if have_pose else None
        stamp = round(n * 1e9 / fps)
        frames.append(RgbdFrame(n, stamp, stamp, colors[n], depth[n], T))
    w, h = image_size(frames[0].rgb_path)
    intr, source = sevenscenes_intrinsics(root, intrinsics, w, h)
    check_intrinsics(intr, frames[0].rgb_path)
    return RgbdSequence("7scenes", root, tuple(frames), intr, source, DEPTH_SCALE, fps,
                        f"{root}/frame-NNNNNN.pose.txt" if have_pose else None, depth_invalid=INVALID_DEPTH)
