"""Inverse tone mapping operators against hand-computed values of their published formulas."""

import numpy as np
import pytest

from probeless.errors import ProbelessError
from probeless.pano import itmo


def grey(*values):
    return np.repeat(np.asarray(values, dtype=np.float64)[:, None], 3, axis=1)


def test_paper_eq_1_to_3_analytic():
    ldr = np.array([[1.0, 1.0, 1.0], [0.5, 0.5, 0.5], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0, 0, 0]])
    out = itmo.paper_itmo(ldr)
    # L = 1 -> Ls = 11.8; L = 0.5 -> 10 / 1024 + 1.8; L = 0.3 (pure red), L = 0.59 (pure green)
    np.testing.assert_allclose(out[0], [11.8] * 3, rtol=1e-6)
    np.testing.assert_allclose(out[1], [0.5 * (10 / 1024 + 1.8)] * 3, rtol=1e-6)
    np.testing.assert_allclose(out[2], [10 * 0.3 ** 10 + 1.8, 0, 0], rtol=1e-6)
    np.testing.assert_allclose(out[3], [0, 10 * 0.59 ** 10 + 1.8, 0], rtol=1e-6)
    np.testing.assert_array_equal(out[4], 0)


def test_landis_analytic():
    out = itmo.landis_itmo(grey(0.25, 0.5, 0.75, 1.0), max_lum=10.0, threshold=0.5, alpha=2.0)
    # below/at R unchanged; 0.75: k = (0.25 / 0.5)^2 = 0.25 -> 0.75 * 0.75 + 0.25 * 10 * 0.75
    np.testing.assert_allclose(out[:, 1], [0.25, 0.5, 0.75 * 0.75 + 0.25 * 7.5, 10.0], rtol=1e-6)


def test_akyuz_analytic_and_chroma():
    ldr = np.array([[0, 0, 0], [0.5, 0.5, 0.5], [1, 1, 1], [0.6, 0.3, 0.1]])
    out = itmo.akyuz_itmo(ldr, max_lum=10.0, gamma=2.0)
    np.testing.assert_allclose(out[:3, 0], [0.0, 2.5, 10.0], rtol=1e-6)
    lum = 0.2126 * 0.6 + 0.7152 * 0.3 + 0.0722 * 0.1
    np.testing.assert_allclose(out[3], np.array([0.6, 0.3, 0.1]) * 10 * lum ** 2 / lum, rtol=1e-5)


def test_inverse_reinhard_inverts_reinhard_forward():
    lw = np.linspace(0.0, 10.0, 21)
    l_white, max_lum = 4.0, 10.0
    lm = lw * l_white / max_lum  # Reinhard 2002 global operator with white point l_white
    ld = lm * (1 + lm / l_white ** 2) / (1 + lm)
    np.testing.assert_allclose(itmo.inverse_reinhard(ld, max_lum, l_white), lw, rtol=1e-4, atol=1e-5)
    np.testing.assert_allclose(itmo.inverse_reinhard(np.array([0.0, 1.0]), 10.0, 10.0), [0, 10], atol=1e-5)


def test_banterle_expand_map_regions():
    dark = np.full((20, 40, 3), 0.5)
    np.testing.assert_allclose(itmo.banterle_expand_map(dark), dark, rtol=1e-6)
    bright = np.full((20, 40, 3), 0.95)
    expect = itmo.inverse_reinhard(np.float32(0.95), 10.0, 10.0)
    np.testing.assert_allclose(itmo.banterle_expand_map(bright), expect, rtol=1e-5)
    spot = dark.copy()
    spot[8:12, 2:6] = 1.0
    out = itmo.banterle_expand_map(spot, sigma_frac=0.02)
    assert out[9, 3, 0] > 5.0  # in the bright spot: expanded towards max_lum
    np.testing.assert_allclose(out[10, 35], 0.5, rtol=1e-3)  # far away: LDR kept


@pytest.mark.parametrize("name", sorted(itmo.ITMO))
def test_monotonic_in_luminance(name):
    g = np.linspace(0.0, 1.0, 101)
    if name == "banterle":  # spatial operator: one flat (all-bright or all-dark) frame per level
        lum = np.array([itmo.apply_itmo(name, np.full((4, 8, 3), v))[0, 0, 0] for v in g])
    else:
        lum = itmo.apply_itmo(name, grey(*g))[:, 1]
    assert np.all(np.diff(lum[g > 0.9]) > 0)
    assert np.all(np.diff(lum) >= -1e-6)
    assert lum[-1] > 1.0  # every operator expands the top of the range


@pytest.mark.parametrize("name", sorted(itmo.ITMO))
def test_shape_and_dtype(name):
    ldr = np.random.default_rng(1).random((6, 12, 3))
    out = itmo.apply_itmo(name, ldr)
    assert out.shape == ldr.shape and out.dtype == np.float32
    assert np.all(np.isfinite(out)) and np.all(out >= 0)


def test_unknown_name_lists_choices():
    with pytest.raises(ProbelessError, match="drago.*akyuz, banterle, landis, paper"):
        itmo.get_itmo("drago")
    with pytest.raises(ProbelessError, match="RGB"):
        itmo.paper_itmo(np.zeros((4, 4)))
