"""``probeless.envmap.metrics.ssim_image`` against scikit-image's ``structural_similarity``.

With Wang et al.'s settings (Gaussian window sigma 1.5, truncated at 3.5 sigma = radius 5, i.e. 11 x 11;
population covariances; K1 0.01, K2 0.03) scikit-image filters with ``scipy.ndimage`` in ``reflect`` mode
(half-sample symmetric, as OpenCV's ``BORDER_REFLECT``) and averages the SSIM map without its 5-pixel
border, per channel, then over channels: the same definition as ``ssim_image``.
"""

from __future__ import annotations

import numpy as np
import pytest
from skimage.metrics import structural_similarity

from probeless.envmap.metrics import ssim_image


def reference(x: np.ndarray, y: np.ndarray, data_range: float) -> float:
    return float(structural_similarity(x, y, data_range=data_range, gaussian_weights=True, sigma=1.5,
                                       use_sample_covariance=False,
                                       channel_axis=-1 if np.ndim(x) == 3 else None))


def structured(h: int, w: int) -> np.ndarray:
    """(H, W, 3) smooth gradients, a checkerboard, a bright disc and a sharp edge in [0, 1]."""
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    checker = ((u // 8 + v // 8) % 2) * 0.5
    disc = (np.hypot(u - w / 3, v - h / 2) < min(h, w) / 5).astype(np.float64)
    edge = (u > 0.7 * w).astype(np.float64) * 0.3
    return np.stack([u / w, checker + 0.2 * v / h, np.clip(disc + edge, 0, 1)], axis=-1)


@pytest.mark.parametrize("shape", [(40, 56, 3), (33, 29, 3), (64, 64)])
def test_ssim_image_matches_skimage_on_random_images(shape):
    rng = np.random.default_rng(sum(shape))
    x = rng.random(shape)
    y = np.clip(x + rng.normal(0, 0.1, shape), 0, 1)
    z = rng.random(shape)  # unrelated: SSIM near 0
    for a, b in ((x, y), (x, z), (y, y)):
        assert ssim_image(a, b, data_range=1.0) == pytest.approx(reference(a, b, 1.0), abs=1e-6)
    assert reference(x, z, 1.0) < 0.1 < 0.99 < reference(y, y, 1.0)


@pytest.mark.parametrize("data_range", [1.0, 4.0, 0.25])
def test_ssim_image_matches_skimage_on_structured_and_hdr_images(data_range):
    x = structured(48, 72) * data_range
    blurred = (x + np.roll(x, 1, axis=0) + np.roll(x, 1, axis=1) + np.roll(x, (1, 1), axis=(0, 1))) / 4
    darker = 0.7 * x
    shifted = np.roll(x, 3, axis=1)
    for y in (blurred, darker, shifted):
        ours, ref = ssim_image(x, y, data_range=data_range), reference(x, y, data_range)
        assert ours == pytest.approx(ref, abs=1e-6)
        assert 0 < ref < 1
    # an HDR pair (values far above 1) compared with the true image's maximum as the data range
    rng = np.random.default_rng(7)
    hdr = structured(40, 40) * rng.uniform(0.5, 20.0, (40, 40, 1))
    est = hdr * rng.uniform(0.8, 1.2, hdr.shape)
    dr = float(hdr.max())
    assert ssim_image(est, hdr, data_range=dr) == pytest.approx(reference(est, hdr, dr), abs=1e-6)
