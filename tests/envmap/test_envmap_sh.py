"""Real SH on cubemaps against scipy's complex harmonics, analytic integrals and brute-force sums."""

from math import pi, sqrt

import numpy as np
import pytest
from scipy.special import sph_harm_y

from probeless.envmap.sh import (
    cosine_lobe,
    irradiance_from_sh,
    project_cubemap,
    radiance_from_sh,
    sh_basis,
)
from probeless.geom.cube import cube_directions, cube_solid_angles, texel_from_direction


def _random_dirs(n, seed=0):
    d = np.random.default_rng(seed).normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def test_solid_angles_sum_to_sphere_and_match_small_texel_approximation():
    for size in (1, 2, 7, 64):
        omega = cube_solid_angles(size)
        assert omega.shape == (6, size, size)
        assert omega.sum() == pytest.approx(4 * pi, rel=1e-12)
    # one face of a cube subtends 4 pi / 6
    assert cube_solid_angles(1)[0, 0, 0] == pytest.approx(4 * pi / 6)
    # a small texel: area / distance^3 at its centre
    size = 256
    omega = cube_solid_angles(size)
    r, c = 17, 200
    a, b = 2 * (c + 0.5) / size - 1, 2 * (r + 0.5) / size - 1
    approx = (2 / size) ** 2 / (1 + a * a + b * b) ** 1.5
    assert omega[3, r, c] == pytest.approx(approx, rel=1e-4)


def test_basis_matches_scipy_complex_harmonics_in_real_form():
    d = _random_dirs(500)
    theta, phi = np.arccos(np.clip(d[:, 2], -1, 1)), np.arctan2(d[:, 1], d[:, 0])
    ours = sh_basis(d, 6)
    for l in range(6):
        for m in range(-l, l + 1):
            y = sph_harm_y(l, abs(m), theta, phi)  # scipy includes the Condon-Shortley phase
            ref = y.real if m == 0 else sqrt(2) * (y.real if m > 0 else y.imag)
            np.testing.assert_allclose(ours[:, l * (l + 1) + m], ref, atol=1e-10, err_msg=f"l={l} m={m}")


def test_basis_band1_is_sloans_table():
    c = sqrt(3 / (4 * pi))
    d = _random_dirs(10)
    y = sh_basis(d, 2)
    np.testing.assert_allclose(y[:, 0], 0.5 / sqrt(pi))
    np.testing.assert_allclose(y[:, 1:], np.stack([-c * d[:, 1], c * d[:, 2], -c * d[:, 0]], axis=1), atol=1e-12)


def test_constant_environment_projects_to_coefficient_zero_only():
    faces = np.broadcast_to(np.array([0.2, 0.5, 1.5]), (6, 32, 32, 3))
    coeffs = project_cubemap(faces, 5)
    np.testing.assert_allclose(coeffs[0], np.array([0.2, 0.5, 1.5]) * sqrt(4 * pi), rtol=1e-6)
    # the only leak is the cube's quadrature error into the cubic-symmetric l = 4 terms
    assert (np.abs(coeffs[1:]) / coeffs[0]).max() < 2e-4
    # and irradiance of a constant environment c is c * pi everywhere
    np.testing.assert_allclose(irradiance_from_sh(coeffs, _random_dirs(20)), np.tile([0.2, 0.5, 1.5], (20, 1)) * pi,
                               rtol=1e-4)


def test_single_texel_projects_to_basis_at_its_direction_times_solid_angle():
    size = 64
    faces = np.zeros((6, size, size, 1))
    faces[2, 10, 40] = 1.0
    coeffs = project_cubemap(faces, 5)[:, 0]
    d = cube_directions(size)[2, 10, 40]
    w = cube_solid_angles(size)[2, 10, 40]
    # texel-integrated basis: equal to the point value at its centre up to its variation across 1.4 deg
    np.testing.assert_allclose(coeffs, sh_basis(d, 5) * w, rtol=5e-3, atol=1e-3 * w)
    assert coeffs[0] == pytest.approx(0.5 / sqrt(pi) * w, rel=1e-6)
    face, row, col = texel_from_direction(d, size)
    assert (int(face), round(float(row)), round(float(col))) == (2, 10, 40)


def test_band_limited_function_is_reconstructed_exactly():
    rng = np.random.default_rng(3)
    truth = rng.normal(size=(25, 2))
    faces = radiance_from_sh(truth, cube_directions(128))
    coeffs = project_cubemap(faces, 5)
    np.testing.assert_allclose(coeffs, truth, atol=2e-3 * np.abs(truth).max())
    d = _random_dirs(100, seed=5)
    np.testing.assert_allclose(radiance_from_sh(coeffs, d), radiance_from_sh(truth, d), atol=1e-2)


def test_cosine_lobe_matches_numerical_legendre_integral():
    # A_l = 2 pi int_0^1 t P_l(t) dt (Funk-Hecke on the clamped cosine)
    from numpy.polynomial import legendre
    t = np.linspace(0, 1, 200001)
    for l, a in enumerate(cosine_lobe(7)):
        p = legendre.legval(t, np.eye(7)[l])
        assert a == pytest.approx(2 * pi * np.trapezoid(t * p, t), abs=1e-6), l
    assert cosine_lobe(5)[[0, 1, 2, 3, 4]] == pytest.approx([pi, 2 * pi / 3, pi / 4, 0, -pi / 24])


def test_irradiance_matches_brute_force_cosine_sum_on_smooth_map():
    size = 48
    dirs = cube_directions(size)
    omega = cube_solid_angles(size)
    rng = np.random.default_rng(7)
    lobes = _random_dirs(3, seed=11)
    # smooth, positive, not band-limited: broad exponential lobes plus a sky gradient
    faces = 0.3 + 0.1 * dirs[..., 2:3] + sum(rng.uniform(0.5, 1.5, 3) * np.exp(2.0 * (dirs @ lobe - 1))[..., None]
                                              for lobe in lobes)
    coeffs = project_cubemap(faces, 5)
    normals = _random_dirs(40, seed=13)
    cos = np.clip(np.einsum("nk,fijk->nfij", normals, dirs), 0, None)
    brute = np.einsum("nfij,fij,fijc->nc", cos, omega, faces)
    ours = irradiance_from_sh(coeffs, normals)
    rel = np.abs(ours - brute) / brute
    assert rel.max() < 0.01, rel.max()
