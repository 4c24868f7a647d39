"""Colour-camera effects against analytic references: Poisson-Gaussian variance, cos^4 vignetting, auto-exposure
step response, flicker averaged over the shutter, response curves, and the per-camera simulator."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad

from probeless.color import linear_to_srgb
from probeless.scene.camera_sim import CameraSim
from probeless.scene.effects_spec import AutoExposure, CameraEffects, Noise, Vignetting
from probeless.scene.rig import expose
from probeless.scene.sensor_effects import (
    auto_exposure_step,
    converged_exposure,
    encode,
    flicker_factor,
    pinhole_cos_theta,
    poisson_gaussian,
    response_lut,
    vignetting_map,
)

K = np.array([[500.0, 0, 319.5], [0, 500.0, 239.5], [0, 0, 1]])


@pytest.mark.parametrize("full_well,read", [(4000.0, 0.003), (500.0, 0.0), (20000.0, 0.01)])
def test_noise_variance_follows_the_poisson_gaussian_model(full_well, read):
    rng = np.random.default_rng(5)
    for mean in (0.02, 0.2, 0.7):
        signal = np.full((400, 500, 3), mean, np.float32)
        out = poisson_gaussian(signal, Noise(full_well, read), rng)
        model = mean / full_well + read ** 2   # Var = mean * gain + sigma^2 with gain = 1 / full well
        assert out.mean() == pytest.approx(mean, abs=4 * np.sqrt(model / out.size))
        assert out.var() == pytest.approx(model, rel=0.02)


def test_noise_matches_true_poisson_counts_in_distribution():
    """Against numpy's Poisson sampler at a high count: same mean and variance of electron counts."""
    full_well, mean = 3000.0, 0.3
    ours = poisson_gaussian(np.full(200_000, mean, np.float32), Noise(full_well), np.random.default_rng(1)) * full_well
    poisson = np.random.default_rng(2).poisson(mean * full_well, 200_000)
    assert ours.mean() == pytest.approx(poisson.mean(), rel=2e-3)
    assert ours.std() == pytest.approx(poisson.std(), rel=0.02)


def test_cos4_vignetting_at_known_pixels():
    vig = vignetting_map(Vignetting("cos4"), pinhole_cos_theta(640, 480, K), (K[0, 2], K[1, 2]))
    for u, v in ((319, 239), (0, 0), (639, 479), (600, 100)):
        theta = np.arctan(np.hypot(u - 319.5, v - 239.5) / 500.0)  # angle of the pixel's ray to the optical axis
        assert vig[v, u, 0] == pytest.approx(np.cos(theta) ** 4, rel=1e-5)
    assert vig[0, 0, 0] == pytest.approx(0.3728, abs=1e-4)  # corner ray 38.6 deg off axis: cos^4 = 0.373


def test_polynomial_vignetting_at_the_centre_and_the_corner():
    vig = vignetting_map(Vignetting("poly", (-0.3, 0.05)), pinhole_cos_theta(641, 481, K), (320.0, 240.0))
    assert vig[240, 320, 0] == pytest.approx(1.0)
    assert vig[0, 0, 0] == pytest.approx(1 - 0.3 + 0.05, rel=1e-5)  # r = 1 at the half diagonal
    assert vig[240, 0, 0] == pytest.approx(1 - 0.3 * 0.8**2 + 0.05 * 0.8**4,  # r = 320 / 400
                                           rel=1e-5)


def test_auto_exposure_step_response_is_first_order_in_log_exposure():
    ae = AutoExposure(target=0.18, tau_s=0.5, min=0.01, max=100)
    e0, scene_mean, dt = 1.0, 0.05, 1 / 30
    target = 0.18 / scene_mean
    e, t = e0, 0.0
    for _ in range(60):
        e, t = auto_exposure_step(e, scene_mean, dt, ae), t + dt
        reached = np.log(e / e0) / np.log(target / e0)
        assert reached == pytest.approx(1 - np.exp(-t / ae.tau_s), rel=1e-9)
    assert auto_exposure_step(e0, scene_mean, 0.2, AutoExposure(0.18, tau_s=0)) == pytest.approx(3.6)


def test_auto_exposure_respects_its_limits():
    ae = AutoExposure(target=0.5, tau_s=0.1, min=0.2, max=4.0)
    assert converged_exposure(1e-6, ae) == 4.0 and converged_exposure(100.0, ae) == 0.2
    e = 1.0
    for _ in range(100):
        e = auto_exposure_step(e, 1e-6, 0.05, ae)
    assert e == pytest.approx(4.0, rel=1e-6)


@pytest.mark.parametrize("t,shutter,amp,phase", [(0.0, 0.01, 0.1, 0.0), (0.0123, 0.004, 0.3, 40.0),
                                                 (1.337, 0.0005, 0.2, -90.0), (2.0, 0.0, 0.1, 10.0)])
def test_flicker_is_the_mean_over_the_shutter(t, shutter, amp, phase):
    f, phi = 100.0, np.radians(phase)
    wave = lambda s: 1 + amp * np.cos(2 * np.pi * f * s + phi)  # noqa: E731
    want = wave(t) if shutter == 0 else quad(wave, t, t + shutter)[0] / shutter
    assert flicker_factor(t, shutter, amp, f, phase) == pytest.approx(want, rel=1e-9)


def test_flicker_averages_out_over_a_whole_period():
    assert flicker_factor(0.123, 0.01, 0.5, 100.0, 17.0) == pytest.approx(1.0, abs=1e-12)


def test_response_curves():
    x = np.array([0.0, 0.01, 0.18, 0.5, 1.0, 2.0], np.float32)
    gamma = encode(x, response_lut(2.2))
    np.testing.assert_array_equal(gamma, np.round(np.clip(x, 0, 1) ** (1 / 2.2) * 255))
    srgb = encode(x, response_lut(None))
    assert np.max(np.abs(srgb.astype(int) - np.round(linear_to_srgb(np.clip(x, 0, 1)) * 255))) <= 1
    assert gamma[2] != srgb[2]  # the curves differ in the mid tones


def _sim(**effects) -> CameraSim:
    return CameraSim(CameraEffects(**effects), 1.3, pinhole_cos_theta(64, 48, K / 10), (3.2, 2.4), None, (0, 0, 1))


def test_camera_without_effects_records_what_the_plain_rig_records():
    radiance = np.random.default_rng(0).random((48, 64, 3), dtype=np.float32) * 1.2
    np.testing.assert_array_equal(_sim().record(radiance, 0.0, 0), expose(radiance, 1.3))


def test_camera_auto_exposure_lags_a_brightness_step_by_one_frame_of_metering():
    ae = AutoExposure(target=0.2, tau_s=0.3, min=0.01, max=50)
    sim, dt = _sim(auto_exposure=ae), 1 / 15
    dark, bright = np.full((48, 64, 3), 0.05, np.float32), np.full((48, 64, 3), 0.5, np.float32)
    sim.record(dark, 0.0, 0)
    assert sim.exposure == pytest.approx(4.0, rel=1e-5)  # starts converged: 0.2 / 0.05
    sim.record(bright, dt, 1)
    assert sim.exposure == pytest.approx(4.0, rel=1e-5)  # metered the dark frame before
    for k in range(2, 20):
        sim.record(bright, k * dt, k)
        reached = np.log(sim.exposure / 4.0) / np.log(0.4 / 4.0)
        assert reached == pytest.approx(1 - np.exp(-(k - 1) * dt / ae.tau_s), rel=1e-5)


def test_camera_white_balance_and_gains():
    sim = _sim(wb_gains=np.array([1.1, 1.0, 0.9]))
    radiance = np.full((48, 64, 3), 0.2, np.float32)
    img = sim.record(radiance, 0.0, 0)
    np.testing.assert_allclose(sim.gains(), [1.43, 1.3, 1.17], rtol=1e-6)
    np.testing.assert_array_equal(img[0, 0], np.round(linear_to_srgb(np.array([0.286, 0.26, 0.234])) * 255))
    np.testing.assert_array_equal(sim.ideal(radiance), img)
