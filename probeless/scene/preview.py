"""Pictures of a scene: cubemap nets and the contact sheet of ``probeless scene preview``."""

from __future__ import annotations

import cv2
import numpy as np

from probeless.geom.cube import sample_cubemap

# Middle row of the net, left to right: views turning right (clockwise seen from above), z up.
NET_FORWARDS = ((1, 0, 0), (0, -1, 0), (-1, 0, 0), (0, 1, 0))
NET_LABELS = ("+X", "-Y", "-X", "+Y")


def _tile(forward, right, up, size: int) -> np.ndarray:
    a = (np.arange(size) + 0.5) / size * 2 - 1
    aa, bb = np.meshgrid(a, a)
    f, r, u = (np.asarray(v, np.float64) for v in (forward, right, up))
    return f + aa[..., None] * r - bb[..., None] * u


def cube_net(faces: np.ndarray, tile: int | None = None) -> np.ndarray:
    """A horizontal-cross net (3 x 4 tiles) of a cubemap as seen from inside, z up.

    The middle row shows the four horizontal views (+X, -Y, -X, +Y: turning right), the ceiling (+Z)
    sits above the second tile and the floor (-Z) below it; empty tiles are black.
    """
    size = tile or faces.shape[1]
    up = np.array([0.0, 0.0, 1.0])
    net = np.zeros((3 * size, 4 * size, faces.shape[3]), faces.dtype)
    for k, fwd in enumerate(NET_FORWARDS):
        f = np.asarray(fwd, np.float64)
        right = np.cross(f, up)
        net[size:2 * size, k * size:(k + 1) * size] = sample_cubemap(faces, _tile(f, right, up, size))
        if k == 1:
            net[:size, size:2 * size] = sample_cubemap(faces, _tile(up, right, -f, size))
            net[2 * size:, size:2 * size] = sample_cubemap(faces, _tile(-up, right, f, size))
    return net


def colorize_depth(depth_mm: np.ndarray, max_m: float) -> np.ndarray:
    """RGB uint8 turbo colour map of a uint16 mm depth image; invalid (0) pixels black."""
    scaled = np.clip(depth_mm.astype(np.float32) / (max_m * 1000.0) * 255.0, 0, 255).astype(np.uint8)
    rgb = cv2.applyColorMap(scaled, cv2.COLORMAP_TURBO)[:, :, ::-1]
    return np.where(depth_mm[..., None] > 0, rgb, 0).astype(np.uint8)


def _fit(img: np.ndarray, width: int, height: int) -> np.ndarray:
    scale = min(width / img.shape[1], height / img.shape[0])
    size = (max(1, int(img.shape[1] * scale)), max(1, int(img.shape[0] * scale)))
    resized = cv2.resize(img, size, interpolation=cv2.INTER_AREA)
    out = np.zeros((height, width, 3), np.uint8)
    y, x = (height - size[1]) // 2, (width - size[0]) // 2
    out[y:y + size[1], x:x + size[0]] = resized
    return out


def contact_sheet(panels: list[tuple[str, np.ndarray]], cell: tuple[int, int] = (640, 480),
                  columns: int = 2) -> np.ndarray:
    """RGB uint8 grid of labelled panels, each fitted into a ``cell`` (width, height)."""
    w, h = cell
    rows = (len(panels) + columns - 1) // columns
    sheet = np.full((rows * (h + 28), columns * w, 3), 24, np.uint8)
    for i, (label, img) in enumerate(panels):
        r, c = divmod(i, columns)
        y0, x0 = r * (h + 28), c * w
        sheet[y0 + 28:y0 + 28 + h, x0:x0 + w] = _fit(img, w, h)
        cv2.putText(sheet, label, (x0 + 8, y0 + 20), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (235, 235, 235), 1, cv2.LINE_AA)
    return sheet


def write_png(path, rgb: np.ndarray) -> None:
    """Write an RGB uint8 image as PNG (OSError with the path on failure)."""
    if not cv2.imwrite(str(path), np.ascontiguousarray(rgb[:, :, ::-1])):
        raise OSError(f"cannot write {path}")
