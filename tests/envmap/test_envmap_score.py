"""``probeless.envmap.score.score_envmap`` against independent references: scikit-image's PSNR and SSIM,
analytic coverages, errors and irradiances, and the published PU21 end points."""

from __future__ import annotations

import numpy as np
import pytest
from skimage.metrics import peak_signal_noise_ratio, structural_similarity

from probeless.color import linear_to_srgb, srgb_to_linear
from probeless.envmap.score import PU21_BANDING_GLARE, SCORES, pu21_encode, score_envmap
from probeless.errors import ProbelessError
from probeless.geom.cube import cube_directions

S = 32


def maps(seed: int = 0, exposure: float = 0.5):
    """(truth_ldr, truth_hdr) of a smooth random-ish environment, some of it above the camera's clip level."""
    d = cube_directions(S)
    rng = np.random.default_rng(seed)
    hdr = np.stack([1.2 + d[..., 0] + 0.5 * d[..., 2] ** 2, 1.0 + 0.8 * d[..., 1], 0.6 + 0.4 * d[..., 2]], axis=-1)
    hdr = hdr * (1 + 0.05 * rng.random(hdr.shape))
    return linear_to_srgb(np.clip(hdr * exposure, 0, 1)), hdr


def test_psnr_and_ssim_common_match_skimage_over_the_mask():
    t_ldr, t_hdr = maps()
    rng = np.random.default_rng(1)
    est = np.clip(t_ldr + rng.normal(0, 0.05, t_ldr.shape), 0, 1)
    common = cube_directions(S)[..., 2] > -0.3
    out = score_envmap(est, t_ldr, t_hdr, exposure=0.5, common=common)
    assert out["psnr_common"] == pytest.approx(peak_signal_noise_ratio(t_ldr[common], est[common], data_range=1.0),
                                               abs=1e-9)
    maps_sk = [structural_similarity(est[f], t_ldr[f], data_range=1.0, gaussian_weights=True, sigma=1.5,
                                     use_sample_covariance=False, channel_axis=-1, full=True)[1].mean(axis=-1)
               for f in range(6)]
    assert out["ssim_common"] == pytest.approx(float(np.stack(maps_sk)[common].mean()), abs=1e-6)
    assert out["psnr_all"] == pytest.approx(peak_signal_noise_ratio(t_ldr, est, data_range=1.0), abs=1e-9)


def test_coverage_of_a_hemisphere_and_solid_angle_rmse():
    t_ldr, t_hdr = maps()
    d = cube_directions(S)
    upper = d[..., 2] > 0
    out = score_envmap(t_ldr, t_ldr, t_hdr, exposure=0.5, observed=upper, common=upper & (d[..., 0] > 0))
    assert out["coverage"] == pytest.approx(0.5, abs=1e-12)
    assert out["common_coverage"] == pytest.approx(0.25, abs=1e-12)
    est = np.clip(t_ldr - 0.3 * d[..., 2:] ** 2, 0, 1)  # errors grow towards the poles, where texels are large
    e2 = ((est - t_ldr) ** 2).mean(axis=-1)
    # solid angle, independently: dOmega = dA (1 + u^2 + v^2)^(-3/2) = max_i |d_i|^3 for the unit direction
    w = np.abs(d).max(axis=-1) ** 3
    expect = np.sqrt((e2 * w).sum() / w.sum())
    got = score_envmap(est, t_ldr, t_hdr, exposure=0.5)["rmse_sa"]
    assert got == pytest.approx(expect, rel=2e-3)  # texel-centre weights vs exact texel solid angles
    assert abs(got - np.sqrt(e2.mean())) > 0.01 * got  # and not the texel-count mean


def test_rmse_sa_weights_a_whole_face_as_a_sixth_of_the_sphere():
    t_ldr, t_hdr = maps()
    est = t_ldr.copy()
    est[2] = np.where(t_ldr[2] > 0.5, t_ldr[2] - 0.2, t_ldr[2] + 0.2)  # error 0.2 on face +Y only
    assert score_envmap(est, t_ldr, t_hdr, exposure=0.5)["rmse_sa"] == pytest.approx(0.2 / np.sqrt(6))


def test_log_rmse_hdr_analytic_and_shows_clipping():
    exposure = 0.25
    hdr = np.full((6, S, S, 3), 0.8)
    ldr = linear_to_srgb(hdr * exposure)
    est = linear_to_srgb(2 * hdr * exposure)  # twice too bright, unclipped
    assert score_envmap(est, ldr, hdr, exposure=exposure)["log_rmse_hdr"] == pytest.approx(np.log10(2), abs=1e-4)
    bright = np.full((6, S, S, 3), 40.0)  # camera linear 10: the LDR map clips it at 1
    clipped = linear_to_srgb(np.clip(bright * exposure, 0, 1))
    out = score_envmap(clipped, clipped, bright, exposure=exposure)
    assert out["log_rmse_hdr"] == pytest.approx(1.0, abs=1e-4)  # log10(10): what LDR loses
    assert out["psnr_common"] == float("inf")


def test_pu21_published_end_points_and_monotonic():
    # end points of the banding_glare encoding as published with the PU21 parameters (ITU-T P.910 siti tools:
    # p_min = 5.4705e-10 at 0.005 cd/m², p_max = 595.3939 at 10000 cd/m²)
    assert pu21_encode(0.005) == pytest.approx(5.4705e-10, abs=1e-12)
    assert pu21_encode(10000.0) == pytest.approx(595.3939, abs=1e-3)
    y = np.logspace(np.log10(0.005), 4, 500)
    assert np.all(np.diff(pu21_encode(y)) > 0)
    assert PU21_BANDING_GLARE[6] == pytest.approx(596.3148142)
    # a uniform error gives 20 log10(peak / |V(a) - V(b)|); exposure 1, white = 100 cd/m²
    hdr = np.full((6, S, S, 3), 0.5)
    est = linear_to_srgb(np.full((6, S, S, 3), 0.25))
    got = score_envmap(est, linear_to_srgb(hdr), hdr, exposure=1.0)["pu21_psnr"]
    expect = 20 * np.log10(595.3939 / abs(pu21_encode(25.0) - pu21_encode(50.0)))
    assert got == pytest.approx(expect, abs=1e-3)


def test_sh_diffuse_error_analytic_for_a_linear_gradient():
    # L(w) = a + b.w has E(n) = pi a + 2 pi / 3 b.n exactly (Ramamoorthi & Hanrahan); vs a uniform truth a,
    # the relative RMS error over the sphere is (2/3) |b| / (sqrt(3) a)
    d = cube_directions(S)
    a, b = 0.4, np.array([0.1, -0.05, 0.2])
    exposure = 1.0
    est = linear_to_srgb(a + d @ b)[..., None].repeat(3, axis=-1)
    truth = np.full((6, S, S, 3), a)
    out = score_envmap(est, linear_to_srgb(truth), truth, exposure=exposure)
    expect = (2 / 3) * np.linalg.norm(b) / (np.sqrt(3) * a)
    assert out["sh_diffuse_error"] == pytest.approx(expect, rel=0.02)
    assert out["sh_diffuse_error_ldr"] == pytest.approx(expect, rel=0.02)


def test_sh_error_ldr_is_the_fair_one_when_the_truth_clips():
    exposure = 0.5
    t_ldr, t_hdr = maps(exposure=exposure)
    assert (t_hdr * exposure > 1).any()
    out = score_envmap(t_ldr, t_ldr, t_hdr, exposure=exposure)  # a perfect LDR estimate
    assert out["sh_diffuse_error_ldr"] == pytest.approx(0.0, abs=1e-9)
    assert out["sh_diffuse_error"] > 0.01  # the light above the clip level is missing
    lin = srgb_to_linear(t_ldr) / exposure
    assert np.all(lin <= t_hdr + 1e-9)


def test_larger_estimate_is_box_filtered_and_masks_follow():
    t_ldr, t_hdr = maps()
    big = t_ldr.repeat(2, axis=1).repeat(2, axis=2)
    obs = (cube_directions(2 * S)[..., 2] > 0)
    out = score_envmap((big * 255).round().astype(np.uint8), t_ldr, t_hdr, exposure=0.5, observed=obs)
    assert out["psnr_all"] > 50 and out["coverage"] == pytest.approx(0.5)
    assert set(SCORES) <= set(out)
    with pytest.raises(ProbelessError, match="multiple"):
        score_envmap(t_ldr[:, :30, :30], t_ldr, t_hdr, exposure=0.5)
    with pytest.raises(ProbelessError, match="exposure"):
        score_envmap(t_ldr, t_ldr, t_hdr, exposure=0.0)
    empty = score_envmap(t_ldr, t_ldr, t_hdr, exposure=0.5, common=np.zeros((6, S, S), bool))
    assert np.isnan(empty["psnr_common"]) and np.isnan(empty["ssim_common"])
