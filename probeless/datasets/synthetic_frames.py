"""Synthetic camera frames, deterministic: a random image of a given size, and moving RGB, depth and
fisheye frames that are realistic and not trivially compressible. The benchmark nodes
(``probeless.nodes.bench``) publish them and the benchmarks' raw sides (``probeless.bench``) send or
write the very same bytes.
"""

from __future__ import annotations

import numpy as np

from probeless.messages.header import Header
from probeless.messages.sensor import DepthImage, Image

DEPTH_SCALE = 1000.0


def bench_image(width: int, height: int) -> np.ndarray:
    """A deterministic, non-constant rgb8 image (content does not matter, pages must be real)."""
    rng = np.random.default_rng(width * 7919 + height)
    return rng.integers(0, 256, (height, width, 3), dtype=np.uint8)


def _smooth(rng: np.random.Generator, h: int, w: int, cells: int = 8) -> np.ndarray:
    """A smooth random field in [0, 1] (bilinear upsampling of a coarse grid), float32 [h, w]."""
    coarse = rng.random((cells + 1, cells + 1)).astype(np.float32)
    ys = np.linspace(0, cells, h, dtype=np.float32)
    xs = np.linspace(0, cells, w, dtype=np.float32)
    y0 = np.minimum(ys.astype(int), cells - 1)
    x0 = np.minimum(xs.astype(int), cells - 1)
    fy, fx = (ys - y0)[:, None], (xs - x0)[None, :]
    a, b = coarse[y0][:, x0], coarse[y0][:, x0 + 1]
    c, d = coarse[y0 + 1][:, x0], coarse[y0 + 1][:, x0 + 1]
    return (a * (1 - fy) * (1 - fx) + b * (1 - fy) * fx + c * fy * (1 - fx) + d * fy * fx).astype(np.float32)


def _rgb_base(rng: np.random.Generator, h: int, w: int, noise: float = 4.0) -> np.ndarray:
    img = np.stack([_smooth(rng, h, w, c) for c in (4, 6, 9)], axis=2) * 200.0 + 20.0
    yy, xx = np.mgrid[0:h, 0:w]
    img[((xx // 40 + yy // 40) % 2 == 0) & (yy > h // 2)] *= 0.6  # some texture (a tiled floor)
    img += rng.normal(0.0, noise, img.shape).astype(np.float32)      # sensor noise
    return np.clip(img, 0, 255).astype(np.uint8)


def camera_frames(kind: str, width: int, height: int, variants: int, seed: int = 7) -> list[np.ndarray]:
    """``variants`` frames of one stream, each the base frame shifted further (a moving scene).

    ``kind``: ``rgb`` (rgb8), ``depth`` (uint16 mm: 0.5-4 m, 3 mm noise, ~2% holes) or ``fisheye``
    (rgb8 with the black border outside the image circle). Deterministic for a given seed.
    """
    rng = np.random.default_rng(seed * 1000 + {"rgb": 1, "depth": 2, "fisheye": 3}[kind])
    if kind == "depth":
        z = 500.0 + 3500.0 * _smooth(rng, height, width, 5) + rng.normal(0.0, 3.0, (height, width))
        base = np.clip(z, 0, 65535).astype(np.uint16)
        base[rng.random((height, width)) < 0.02] = 0
    else:
        base = _rgb_base(rng, height, width)
        if kind == "fisheye":
            yy, xx = np.mgrid[0:height, 0:width]
            r = min(width, height) / 2
            base[(yy - height / 2 + 0.5) ** 2 + (xx - width / 2 + 0.5) ** 2 > r * r] = 0
    step = max(1, width // 80)
    return [np.ascontiguousarray(np.roll(base, i * step, axis=1)) for i in range(variants)]


def camera_message(kind: str, data: np.ndarray, stamp_ns: int):
    """The message CameraSource publishes for one frame of stream ``kind``."""
    if kind == "depth":
        return DepthImage(Header(stamp_ns, "depth"), data, DEPTH_SCALE)
    return Image(Header(stamp_ns, kind), data, "rgb8")
