"""The equirect layout against panoramas whose layout is known independently (issue 27).

A real 360° photo is laid out so that turning right moves right in the image: text written into it reads
left to right in any upright view of it. Mitsuba 3's ``envmap`` documents its lat-long layout (y up,
``u = atan2(x, -z) / 2 pi``, ``v = acos(y) / pi``); turned into our z-up world by a proper rotation it must show
the same view as :func:`probeless.pano.view.view_equirect`. The counter-clockwise layout used before showed
both mirrored.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from probeless.pano import equirect
from probeless.pano.view import view_equirect

TEXT = "FJ7 RK4L"  # glyphs unlike their mirror images


def _upright_camera(forward) -> np.ndarray:
    """4x4 world_from_camera (OpenCV: x right, y down, z forward) looking along ``forward``, world z up."""
    f = np.asarray(forward, np.float64) / np.linalg.norm(forward)
    right = np.cross(f, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    pose = np.eye(4)
    pose[:3, :3] = np.stack([right, np.cross(f, right), f], axis=1)
    return pose


def _put_text(img: np.ndarray, x: int, y: int) -> None:
    cv2.putText(img, TEXT, (x, y), cv2.FONT_HERSHEY_SIMPLEX, 1.0, 255, 2, cv2.LINE_AA)


@pytest.mark.parametrize("col", [600, 1400, 2000])  # the last one runs across the seam
def test_text_in_a_panorama_reads_left_to_right_in_a_view(col):
    w, row = 2048, 512
    (tw, th), base = cv2.getTextSize(TEXT, cv2.FONT_HERSHEY_SIMPLEX, 1.0, 2)
    pano = np.zeros((w // 2, w), np.uint8)
    for x in (col - tw // 2, col - tw // 2 - w):  # a 360° image wraps around
        _put_text(pano, x, row + th // 2)
    template = np.zeros((th + base + 8, tw + 8), np.uint8)
    _put_text(template, 4, th + 4)
    # an upright camera facing the text's centre, one view pixel per panorama pixel there (focal W / 2 pi)
    forward = equirect.pixel_to_direction(np.array(col + 0.5), np.array(row + 0.5), w, w // 2)
    vw, vh = 320, 96
    fov = math.degrees(2 * math.atan(vw / 2 / (w / (2 * math.pi))))
    frame = np.repeat(pano[..., None], 3, axis=2).astype(np.float32) / 255.0
    view = np.ascontiguousarray(view_equirect(frame, _upright_camera(forward), fov, vw, vh)[..., 0])
    # the text's centre is the view's centre: correlate there (within 3 px), as written and mirrored
    t = template.astype(np.float32) / 255.0
    cx, cy = 4 + tw // 2, 4 + th // 2
    x0, y0 = (vw - 1) // 2 - cx - 3, (vh - 1) // 2 - cy - 3
    window = view[y0:y0 + t.shape[0] + 6, x0:x0 + t.shape[1] + 6]
    reads = cv2.matchTemplate(window, t, cv2.TM_CCOEFF_NORMED).max()
    mirrored = cv2.matchTemplate(window, np.ascontiguousarray(t[:, ::-1]), cv2.TM_CCOEFF_NORMED).max()
    assert reads > 0.8 and mirrored < 0.5, (reads, mirrored)


def _blob_panorama(w: int) -> np.ndarray:
    """(W/2, W, 3) float32 smooth panorama: three coloured Gaussian blobs near the equator, dim grey elsewhere."""
    h = w // 2
    v, u = np.mgrid[0:h, 0:w] + 0.5
    img = np.full((h, w, 3), 0.05, np.float32)
    for (cu, cv, colour) in ((0.30, 0.45, (1, 0, 0)), (0.36, 0.50, (0, 1, 0)), (0.33, 0.60, (0, 0, 1))):
        du = (u / w - cu + 0.5) % 1.0 - 0.5
        img += np.exp(-((du * w) ** 2 + (v - cv * h) ** 2) / (2 * (w / 40) ** 2))[..., None] * np.float32(colour)
    return img


def test_views_match_mitsuba_envmap_of_the_same_panorama(tmp_path):
    pytest.importorskip("mitsuba")
    from probeless.pano.sources import write_hdr_image
    from probeless.pano.view import intrinsics
    from probeless.pbgi.reference import _mitsuba, _sensor

    mi = _mitsuba()
    w = 256
    pano = _blob_panorama(w)
    path = tmp_path / "blobs.hdr"
    write_hdr_image(str(path), pano)
    # Mitsuba's envmap frame (documented: y up, u = atan2(x, -z) / 2 pi) in our world: its u = 0 (local -z) at
    # +x, u = 1/4 (local +x) at -y, local +y (v = 0) at +z; the columns are the images of local x, y, z
    to_world = np.eye(4)
    to_world[:3, :3] = np.array([[0, 0, -1], [-1, 0, 0], [0, 1, 0]], np.float64)
    assert np.linalg.det(to_world[:3, :3]) == pytest.approx(1.0)  # a rotation: it cannot undo a reflection
    # face the blobs (u = 0.33, v = 0.5) by Mitsuba's documented layout, not ours
    phi, theta = 2 * np.pi * 0.33, np.pi * 0.5
    local = [np.sin(theta) * np.sin(phi), np.cos(theta), -np.sin(theta) * np.cos(phi)]
    pose = _upright_camera(to_world[:3, :3] @ local)
    vw, vh, fov = 48, 32, 70.0
    K = intrinsics(fov, vw, vh)
    scene = mi.load_dict({"type": "scene", "integrator": {"type": "direct"},
                          "sensor": _sensor(mi, K, pose, vw, vh, 16),
                          "env": {"type": "envmap", "filename": str(path),
                                  "to_world": mi.ScalarTransform4f(to_world.tolist())}})
    ref = np.array(mi.render(scene, spp=16, seed=1), np.float32)[..., :3]
    ours = view_equirect(pano, pose, fov, vw, vh)
    mirrored = view_equirect(np.ascontiguousarray(pano[:, ::-1]), pose, fov, vw, vh)

    def rel(a):
        return float(np.sqrt(((a - ref) ** 2).mean() / (ref ** 2).mean()))

    assert ref.max() > 0.5  # the blobs are in view
    assert rel(ours) < 0.05 and rel(mirrored) > 0.3, (rel(ours), rel(mirrored))
