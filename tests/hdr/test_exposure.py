"""Exposure matching (paper 001 §4.1) against known exposures, numpy's histogram and scipy's Wasserstein."""

import numpy as np
import pytest
from scipy.stats import wasserstein_distance

from probeless.color import from_srgb8, to_srgb8
from probeless.errors import HdrError
from probeless.hdr import exposure


def _photo(seed=1, h=192, w=256):
    """Log-normal radiance (about 5 decades) with random chromaticity, (h, w, 3) float32."""
    rng = np.random.default_rng(seed)
    y = np.exp(rng.normal(np.log(0.3), 1.6, size=(h, w)))
    return (y[..., None] * rng.uniform(0.6, 1.4, size=(h, w, 3))).astype(np.float32)


def test_luminance_weights():
    rgb = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1], [0.5, 0.25, 2.0]], np.float32)
    ref = [0.2126, 0.7152, 0.0722, 1.0, 0.5 * 0.2126 + 0.25 * 0.7152 + 2.0 * 0.0722]
    np.testing.assert_allclose(exposure.luminance(rgb), ref, rtol=1e-6)
    assert exposure.luminance(np.zeros((4, 5, 3))).shape == (4, 5)


def test_histogram_matches_numpy():
    y = np.random.default_rng(0).uniform(-0.2, 1.3, 5000)
    ref, _ = np.histogram(np.clip(y, 0, 1), bins=128, range=(0, 1))
    h = exposure.luminance_histogram(y)
    np.testing.assert_allclose(h, ref / ref.sum(), atol=1e-12)
    assert h.sum() == pytest.approx(1.0)


def test_histogram_distance_is_scipy_wasserstein_of_bin_centres():
    rng = np.random.default_rng(2)
    a, b = rng.uniform(0, 1, 300), rng.uniform(0, 1, 500) ** 2
    ha, hb = exposure.luminance_histogram(a, 16), exposure.luminance_histogram(b, 16)
    ca = (np.floor(a * 16) + 0.5) / 16  # each sample moved to its bin centre, unweighted
    cb = (np.floor(b * 16) + 0.5) / 16
    assert exposure.histogram_distance(ha, hb) == pytest.approx(wasserstein_distance(ca, cb), rel=1e-9)


def test_fixed_exposures_span_the_photo():
    img = _photo()
    y = exposure.luminance(img)
    a = exposure.fixed_exposures(img)
    np.testing.assert_allclose(a[1:] / a[:-1], 2.0)
    assert a[0] * y.max() < 1 / 128  # darkest: all in the first bin
    assert a[-1] * y[y > 0].min() >= 1.0  # brightest: everything clips


@pytest.mark.parametrize("alpha0", [0.02, 0.2, 2.0, 20.0])
def test_exact_cloud_recovers_alpha(alpha0):
    img = _photo()
    px = img.reshape(-1, 3)[np.random.default_rng(3).permutation(img.shape[0] * img.shape[1])]
    m = exposure.match_exposure(img, np.clip(alpha0 * px, 0, 1))
    assert m.alpha == pytest.approx(alpha0, rel=1e-3)
    np.testing.assert_allclose(m.ldr_image, np.clip(np.float32(m.alpha) * img, 0, 1), rtol=1e-6)


@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("alpha0", [0.02, 0.2, 2.0, 20.0])
def test_sampled_quantised_cloud_recovers_alpha(alpha0, seed):
    """Half of the pixels, exposed by alpha0, clamped and stored as 8-bit sRGB: alpha within 5 %."""
    img = _photo()
    n = img.shape[0] * img.shape[1]
    px = img.reshape(-1, 3)[np.random.default_rng(seed).permutation(n)[: n // 2]]
    cloud = from_srgb8(to_srgb8(alpha0 * px))
    m = exposure.match_exposure(img, cloud)
    assert m.alpha == pytest.approx(alpha0, rel=0.05)
    assert m.distance <= m.candidates[:, 1].min()
    assert 0 <= m.steps <= 50
    k = int(np.argmin(m.candidates[:, 1]))
    assert m.candidates[k, 0] / 2 <= m.alpha <= m.candidates[k, 0] * 2


def test_max_steps_zero_gives_best_fixed_exposure():
    img = _photo()
    cloud = np.clip(0.3 * img.reshape(-1, 3), 0, 1)
    m = exposure.match_exposure(img, cloud, exposures=[0.125, 0.25, 0.5, 1.0], max_steps=0)
    assert m.steps == 0 and m.alpha == pytest.approx(0.25)
    assert m.distance == pytest.approx(m.candidates[1, 1])


@pytest.mark.parametrize("cloud,word", [
    (np.zeros((0, 3)), "empty"),
    (np.array([[0.1, np.nan, 0.2]]), "NaN"),
    (np.array([[0.1, -0.1, 0.2]]), "negative"),
    (np.array([[0.1, 1.5, 0.2]]), "0..1"),
    (np.zeros((4, 2)), "shape"),
])
def test_bad_cloud_raises_naming_it(cloud, word):
    with pytest.raises(HdrError, match=f"cloud_rgb_linear.*{word}"):
        exposure.match_exposure(_photo(h=8, w=8), cloud)


@pytest.mark.parametrize("img,word", [
    (np.zeros((0, 4, 3)), "empty"),
    (np.full((4, 4, 3), np.inf), "infinite"),
    (-np.ones((4, 4, 3)), "negative"),
    (np.ones((16, 3)), "shape"),
])
def test_bad_photo_raises_naming_it(img, word):
    with pytest.raises(HdrError, match=f"hdr_image.*{word}"):
        exposure.match_exposure(img, np.full((5, 3), 0.5))


def test_black_photo_raises():
    with pytest.raises(HdrError, match="black"):
        exposure.match_exposure(np.zeros((4, 4, 3)), np.full((5, 3), 0.5))
