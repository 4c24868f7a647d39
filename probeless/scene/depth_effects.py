"""Kinect-v1-like depth errors as pure functions on a z image [m] (0 = no return).

* axial noise sigma_z = k z^2 (Khoshelham & Elberink 2012, "Accuracy and resolution of Kinect depth
  data for indoor mapping applications", Sensors 12(2): k = 1.425e-3 / m, i.e. 1.4 mm at 1 m, 3.6 cm at 5 m);
* disparity quantisation: z = b f / d with d rounded to ``disparity_step_px`` (1/8 px on the Kinect v1);
* dropouts where a surface is seen at grazing incidence, and at depth discontinuities;
* flying pixels: at a discontinuity some pixels take a depth between the near and the far side.
"""

from __future__ import annotations

import numpy as np

from probeless.scene.effects_spec import KinectDepth


def axial_noise(z: np.ndarray, k: float, rng: np.random.Generator) -> np.ndarray:
    """``z`` plus zero-mean Gaussian noise of standard deviation ``k z^2`` (0 stays 0)."""
    noisy = z + rng.standard_normal(z.shape, dtype=np.float32) * np.float32(k) * z * z
    return np.where(z > 0, noisy, 0.0)


def quantise_disparity(z: np.ndarray, baseline_m: float, focal_px: float, step_px: float) -> np.ndarray:
    """Depth after rounding the disparity ``b f / z`` to multiples of ``step_px`` (0 stays 0)."""
    bf = baseline_m * focal_px
    d = np.where(z > 0, bf / np.where(z > 0, z, 1.0), 0.0)
    dq = np.round(d / step_px) * step_px
    return np.where((z > 0) & (dq > 0), bf / np.where(dq > 0, dq, 1.0), 0.0)


def incidence_cos(z: np.ndarray, K: np.ndarray) -> np.ndarray:
    """(H, W) |cos| of the angle between each pixel's viewing ray and the surface normal, from depth gradients.

    With P = z r, r = ((u - cx) / fx, (v - cy) / fy, 1), the normal dP/du x dP/dv is proportional to
    (-a, -b, a x + b y + c) with a = z_u / fy, b = z_v / fx, c = z / (fx fy), and its dot product with r is c.
    """
    h, w = z.shape
    z = z.astype(np.float32)
    x = ((np.arange(w, dtype=np.float32) - K[0, 2]) / K[0, 0])[None, :]
    y = ((np.arange(h, dtype=np.float32) - K[1, 2]) / K[1, 1])[:, None]
    a = np.gradient(z, axis=1) / np.float32(K[1, 1])
    b = np.gradient(z, axis=0) / np.float32(K[0, 0])
    c = z / np.float32(K[0, 0] * K[1, 1])
    nz = a * x + b * y + c
    norm = np.sqrt(a * a + b * b + nz * nz) * np.sqrt(x * x + y * y + 1.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = np.abs(c) / norm
    return np.nan_to_num(cos, nan=1.0)


def discontinuities(z: np.ndarray, jump_per_m: float) -> tuple[np.ndarray, np.ndarray]:
    """(mask, other side): pixels whose 4-neighbour depth step exceeds ``jump_per_m * z``, and that neighbour's z."""
    pad = np.pad(z, 1, mode="edge")
    neighbours = np.stack([pad[:-2, 1:-1], pad[2:, 1:-1], pad[1:-1, :-2], pad[1:-1, 2:]])
    step = np.abs(neighbours - z)
    biggest = np.argmax(step, axis=0)
    other = np.take_along_axis(neighbours, biggest[None], axis=0)[0]
    mask = (step.max(axis=0) > jump_per_m * np.maximum(z, other)) & (z > 0)
    return mask, other


def kinect_depth(z: np.ndarray, K: np.ndarray, p: KinectDepth, rng: np.random.Generator) -> np.ndarray:
    """Apply every :class:`KinectDepth` effect to a clean z image [m]; dropped pixels are 0."""
    z = np.asarray(z, dtype=np.float32)
    out = axial_noise(z, p.sigma_k, rng) if p.sigma_k > 0 else z.copy()
    if p.disparity_step_px > 0:
        out = quantise_disparity(out, p.baseline_m, p.focal_px, p.disparity_step_px)
    if p.max_incidence_deg < 90:
        out[incidence_cos(z, K) < np.cos(np.radians(p.max_incidence_deg))] = 0.0
    if p.edge_dropout > 0 or p.flying_pixels > 0:
        edges, other = discontinuities(z, p.edge_jump_m)
        u = rng.random(z.shape, dtype=np.float32)
        drop = edges & (u < p.edge_dropout)
        fly = edges & (u >= p.edge_dropout) & (u < p.edge_dropout + p.flying_pixels) & (other > 0)
        s = rng.random(z.shape, dtype=np.float32)
        out = np.where(fly, z + s * (other - z), out)
        out[drop] = 0.0
    return out
