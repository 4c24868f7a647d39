"""Kinect-like depth against analytic references: sigma = k z^2 on flat walls, disparity quantisation steps,
incidence angles of tilted planes, and dropouts / flying pixels at a depth step."""

from __future__ import annotations

import numpy as np
import pytest

from probeless.scene.depth_effects import (
    axial_noise,
    discontinuities,
    incidence_cos,
    kinect_depth,
    quantise_disparity,
)
from probeless.scene.effects_spec import KinectDepth

K = np.array([[525.0, 0, 319.5], [0, 525.0, 239.5], [0, 0, 1]])
KHOSHELHAM_K = 1.425e-3  # Khoshelham & Elberink 2012 [1/m]


@pytest.mark.parametrize("z", [0.8, 1.5, 3.0, 4.5])
def test_noise_sigma_grows_with_z_squared_on_a_flat_wall(z):
    wall = np.full((480, 640), z, np.float32)
    out = kinect_depth(wall, K, KinectDepth(sigma_k=KHOSHELHAM_K), np.random.default_rng(int(z * 10)))
    assert out.std() == pytest.approx(KHOSHELHAM_K * z * z, rel=0.01)
    assert out.mean() == pytest.approx(z, abs=5 * KHOSHELHAM_K * z * z / np.sqrt(out.size))


def test_no_return_stays_zero():
    z = np.zeros((10, 10), np.float32)
    assert not axial_noise(z, 0.01, np.random.default_rng(0)).any()
    assert not quantise_disparity(z, 0.075, 580, 0.125).any()


@pytest.mark.parametrize("z", [1.0, 2.0, 4.0])
def test_disparity_quantisation_levels(z):
    bf, step = 0.075 * 580, 0.125
    ramp = np.linspace(z * 0.97, z * 1.03, 5000)
    levels = np.unique(quantise_disparity(ramp, 0.075, 580, step))
    disparities = bf / levels
    np.testing.assert_allclose(disparities / step, np.round(disparities / step), atol=1e-9)  # whole 1/8 px steps
    spacing = np.median(np.diff(levels))
    assert spacing == pytest.approx(z * z * step / bf, rel=0.04)  # dz = z^2 dd / (b f): 1.15 cm at 2 m
    error = np.abs(quantise_disparity(ramp, 0.075, 580, step) - ramp)
    assert np.all(error <= 0.52 * ramp * ramp * step / bf)  # at most half a local step


def _plane_depth(normal: np.ndarray, d: float) -> tuple[np.ndarray, np.ndarray]:
    """z image of the plane n . P = d and the analytic |cos| between each pixel's ray and n."""
    v, u = np.mgrid[0:480, 0:640].astype(np.float64)
    rays = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], axis=-1)
    nr = rays @ normal
    return d / nr, np.abs(nr) / (np.linalg.norm(normal) * np.linalg.norm(rays, axis=-1))


@pytest.mark.parametrize("tilt_deg", [0.0, 30.0, 60.0, 75.0])
def test_incidence_angle_of_tilted_planes(tilt_deg):
    a = np.radians(tilt_deg)
    z, want = _plane_depth(np.array([np.sin(a), 0.3 * np.sin(a), -np.cos(a)]), -2.0)
    got = incidence_cos(z.astype(np.float32), K)
    seen = ((z > 0) & (z < 8))[5:-5, 5:-5]  # away from where the plane meets the horizon
    assert seen.mean() > 0.4
    np.testing.assert_allclose(got[5:-5, 5:-5][seen], want[5:-5, 5:-5][seen], atol=2e-3)


def test_grazing_pixels_drop_out():
    a = np.radians(70.0)
    z, cos = _plane_depth(np.array([np.sin(a), 0.0, -np.cos(a)]), -2.0)
    z = np.where((z > 0) & (z < 8), z, 0.0)
    out = kinect_depth(z.astype(np.float32), K, KinectDepth(max_incidence_deg=72.0), np.random.default_rng(0))
    inner = (slice(5, -5), slice(5, -5))
    grazing = (cos < np.cos(np.radians(72.0)) - 2e-3)[inner]
    clear = (cos > np.cos(np.radians(72.0)) + 2e-3)[inner] & (z[inner] > 0) & (z[inner] < 7)
    assert grazing.sum() > 1000 and clear.sum() > 1000
    assert np.all(out[inner][grazing] == 0) and np.all(out[inner][clear] > 0)


def test_edges_drop_out_or_fly_with_the_requested_probabilities():
    z = np.full((2000, 40), 1.0, np.float32)
    z[:, 20:] = 3.0
    edges, other = discontinuities(z, 0.05)
    assert set(np.nonzero(edges.any(axis=0))[0]) == {19, 20}
    np.testing.assert_array_equal(other[:, 19], 3.0)
    np.testing.assert_array_equal(other[:, 20], 1.0)
    p = KinectDepth(edge_dropout=0.3, flying_pixels=0.2)
    out = kinect_depth(z, K, p, np.random.default_rng(3))
    edge = out[:, 19:21]
    n = edge.size
    dropped = np.mean(edge == 0)
    flying = np.mean((edge > 1.0) & (edge < 3.0))
    assert dropped == pytest.approx(0.3, abs=4 * np.sqrt(0.3 * 0.7 / n))
    assert flying == pytest.approx(0.2, abs=4 * np.sqrt(0.2 * 0.8 / n))
    np.testing.assert_array_equal(np.delete(out, [19, 20], axis=1), np.delete(z, [19, 20], axis=1))
