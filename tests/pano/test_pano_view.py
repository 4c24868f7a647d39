"""Perspective views of 360° frames, head path, stereo eyes and display encoding (probeless.pano.view/composite)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from probeless.color import from_srgb8
from probeless.errors import ProbelessError
from probeless.pano.composite import composite_view, encode_display
from probeless.pano.equirect import direction_to_pixel
from probeless.pano.itmo import gamma_decode
from probeless.pano.view import head_pose, intrinsics, look_rotation, side_by_side, stereo_eye_poses, view_equirect


def pixel_rays(K, rotation, width, height):
    """World rays of every pixel centre, written out independently of view.view_rays."""
    out = np.empty((height, width, 3))
    for v in range(height):
        for u in range(width):
            cam = np.array([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], 1.0])
            out[v, u] = rotation @ cam
    return out


def coordinate_frame(width: int) -> np.ndarray:
    """An equirect whose pixel (r, c) holds its own centre (c + 0.5, r + 0.5): bilinear lookups return u, v."""
    h = width // 2
    v, u = np.mgrid[0:h, 0:width] + 0.5
    return np.stack([u, v, np.zeros_like(u)], axis=-1).astype(np.float32)


def test_intrinsics_span_the_horizontal_field_of_view():
    K = intrinsics(70.0, 200, 100)
    left = np.linalg.inv(K) @ [-0.5, 49.5, 1.0]   # outer edges of the first and last column
    right = np.linalg.inv(K) @ [199.5, 49.5, 1.0]
    cos = left @ right / np.linalg.norm(left) / np.linalg.norm(right)
    assert math.degrees(math.acos(cos)) == pytest.approx(70.0, abs=1e-9)
    assert K[0, 0] == K[1, 1]
    with pytest.raises(ProbelessError):
        intrinsics(180.0, 10, 10)


@pytest.mark.parametrize("yaw,pitch", [(0.0, 0.0), (37.0, -20.0), (200.0, 45.0)])
def test_look_rotation_is_an_opencv_camera_looking_along_yaw_and_pitch(yaw, pitch):
    R = look_rotation(yaw, pitch)
    y, p = math.radians(yaw), math.radians(pitch)
    np.testing.assert_allclose(R[:, 2], [math.cos(p) * math.cos(y), math.cos(p) * math.sin(y), math.sin(p)],
                               atol=1e-12)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    assert abs(R[2, 0]) < 1e-12            # camera x (right) stays horizontal: no roll
    assert R[2, 1] < 0                     # camera y points down
    # the right of a camera looking along +x (z up) is -y
    np.testing.assert_allclose(look_rotation(0.0, 0.0)[:, 0], [0, -1, 0], atol=1e-12)


def test_head_path_sweeps_yaw_at_its_rate_and_nods():
    kw = dict(yaw0_deg=10.0, yaw_deg_per_s=20.0, pitch_deg=-5.0, pitch_amp_deg=3.0, pitch_period_s=4.0)
    for t in (0.0, 0.5, 1.0, 2.5):
        f = head_pose(t, **kw)[:3, 2]
        yaw = math.degrees(math.atan2(f[1], f[0]))
        pitch = math.degrees(math.asin(f[2]))
        assert yaw == pytest.approx(10.0 + 20.0 * t)
        assert pitch == pytest.approx(-5.0 + 3.0 * math.sin(2 * math.pi * t / 4.0))
    np.testing.assert_allclose(head_pose(1.0, position=(1, 2, 3))[:3, 3], [1, 2, 3])


def test_stereo_eyes_are_ipd_apart_along_the_head_x_axis():
    head = head_pose(0.7, yaw0_deg=33.0, pitch_deg=10.0, position=(0.5, -1.0, 1.6))
    left, right = stereo_eye_poses(head, 0.064)
    np.testing.assert_allclose(right[:3, 3] - left[:3, 3], 0.064 * head[:3, 0], atol=1e-12)
    np.testing.assert_allclose((right[:3, 3] + left[:3, 3]) / 2, head[:3, 3], atol=1e-12)
    np.testing.assert_allclose(left[:3, :3], head[:3, :3])
    np.testing.assert_allclose(right[:3, :3], head[:3, :3])


def test_side_by_side_puts_the_left_eye_left():
    a, b = np.zeros((4, 3, 3), np.uint8), np.full((4, 3, 3), 9, np.uint8)
    sbs = side_by_side(a, b)
    assert sbs.shape == (4, 6, 3) and (sbs[:, :3] == 0).all() and (sbs[:, 3:] == 9).all()
    with pytest.raises(ProbelessError):
        side_by_side(a, b[:, :2])


@pytest.mark.parametrize("yaw,pitch", [(100.0, 10.0), (250.0, -30.0)])
def test_view_equirect_samples_the_frame_at_direction_to_pixel(yaw, pitch):
    frame = coordinate_frame(256)
    w, h = 48, 36
    pose = np.eye(4)
    pose[:3, :3] = look_rotation(yaw, pitch)
    view = view_equirect(frame, pose, 60.0, w, h)
    u, v = direction_to_pixel(pixel_rays(intrinsics(60.0, w, h), pose[:3, :3], w, h), 256, 128)
    inner = (u > 1) & (u < 255) & (v > 1) & (v < 127)   # away from the seam and the poles
    assert inner.mean() > 0.9
    np.testing.assert_allclose(view[..., 0][inner], u[inner], atol=0.02)
    np.testing.assert_allclose(view[..., 1][inner], v[inner], atol=0.02)


def test_view_equirect_wraps_across_the_seam_and_ignores_translation():
    # a frame smooth in longitude (cos phi, sin phi): any seam artefact shows as a jump
    w = 128
    phi = (np.arange(w) + 0.5) * 2 * np.pi / w
    frame = np.zeros((w // 2, w, 3), np.float32)
    frame[..., 0], frame[..., 1] = np.cos(phi), np.sin(phi)
    pose = np.eye(4)
    pose[:3, :3] = look_rotation(0.0, 0.0)     # looking at phi = 0, the seam in the middle of the view
    view = view_equirect(frame, pose, 90.0, 64, 32)
    rays = pixel_rays(intrinsics(90.0, 64, 32), pose[:3, :3], 64, 32)
    ray_phi = np.arctan2(-rays[..., 1], rays[..., 0])  # the column longitude: from +x towards -y (pano.equirect)
    # linear interpolation over a texel step d errs by <= d^2 / 8; cv2 rounds positions to 1/32 texel
    # (<= d / 64 here); reading a clamped edge column instead of wrapping would err by up to d
    d = 2 * math.pi / w
    tol = d * d / 8 + d / 64 + 1e-4
    np.testing.assert_allclose(view[..., 0], np.cos(ray_phi), atol=tol)
    np.testing.assert_allclose(view[..., 1], np.sin(ray_phi), atol=tol)
    moved = pose.copy()
    moved[:3, 3] = [5.0, -3.0, 2.0]
    np.testing.assert_array_equal(view_equirect(frame, moved, 90.0, 64, 32), view)


def test_view_equirect_keeps_uint8_frames_uint8():
    rng = np.random.default_rng(1)
    frame = rng.integers(0, 256, (32, 64, 3), dtype=np.uint8)
    out = view_equirect(frame, np.eye(4), 50.0, 20, 10)
    assert out.dtype == np.uint8 and out.shape == (10, 20, 3)
    with pytest.raises(ProbelessError):
        view_equirect(frame[:, :40], np.eye(4), 50.0, 20, 10)


def test_display_encodings_invert_the_decodings_the_itmos_use():
    codes = np.arange(256, dtype=np.uint8)
    np.testing.assert_array_equal(encode_display(codes / 255.0, "direct"), codes)
    np.testing.assert_array_equal(encode_display(gamma_decode(codes / 255.0), "gamma"), codes)
    np.testing.assert_array_equal(encode_display(from_srgb8(codes), "srgb"), codes)
    np.testing.assert_array_equal(encode_display(np.array([-1.0, 7.0]), "direct"), [0, 255])
    with pytest.raises(ProbelessError):
        encode_display(codes, "log")


def test_composite_view_replaces_only_masked_pixels_with_the_exposed_render():
    rng = np.random.default_rng(2)
    bg = rng.integers(0, 256, (6, 8, 3), dtype=np.uint8)
    color = rng.random((6, 8, 3)).astype(np.float32) * 2
    mask = rng.random((6, 8)) < 0.4
    out = composite_view(bg, color, mask, exposure=0.5, display="direct")
    np.testing.assert_array_equal(out[~mask], bg[~mask])
    np.testing.assert_array_equal(out[mask], np.rint(np.clip(color[mask] * 0.5, 0, 1) * 255).astype(np.uint8))
    with pytest.raises(ProbelessError):
        composite_view(bg, color, mask[:, :4])
