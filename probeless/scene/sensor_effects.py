"""Colour-camera imperfections as pure functions: response curve, vignetting, Poisson-Gaussian noise,
auto-exposure lag and mains flicker. probeless.scene.camera_sim strings them together per camera.

Signals are linear and normalised so that 1 is the sensor's full well (what clips to code 255).
"""

from __future__ import annotations

import numpy as np

from probeless.color import linear_to_srgb, luminance
from probeless.scene.effects_spec import AutoExposure, Noise, Vignetting

LUT_STEPS = 65535


def response_lut(gamma: float | None = None) -> np.ndarray:
    """(65536,) uint8 codes of the linear signal ``i / 65535``: sRGB (``gamma`` None) or ``x ** (1 / gamma)``."""
    x = np.arange(LUT_STEPS + 1) / LUT_STEPS
    encoded = linear_to_srgb(x) if gamma is None else x ** (1.0 / gamma)
    return np.round(encoded * 255.0).astype(np.uint8)


def encode(signal: np.ndarray, lut: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """uint8 codes of the linear signal ``signal * scale`` (clipped to [0, 1]) through a :func:`response_lut` table
    (linear steps of 1.5e-5: at most one code from exact rounding, several times faster than the curve per pixel)."""
    scaled = np.nan_to_num(signal * np.float32(scale * LUT_STEPS), nan=0.0)
    return lut[np.clip(scaled + 0.5, 0, LUT_STEPS).astype(np.uint16)]


def pinhole_cos_theta(width: int, height: int, K: np.ndarray) -> np.ndarray:
    """(H, W) cosine of the angle between each pixel's ray and the optical axis of a pinhole camera."""
    v, u = np.mgrid[0:height, 0:width].astype(np.float64)
    x, y = (u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1]
    return 1.0 / np.sqrt(1.0 + x * x + y * y)


def vignetting_map(vig: Vignetting, cos_theta: np.ndarray, center: tuple[float, float]) -> np.ndarray:
    """(H, W, 1) float32 relative illumination: ``cos4`` = cos^4(theta); ``poly`` = 1 + k1 r^2 + k2 r^4 + k3 r^6
    with r the distance from ``center`` (cx, cy) in units of half the diagonal between corner pixel centres
    (clipped to >= 0)."""
    h, w = cos_theta.shape
    if vig.model == "cos4":
        gain = np.clip(cos_theta, 0.0, 1.0) ** 4
    else:
        v, u = np.mgrid[0:h, 0:w].astype(np.float64)
        r2 = ((u - center[0]) ** 2 + (v - center[1]) ** 2) / (0.25 * ((w - 1) ** 2 + (h - 1) ** 2))
        gain = 1.0 + sum(k * r2 ** (i + 1) for i, k in enumerate(vig.coeffs))
    return np.clip(gain, 0.0, None).astype(np.float32)[..., None]


def poisson_gaussian(signal: np.ndarray, noise: Noise, rng: np.random.Generator, scale: float = 1.0) -> np.ndarray:
    """``x = signal * scale`` plus zero-mean noise of variance ``x / full_well + read_sigma^2`` (float32).

    Shot noise uses the Gaussian approximation of the Poisson count (exact in mean and variance; fine
    above a few electrons), which is several times faster than drawing Poisson samples per pixel.
    """
    x = np.multiply(signal, np.float32(scale), dtype=np.float32)
    noisy = np.maximum(x, np.float32(0.0))
    noisy *= np.float32(1.0 / noise.full_well)
    noisy += np.float32(noise.read_sigma ** 2)
    np.sqrt(noisy, out=noisy)
    noisy *= rng.standard_normal(x.shape, dtype=np.float32)
    noisy += x
    return noisy


def metered_mean(radiance: np.ndarray, mask: np.ndarray | None = None, step: int = 4) -> float:
    """Mean luminance of ``radiance`` (H, W, 3) on every ``step``-th pixel (inside ``mask`` when given)."""
    lum = luminance(radiance[::step, ::step].astype(np.float32))
    if mask is not None:
        lum = lum[mask[::step, ::step]]
    return float(np.mean(lum)) if lum.size else 0.0


def converged_exposure(scene_mean: float, ae: AutoExposure) -> float:
    """The exposure that brings a scene of mean luminance ``scene_mean`` to ``ae.target``, within the limits."""
    return float(np.clip(ae.target / max(scene_mean, 1e-9), ae.min, ae.max))


def auto_exposure_step(exposure: float, scene_mean: float, dt: float, ae: AutoExposure) -> float:
    """Exposure after ``dt`` seconds of first-order lag (time constant ``ae.tau_s``, in log exposure)
    towards :func:`converged_exposure` of the metered ``scene_mean``."""
    target = converged_exposure(scene_mean, ae)
    alpha = 1.0 if ae.tau_s <= 0 else 1.0 - np.exp(-max(dt, 0.0) / ae.tau_s)
    return float(np.exp(np.log(exposure) + alpha * (np.log(target) - np.log(exposure))))


def flicker_factor(t: float, exposure_s: float, amplitude: float, frequency_hz: float, phase_deg: float = 0.0) -> float:
    """Mean of ``1 + amplitude cos(2 pi f s + phase)`` over the shutter interval s in [t, t + exposure_s]."""
    w, phi = 2.0 * np.pi * frequency_hz, np.radians(phase_deg)
    if exposure_s <= 0:
        return float(1.0 + amplitude * np.cos(w * t + phi))
    return float(1.0 + amplitude * (np.sin(w * (t + exposure_s) + phi) - np.sin(w * t + phi)) / (w * exposure_s))
