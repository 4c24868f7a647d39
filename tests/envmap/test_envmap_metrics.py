"""Environment-map metrics against analytic values and an independent SSIM reference (scipy.ndimage)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from probeless.envmap import metrics as M
from probeless.errors import ProbelessError
from probeless.geom.cube import cube_solid_angles, texel_direction


def _dirs(size):
    row, col = np.meshgrid(np.arange(size), np.arange(size), indexing="ij")
    return np.stack([texel_direction(f, row, col, size) for f in range(6)])  # (6, S, S, 3)


def _ssim_reference(x, y, c1=1e-4, c2=9e-4):
    """The published SSIM formula with scipy's Gaussian filter (sigma 1.5, 11 taps), border of 5 cropped."""
    def g(a):
        return ndimage.gaussian_filter(a, 1.5, truncate=3.5, mode="reflect")  # radius 5
    mx, my = g(x), g(y)
    sx, sy, sxy = g(x * x) - mx ** 2, g(y * y) - my ** 2, g(x * y) - mx * my
    s = (2 * mx * my + c1) * (2 * sxy + c2) / ((mx ** 2 + my ** 2 + c1) * (sx + sy + c2))
    return s[5:-5, 5:-5].mean()


def test_psnr_of_known_additive_error():
    rng = np.random.default_rng(0)
    ref = rng.uniform(0.2, 0.8, (6, 16, 16, 3))
    assert M.envmap_psnr(ref + 0.1, ref) == pytest.approx(20.0, abs=1e-9)  # MSE 0.01
    assert M.envmap_psnr(ref, ref) == float("inf")
    est = ref.copy()
    est[4] += 0.05          # error only on the ceiling face
    mask = np.zeros((6, 16, 16), bool)
    mask[4] = True
    assert M.envmap_psnr(est, ref, mask) == pytest.approx(-10 * np.log10(0.05 ** 2), abs=1e-9)
    assert M.envmap_psnr(est, ref) == pytest.approx(-10 * np.log10(0.05 ** 2 / 6), abs=1e-9)
    ref8 = np.round(ref * 255).astype(np.uint8)
    assert M.envmap_psnr(ref8, ref8.astype(np.float64) / 255 + 0.01) == pytest.approx(40.0, abs=1e-9)
    with pytest.raises(ProbelessError, match="empty mask"):
        M.envmap_psnr(est, ref, np.zeros((6, 16, 16), bool))


def test_ssim_identity_noise_and_published_formula():
    rng = np.random.default_rng(1)
    x = ndimage.gaussian_filter(rng.uniform(0, 1, (48, 48)), 2)
    assert M.ssim_image(x, x) == pytest.approx(1.0, abs=1e-12)
    scores = [M.ssim_image(x, np.clip(x + rng.normal(0, s, x.shape), 0, 1)) for s in (0.01, 0.05, 0.2)]
    assert scores[0] > scores[1] > scores[2] and scores[0] < 1
    # constant images: variances vanish, SSIM = (2ab + C1) / (a^2 + b^2 + C1)
    a, b = 0.3, 0.6
    assert M.ssim_image(np.full((20, 20), a), np.full((20, 20), b)) == pytest.approx(
        (2 * a * b + 1e-4) / (a * a + b * b + 1e-4), rel=1e-9)
    for y in (0.5 * x, x + 0.1, np.clip(x + rng.normal(0, 0.1, x.shape), 0, 1)):
        assert M.ssim_image(x, y) == pytest.approx(_ssim_reference(x, y), abs=1e-9)


def test_envmap_ssim_averages_faces():
    rng = np.random.default_rng(2)
    ref = rng.uniform(0, 1, (6, 24, 24, 3))
    est = ref.copy()
    est[0] = rng.uniform(0, 1, (24, 24, 3))
    per_face = [np.mean([_ssim_reference(est[f, ..., c], ref[f, ..., c]) for c in range(3)]) for f in range(6)]
    assert M.envmap_ssim(est, ref) == pytest.approx(np.mean(per_face), abs=1e-9)
    assert M.envmap_ssim(ref, ref) == pytest.approx(1.0)


@pytest.mark.parametrize("size", [1, 2, 7, 64])
def test_texel_solid_angles_sum_to_sphere(size):
    omega = cube_solid_angles(size)
    assert omega.shape == (6, size, size)
    assert omega.sum() == pytest.approx(4 * np.pi, rel=1e-12)


def test_texel_solid_angle_matches_differential_formula():
    # small texels: dOmega ~ (2/S)^2 / (1 + a^2 + b^2)^(3/2) at the texel centre
    s = 512
    t = 2 * (np.arange(s) + 0.5) / s - 1
    approx = (2 / s) ** 2 / (1 + t[:, None] ** 2 + t[None, :] ** 2) ** 1.5
    np.testing.assert_allclose(cube_solid_angles(s)[0], approx, rtol=2e-5)


def test_coverage_of_hemisphere_and_cap():
    s = 32
    d = _dirs(s)
    assert M.coverage(d[..., 2] > 0) == pytest.approx(0.5, abs=1e-12)
    assert M.coverage(np.ones((6, s, s), bool)) == pytest.approx(1.0)
    # a cap within 60 deg of +Z covers (1 - cos 60) / 2 = 0.25 of the sphere (texel-centre quantisation)
    assert M.coverage(d[..., 2] >= 0.5, cube_solid_angles(s)) == pytest.approx(0.25, abs=0.01)


def test_mirror_sphere_reflects_view_direction_at_centre_and_doubles_angles():
    s = 96
    env = (_dirs(s) + 1) / 2  # colour = direction
    img, inside = M.render_mirror_sphere(env, 101)
    np.testing.assert_allclose(img[50, 50], [1.0, 0.5, 0.5], atol=1 / s)  # along +X, towards the viewer
    assert not inside[0, 0] and inside[50, 50] and inside.sum() == pytest.approx(np.pi * 50.5 ** 2, rel=0.01)
    # pixel on the upper vertical axis at normal elevation 30 deg reflects at elevation 60 deg
    size = 400
    img, _ = M.render_mirror_sphere(env, size)
    row = round(size / 2 * (1 - np.sin(np.radians(30))) - 0.5)
    z = 1 - 2 * (row + 0.5) / size
    th = np.arcsin(z)
    np.testing.assert_allclose(img[row, size // 2], ([np.cos(2 * th), 0, np.sin(2 * th)] + np.ones(3)) / 2,
                               atol=2 / s)
    # image right is +Y: a normal towards +Y (45 deg) reflects to +Y
    col = round(size / 2 * (1 + np.sin(np.radians(45))) - 0.5)
    assert img[size // 2, col, 1] > 0.95


@pytest.mark.slow
def test_diffuse_sphere_constant_and_directional_light():
    s = 32
    L = np.array([0.2, 0.5, 1.5])
    img, inside = M.render_diffuse_sphere(np.broadcast_to(L, (6, s, s, 3)), 33, albedo=0.7)
    # the integral of the clamped cosine is pi; texel-centre quadrature at 32^2 faces is within 0.1 %
    np.testing.assert_allclose(img[inside], np.broadcast_to(0.7 * L, img[inside].shape), rtol=1e-3)
    assert np.all(img[~inside] == 0)
    # a small bright patch around +X: the centre normal (+X) sees E = L sum(dOmega cos), cos = 1/sqrt(1+a^2+b^2)
    env = np.zeros((6, 64, 64, 1))
    env[0, 30:34, 30:34] = 10.0
    t = 2 * (np.arange(30, 34) + 0.5) / 64 - 1
    cos = 1 / np.sqrt(1 + t[:, None] ** 2 + t[None, :] ** 2)
    irradiance = 10.0 * (cube_solid_angles(64)[0, 30:34, 30:34] * cos).sum()
    img, _ = M.render_diffuse_sphere(env, 33, max_face=64)
    assert img[16, 16, 0] == pytest.approx(irradiance / np.pi, rel=1e-9)
    # downsampling to 16 keeps the irradiance close (low frequency)
    img16, _ = M.render_diffuse_sphere(env, 33, max_face=16)
    assert img16[16, 16, 0] == pytest.approx(img[16, 16, 0], rel=0.02)


@pytest.mark.slow
def test_sphere_psnrs():
    rng = np.random.default_rng(3)
    ref = ndimage.gaussian_filter(rng.uniform(0.1, 0.9, (6, 32, 32, 3)), (0, 2, 2, 0))
    assert M.mirror_psnr(ref, ref) == float("inf")
    assert M.mirror_psnr(ref + 0.1, ref) == pytest.approx(20.0, abs=1e-9)
    assert M.diffuse_psnr(ref, ref) == float("inf")
    assert M.diffuse_psnr(ref * 0.8, ref) < M.diffuse_psnr(ref * 0.95, ref) < 60


def test_sh_relative_error():
    rng = np.random.default_rng(4)
    ref = rng.normal(size=(25, 3))
    assert M.sh_rel_error(1.1 * ref, ref, irradiance=False) == pytest.approx(0.1)
    assert M.sh_rel_error(1.1 * ref, ref) == pytest.approx(0.1)
    est = ref.copy()
    est[9:16] += 5.0  # band 3 is invisible to irradiance (A_3 = 0)
    assert M.sh_rel_error(est, ref) == pytest.approx(0.0, abs=1e-12)
    assert M.sh_rel_error(est, ref, irradiance=False) > 1
    # irradiance error of a DC-only change: (pi * dc) / |A_l c_lm|
    est = ref.copy()
    est[0] += 0.5
    a = np.repeat(M.COSINE_LOBE, [1, 3, 5, 7, 9])[:, None]
    assert M.sh_rel_error(est, ref) == pytest.approx(np.pi * 0.5 * np.sqrt(3) / np.linalg.norm(a * ref))
    with pytest.raises(ProbelessError, match="bands"):
        M.sh_rel_error(np.zeros((24, 3)), np.zeros((24, 3)))
