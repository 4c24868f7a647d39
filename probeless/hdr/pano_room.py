"""Ground truth on real HDR radiance: a box room painted with a real HDR panorama (issue 27's "Measured first" case).

The walls, floor and ceiling of an axis-aligned box (``room`` (x, y, z) [m], floor at z = 0) carry the
panorama seen from the box's centre: a surface point ``p`` has the radiance of the panorama in the direction
``p - centre`` (bilinear; equirectangular, column ``u = (atan2(d_y, d_x) / 2 pi) mod 1`` times the width, row
``v = acos(d_z) / pi`` times the height). The mapping is this module's own and only has to agree with itself:
the cloud and the photo read the same painted room. So every wall point is as bright as the real scene in that
direction, with its real dynamic range (sun, sky, lamps).

* the cloud: the box's surfaces sampled on a ``spacing`` grid (cell centres), the scanner's exposure chosen so
  that ``clip_fraction`` of the points are over-exposed (CIE Y of the exposed radiance > 0.9), ``ldr =
  clip(exposure x radiance, 0, 1)`` (Eq. 1) stored as 8-bit sRGB codes and decoded, like a scanner's;
* the photo: a linear pinhole render (exact ray-box intersection, the same painting) from ``photo_offset`` off
  the centre, aimed at ``photo_target``: ``overexposed`` (the clipped points' centroid), ``brightest`` (the
  brightest point of the painting: the sun or a lamp, so that the photo is mostly the bright part) or ``down``
  (towards the floor, so that the photo sees only a part of the room with little of the bright part), times the
  unknown ``photo_exposure``.

:func:`pano_room_case` returns a :class:`~.synthetic.SyntheticCase`, with the true photo pose.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from probeless.errors import HdrError

ROOM = (5.0, 4.0, 2.6)
OBJECT_HEIGHT = 1.0


def pano_lookup(pano: np.ndarray, d: np.ndarray) -> np.ndarray:
    """(M, 3) float32 radiance of the equirectangular ``pano`` (H, W, 3) in the directions ``d`` (M, 3)
    (module doc), bilinear, wrapping in longitude."""
    h, w = pano.shape[:2]
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    u = (np.arctan2(d[:, 1], d[:, 0]) / (2 * np.pi)) % 1.0 * w - 0.5
    v = np.arccos(np.clip(d[:, 2], -1.0, 1.0)) / np.pi * h - 0.5
    v = np.clip(v, 0.0, h - 1.0)
    x0 = np.floor(u).astype(np.int64)
    y0 = np.floor(v).astype(np.int64)
    fx, fy = (u - x0)[:, None], (v - y0)[:, None]
    x1, y1 = (x0 + 1) % w, np.minimum(y0 + 1, h - 1)
    x0 %= w
    top = pano[y0, x0] * (1 - fx) + pano[y0, x1] * fx
    bot = pano[y1, x0] * (1 - fx) + pano[y1, x1] * fx
    return (top * (1 - fy) + bot * fy).astype(np.float32)


def box_points(room, spacing: float) -> np.ndarray:
    """(N, 3) float32 cell centres of a ``spacing`` grid on the six faces of the box [0, room]."""
    L = np.asarray(room, np.float64)
    out = []
    for axis in range(3):
        a, b = [i for i in range(3) if i != axis]
        ga = (np.arange(int(np.ceil(L[a] / spacing))) + 0.5) * (L[a] / np.ceil(L[a] / spacing))
        gb = (np.arange(int(np.ceil(L[b] / spacing))) + 0.5) * (L[b] / np.ceil(L[b] / spacing))
        A, B = np.meshgrid(ga, gb, indexing="ij")
        for side in (0.0, L[axis]):
            p = np.zeros((A.size, 3))
            p[:, a], p[:, b], p[:, axis] = A.ravel(), B.ravel(), side
            out.append(p)
    return np.concatenate(out).astype(np.float32)


def ray_box(origin: np.ndarray, dirs: np.ndarray, room) -> np.ndarray:
    """(M, 3) exit points of rays from ``origin`` (inside the box [0, room]) along ``dirs`` (M, 3)."""
    L = np.asarray(room, np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_hi = np.where(dirs > 0, (L - origin) / dirs, np.where(dirs < 0, -origin / dirs, np.inf))
    t = t_hi.min(axis=1)
    return origin + dirs * t[:, None]


def pano_room_case(hdri, *, room=ROOM, spacing: float = 0.03, clip_fraction: float = 0.05,
                   photo_offset=(0.8, 0.3, 0.1), photo_target: str = "overexposed", photo_size=(320, 240),
                   photo_fov_deg: float = 90.0, photo_exposure: float = 0.37):
    """The :class:`~.synthetic.SyntheticCase` of the painted box room (module doc); ``hdri``: a .hdr/.exr
    equirectangular panorama; the virtual object at the box's centre, ``OBJECT_HEIGHT`` above the floor."""
    from probeless.color import from_srgb8, to_srgb8
    from probeless.hdr.exposure import luminance
    from probeless.hdr.synthetic import SyntheticCase
    from probeless.hdr.views import camera_looking_at
    from probeless.pano.sources import read_panorama

    path = Path(hdri)
    if not path.is_file():
        raise HdrError(f"{path}: panorama not found")
    if not (0 < clip_fraction < 0.5) or spacing <= 0 or photo_exposure <= 0:
        raise HdrError("pano_room_case: need 0 < clip_fraction < 0.5, spacing > 0, photo_exposure > 0")
    if photo_target not in ("overexposed", "brightest", "down"):
        raise HdrError(f"pano_room_case: photo_target must be overexposed, brightest or down, got {photo_target!r}")
    pano = np.maximum(np.asarray(read_panorama(str(path)), np.float32), 0.0)
    L = np.asarray(room, np.float64)
    centre = L / 2.0
    pts = box_points(L, spacing)
    rad = pano_lookup(pano, pts.astype(np.float64) - centre)
    y = luminance(rad)
    exposure = float(0.9 / np.quantile(y, 1.0 - clip_fraction))
    ldr = from_srgb8(to_srgb8(np.clip(np.float32(exposure) * rad, 0.0, 1.0))).astype(np.float32)  # 8-bit scan
    over = luminance(ldr) > 0.9
    cam = centre + np.asarray(photo_offset, np.float64)
    if photo_target == "overexposed":
        target = pts[over].mean(axis=0)
    elif photo_target == "brightest":
        target = pts[int(np.argmax(y))]
    else:
        target = cam + np.array([0.3, 0.2, -1.0])
    if np.linalg.norm(target - cam) < 1e-3:
        target = cam + np.array([1.0, 0.0, 0.0])
    w, h = int(photo_size[0]), int(photo_size[1])
    K, pose = camera_looking_at(cam, target, photo_fov_deg, (w, h))
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    rays = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], axis=-1).reshape(-1, 3)
    dirs = rays @ pose[:3, :3].T
    hits = ray_box(cam, dirs, L)
    photo = pano_lookup(pano, hits - centre).reshape(h, w, 3) * np.float32(photo_exposure)
    obj = np.array([centre[0], centre[1], OBJECT_HEIGHT])
    # truth in the scanner's units is exposure x radiance: keep radiance as the truth and the exposure with it
    return SyntheticCase(pts, rad.astype(np.float32), ldr, photo.astype(np.float32), obj, exposure,
                         float(photo_exposure), cam, f"{path.stem}_{photo_target}", K, pose)
