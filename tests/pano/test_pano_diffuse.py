"""Equirect helpers and diffuse radiance maps against analytic integrals and the brute-force sum."""

import numpy as np
import pytest
from scipy import integrate

from probeless.errors import ProbelessError
from probeless.pano import diffuse, equirect


@pytest.mark.parametrize("w,h", [(8, 4), (64, 32), (1280, 640)])
def test_solid_angles_sum_to_4pi(w, h):
    assert equirect.solid_angles(w, h).sum() == pytest.approx(4 * np.pi, rel=1e-12)


def test_row_solid_angle_matches_numeric_integral():
    w, h = 16, 8
    t0, t1 = 2 * np.pi / h, 3 * np.pi / h  # row 2
    ref, _ = integrate.dblquad(lambda t, p: np.sin(t), 0, 2 * np.pi / w, t0, t1)
    assert equirect.row_solid_angles(w, h)[2] == pytest.approx(ref, rel=1e-9)


def test_direction_convention_and_round_trip():
    w, h = 64, 32
    d = equirect.pixel_to_direction(np.array([0.0, w / 4, w / 2, 5.0]), np.array([h / 2, h / 2, h / 2, 0.0]), w, h)
    np.testing.assert_allclose(d[:3], [[1, 0, 0], [0, -1, 0], [-1, 0, 0]], atol=1e-12)  # clockwise from above
    np.testing.assert_allclose(d[3], [0, 0, 1], atol=1e-12)  # row 0 = zenith
    dirs = equirect.pixel_directions(w, h)
    u, v = equirect.direction_to_pixel(dirs, w, h)
    vv, uu = np.mgrid[0:h, 0:w] + 0.5
    np.testing.assert_allclose(u, uu, atol=1e-9)
    np.testing.assert_allclose(v, vv, atol=1e-9)


def smooth_env(w, h, sun=0.0):
    d = equirect.pixel_directions(w, h)
    s = np.array([0.5, 0.3, 0.6]) / np.linalg.norm([0.5, 0.3, 0.6])
    lum = 0.5 + 0.3 * d[..., 2] + 0.2 * np.exp(3 * (d @ s - 1))
    lum = lum + sun * (d @ s > np.cos(np.radians(4.0)))
    return (lum[..., None] * np.array([1.0, 0.9, 0.8])).astype(np.float32)


@pytest.mark.parametrize("normalize,rtol", [("weights", 1e-5), ("pi", 3e-3)])
def test_constant_environment_gives_itself(normalize, rtol):
    env = np.full((64, 128, 3), [2.0, 1.0, 0.5], np.float32)
    fast = diffuse.diffuse_map(env, (32, 16), normalize=normalize)
    assert fast.shape == (16, 32, 3) and fast.dtype == np.float32
    np.testing.assert_allclose(fast, np.broadcast_to([2.0, 1.0, 0.5], fast.shape), rtol=rtol)
    brute = diffuse.diffuse_map_bruteforce(env, (8, 4), normalize=normalize)
    np.testing.assert_allclose(brute, np.broadcast_to([2.0, 1.0, 0.5], brute.shape), rtol=rtol)


def test_small_cap_gives_analytic_cosine_falloff():
    # cap of radius a around s, radiance L0: D(n) = L0 sin^2(a) (n . s) / 1 while the cap is above
    # n's horizon (n . s >= sin a), 0 when it is entirely below (n . s <= -sin a)
    w, h, sub, a, l0 = 512, 256, 4, np.radians(8.0), 100.0
    s = np.array([0.3, -0.5, 0.4]) / np.linalg.norm([0.3, -0.5, 0.4])
    fine = equirect.pixel_directions(w * sub, h * sub) @ s > np.cos(a)
    wts = equirect.solid_angles(w * sub, h * sub)
    cover = (fine * wts).reshape(h, sub, w, sub).sum(axis=(1, 3)) / equirect.solid_angles(w, h)
    env = np.repeat((l0 * cover)[..., None], 3, axis=2).astype(np.float32)
    normals = equirect.pixel_directions(32, 16).reshape(-1, 3)
    ns = normals @ s
    expect = l0 * np.sin(a) ** 2 * np.maximum(ns, 0)
    lit, dark = ns >= np.sin(a) + 0.05, ns <= -np.sin(a) - 0.05  # margin: input texels are 2.8 deg wide
    fast = diffuse.diffuse_map(env, (32, 16), normalize="pi").reshape(-1, 3)[:, 0]
    np.testing.assert_allclose(fast[lit], expect[lit], rtol=0.01)
    assert np.all(fast[dark] == 0)
    idx = np.flatnonzero(lit)[::8]
    brute = diffuse.diffuse_map_bruteforce(env, (32, 16), normalize="pi", texels=idx)[:, 0]
    np.testing.assert_allclose(brute, expect[idx], rtol=0.01)


@pytest.mark.slow
@pytest.mark.parametrize("out_size", [(16, 8), (32, 16), (64, 32)])
def test_fast_matches_bruteforce_within_1_percent(out_size):
    env = smooth_env(256, 128, sun=50.0)
    fast = diffuse.diffuse_map(env, out_size)
    brute = diffuse.diffuse_map_bruteforce(env, out_size)
    rel = np.abs(fast - brute) / brute
    assert rel.max() < 0.01, rel.max()


def test_bruteforce_texel_subset_matches_full():
    env = smooth_env(64, 32)
    full = diffuse.diffuse_map_bruteforce(env, (16, 8))
    idx = np.array([0, 17, 64, 127])
    np.testing.assert_array_equal(diffuse.diffuse_map_bruteforce(env, (16, 8), texels=idx),
                                  full.reshape(-1, 3)[idx])


def test_sh9_exact_for_band2_environment_and_close_for_smooth():
    w, h = 256, 128
    d = equirect.pixel_directions(w, h)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    band2 = (1.0 + 0.5 * z + 0.3 * x + 0.4 * x * y + 0.2 * (3 * z * z - 1))[..., None].astype(np.float32)
    # analytic: Funk-Hecke scales band l by A_l / pi = 1, 2/3, 1/4 (constant, linear, quadratic)
    n = equirect.pixel_directions(32, 16)
    nx, ny, nz = n[..., 0], n[..., 1], n[..., 2]
    expect = 1.0 + (2 / 3) * (0.5 * nz + 0.3 * nx) + 0.25 * (0.4 * nx * ny + 0.2 * (3 * nz * nz - 1))
    np.testing.assert_allclose(diffuse.sh9_irradiance_map(band2)[..., 0], expect, rtol=1e-3)
    np.testing.assert_allclose(diffuse.diffuse_map(band2, normalize="pi")[..., 0], expect, rtol=3e-3)
    env = smooth_env(w, h)
    exact = diffuse.diffuse_map_bruteforce(env, (32, 16), normalize="pi")
    assert np.abs(diffuse.sh9_irradiance_map(env) - exact).max() / exact.max() < 0.03


def test_bad_sizes_raise():
    with pytest.raises(ProbelessError, match="out_size"):
        diffuse.diffuse_map(np.zeros((8, 16, 3)), (30, 16))
    with pytest.raises(ProbelessError, match="equirectangular"):
        diffuse.diffuse_map(np.zeros((8, 15, 3)))
    with pytest.raises(ProbelessError, match="normalize"):
        diffuse.diffuse_map(np.zeros((8, 16, 3)), normalize="area")
