"""Regenerate the procedural textures shipped in launch/scenes/textures/ (our own work, CC0).

Run: python tools/make_textures.py [OUT_DIR]
"""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np


def plaster(size: int = 256, seed: int = 3) -> np.ndarray:
    """A tileable off-white plaster texture (sRGB uint8, BGR for cv2.imwrite)."""
    rng = np.random.default_rng(seed)
    img = np.zeros((size, size), np.float32)
    for octave, weight in ((8, 0.5), (32, 0.3), (128, 0.2)):
        noise = rng.standard_normal((octave, octave)).astype(np.float32)
        tiled = np.tile(noise, (3, 3))  # resize a 3x3 tiling and keep the centre: seamless wrap
        big = cv2.resize(tiled, (3 * size, 3 * size), interpolation=cv2.INTER_CUBIC)
        img += weight * big[size:2 * size, size:2 * size]
    img = (img - img.mean()) / (img.std() + 1e-6)
    base = np.array([200, 206, 212], np.float32)  # BGR: warm off-white
    out = base[None, None, :] + 9.0 * img[..., None]
    return np.clip(out, 0, 255).astype(np.uint8)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    out = Path(argv[0] if argv else "launch/scenes/textures")
    out.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(out / "plaster.png"), plaster())
    print(f"wrote {out / 'plaster.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
