"""Projection of view samples onto points and the over-exposed transfer, against hand computations."""

import numpy as np
import pytest

from probeless.errors import HdrError
from probeless.hdr import transfer


def test_overexposed_threshold():
    ldr = np.array([[1, 1, 1], [0.9, 0.9, 0.9], [0.95, 0.95, 0.85], [1, 1, 0], [0, 1, 1]], np.float32)
    # Y: 1, 0.9 (not strictly above), 0.2126*.95+0.7152*.95+0.0722*.85 = 0.94278, 0.9278, 0.7874
    np.testing.assert_array_equal(transfer.overexposed(ldr), [True, False, True, True, False])
    np.testing.assert_array_equal(transfer.overexposed(ldr, threshold=0.93), [True, False, True, False, False])


def test_project_plain_mean_by_hand():
    ids0 = np.array([[0, 0], [1, -1]])
    v0 = np.array([[[1, 2, 3], [3, 4, 5]], [[10, 10, 10], [99, 99, 99]]], np.float32)
    ids1 = np.array([[1, 3]])
    v1 = np.array([[[20, 30, 40], [7, 8, 9]]], np.float32)
    mean, count = transfer.project_views([ids0, ids1], [v0, v1], n_points=4)
    np.testing.assert_array_equal(count, [2, 2, 0, 1])
    np.testing.assert_allclose(mean, [[2, 3, 4], [15, 20, 25], [0, 0, 0], [7, 8, 9]])
    assert mean.dtype == np.float32


def test_project_weighted_mean_by_hand():
    ids0 = np.array([[0, 1]])
    v0 = np.array([[[1, 1, 1], [4, 0, 0]]], np.float32)
    ids1 = np.array([[0, -1]])
    v1 = np.array([[[4, 7, 1], [5, 5, 5]]], np.float32)
    ssd0, ssd1 = np.array([[1.0, 0.5]]), np.array([[3.0, 0.0]])
    w0, w1 = transfer.inverse_ssd_weights(ssd0, eps=0), transfer.inverse_ssd_weights(ssd1, eps=1.0)
    mean, count = transfer.project_views([ids0, ids1], [v0, v1], 2, weights_per_view=[w0, w1])
    # point 0: weights 1 and 1/4 -> (1*1 + 0.25*4) / 1.25 = 1.6, (1 + 0.25*7)/1.25 = 2.2, 1
    np.testing.assert_allclose(mean, [[1.6, 2.2, 1.0], [4, 0, 0]], rtol=1e-6)
    np.testing.assert_array_equal(count, [2, 1])


def test_project_background_only_and_no_views():
    mean, count = transfer.project_views([np.full((3, 3), -1)], [np.full((3, 3, 3), np.nan)], 5)
    np.testing.assert_array_equal(count, 0)
    np.testing.assert_array_equal(mean, 0)
    mean, count = transfer.project_views([], [], 2)
    assert mean.shape == (2, 3) and count.tolist() == [0, 0]


@pytest.mark.parametrize("ids,vals,w,word", [
    (np.array([[5]]), np.ones((1, 1, 3)), None, "ids must be in"),
    (np.array([[-2]]), np.ones((1, 1, 3)), None, "ids must be in"),
    (np.array([[0.0]]), np.ones((1, 1, 3)), None, "integer"),
    (np.array([[0]]), np.ones((1, 2, 3)), None, "does not match"),
    (np.array([[0]]), np.ones((1, 1, 3)), np.array([[0.0]]), "> 0"),
    (np.array([[0]]), np.full((1, 1, 3), np.nan), None, "NaN"),
])
def test_project_bad_input(ids, vals, w, word):
    with pytest.raises(HdrError, match=word):
        transfer.project_views([ids], [vals], 3, weights_per_view=None if w is None else [w])


LDR = np.array([[0.2, 0.4, 0.1], [1.0, 1.0, 1.0], [1.0, 0.95, 0.8], [1.0, 1.0, 0.9]], np.float32)
SAMPLES = np.array([[9, 9, 9], [2.0, 3.0, 4.0], [1.0, 2.0, 0.5], [5, 5, 5]], np.float32)
COUNTS = np.array([1, 2, 1, 0])


def test_rgb_takes_the_sample_colour_times_alpha():
    hdr, valid = transfer.apply_transfer(LDR, SAMPLES, COUNTS, alpha=0.5, mode="rgb")
    np.testing.assert_allclose(hdr[0], LDR[0])  # well exposed: LDR kept even with a sample
    np.testing.assert_allclose(hdr[1], [1.0, 1.5, 2.0])
    np.testing.assert_allclose(hdr[2], [0.5, 1.0, 0.25])
    np.testing.assert_allclose(hdr[3], LDR[3])  # over-exposed, no sample: LDR kept, invalid
    np.testing.assert_array_equal(valid, [True, True, True, False])


def test_lum_keeps_ldr_chromaticity_at_sample_luminance():
    hdr, valid = transfer.apply_transfer(LDR, SAMPLES, COUNTS, alpha=2.0, mode="lum")
    y = lambda c: 0.2126 * c[..., 0] + 0.7152 * c[..., 1] + 0.0722 * c[..., 2]  # noqa: E731
    for i in (1, 2):
        assert y(hdr[i]) == pytest.approx(y(2.0 * SAMPLES[i]), rel=1e-6)
        np.testing.assert_allclose(hdr[i] / hdr[i].sum(), LDR[i] / LDR[i].sum(), rtol=1e-6)
    np.testing.assert_allclose(hdr[[0, 3]], LDR[[0, 3]])
    np.testing.assert_array_equal(valid, [True, True, True, False])


def test_photo_samples_are_continuous_at_the_threshold():
    """Cloud = clamp(alpha I); samples of I: a transferred point equals alpha * I, as an unclipped one."""
    alpha = 0.25
    radiance = np.array([[3.2, 3.2, 3.2], [3.8, 3.8, 3.8], [40.0, 30.0, 20.0]], np.float32)
    ldr = np.clip(alpha * radiance, 0, 1)
    hdr, valid = transfer.apply_transfer(ldr, radiance, np.ones(3, int), alpha=alpha)
    np.testing.assert_allclose(hdr, alpha * radiance, rtol=1e-6)
    assert valid.all()


def test_apply_transfer_bad_input():
    with pytest.raises(HdrError, match="mode"):
        transfer.apply_transfer(LDR, SAMPLES, COUNTS, mode="xyz")
    with pytest.raises(HdrError, match="alpha"):
        transfer.apply_transfer(LDR, SAMPLES, COUNTS, alpha=0.0)
    with pytest.raises(HdrError, match="hdr_samples"):
        transfer.apply_transfer(LDR, SAMPLES[:2], COUNTS)
    with pytest.raises(HdrError, match="counts"):
        transfer.apply_transfer(LDR, SAMPLES, COUNTS[:2])


def test_landis_pc_by_formula():
    """Landis (threshold 0.5, alpha 2, max 10): Lw = Ld (1 - k + 10 k), k = ((Ld - 0.5) / 0.5)^2."""
    pts = np.array([[0.3, 0.3, 0.3], [0.75, 0.75, 0.75], [1, 1, 1], [0, 0, 0]], np.float32)
    out = transfer.expand_points(pts, "landis", max_lum=10.0)
    k = ((0.75 - 0.5) / 0.5) ** 2
    np.testing.assert_allclose(out[:, 0], [0.3, 0.75 * (1 - k + 10 * k), 10.0, 0.0], rtol=1e-5)
    np.testing.assert_allclose(out[:, 0], out[:, 1])


def test_banterle_pc_expands_white_to_max_and_keeps_black():
    pts = np.array([[0.1, 0.1, 0.1]] * 20 + [[1, 1, 1]] + [[0, 0, 0]], np.float32)
    pos = np.arange(len(pts), dtype=np.float32)[:, None] * np.array([[1.0, 0.0, 0.0]], np.float32)
    out = transfer.expand_points(pts, "banterle", max_lum=10.0, points=pos)
    assert out.shape == pts.shape
    np.testing.assert_allclose(out[20], 10.0, rtol=1e-5)  # E = 1 at the over-exposed point
    np.testing.assert_array_equal(out[21], 0.0)


def test_expand_with_operator_view_and_checks():
    view = np.zeros((4, 6, 3), np.float32)
    view[1:3, 2:4] = 1.0
    out = transfer.expand_with_operator(view, "landis", max_lum=20.0)
    np.testing.assert_allclose(out[1:3, 2:4], 20.0, rtol=1e-5)
    np.testing.assert_array_equal(out[0], 0.0)
    with pytest.raises(HdrError, match="unknown expansion operator"):
        transfer.expand_with_operator(view, "paper", max_lum=10.0)
    with pytest.raises(HdrError, match="0..1"):
        transfer.expand_with_operator(view * 2, "landis", max_lum=10.0)


def _cluster(indices):
    from probeless.hdr.views import SaturatedCluster

    idx = np.asarray(indices)
    return SaturatedCluster(idx, np.zeros(3), 1.0, None)


def test_cluster_outliers_are_rejected_and_real_variation_kept():
    rng = np.random.default_rng(0)
    n = 200
    # cluster A: an emitter at 4.6 with a lamp's 20.2 fetched into 10 % of it (PatchMatch's clipped ambiguity)
    a = np.full(n, 4.6)
    a[rng.choice(n, 20, replace=False)] = 20.2
    # cluster B: a window whose radiance really varies by 1.8x (a sky gradient): nothing is rejected
    b = np.linspace(3.0, 5.4, n)
    y = np.concatenate([a, b, [7.0, 1.0]])  # + a 2-point cluster C, left alone
    hdr = np.repeat(y[:, None], 3, axis=1).astype(np.float32)
    valid = np.ones(len(y), bool)
    valid[5] = False  # a point without a value stays without one
    clusters = [_cluster(np.arange(n)), _cluster(np.arange(n, 2 * n)), _cluster([2 * n, 2 * n + 1])]
    v, rejected = transfer.reject_cluster_outliers(hdr, valid, clusters)
    lamp = np.flatnonzero(a == 20.2)
    assert rejected == len(lamp) - (5 in lamp)
    assert not v[lamp].any() and v[np.setdiff1d(np.arange(n), np.append(lamp, 5))].all() and not v[5]
    assert v[n:].all()
    # the input mask is not modified
    assert valid.sum() == len(y) - 1


def test_cluster_outliers_spread_widens_the_band():
    # a cluster whose values spread over 2 stops (MAD-scaled band wider than the factor) loses only far outliers
    y = np.exp(np.random.default_rng(1).normal(np.log(4.0), 0.5, 400))
    y[:4] = 4.0 * 40
    hdr = np.repeat(y[:, None], 3, axis=1).astype(np.float32)
    v, rejected = transfer.reject_cluster_outliers(hdr, np.ones(400, bool), [_cluster(np.arange(400))])
    med = np.median(np.log(y))
    band = 3 * 1.4826 * np.median(np.abs(np.log(y) - med))
    np.testing.assert_array_equal(v, np.abs(np.log(y) - med) <= band)
    assert not v[:4].any() and 4 <= rejected < 20


def test_cluster_outliers_bad_input():
    hdr = np.ones((4, 3), np.float32)
    with pytest.raises(HdrError, match="valid"):
        transfer.reject_cluster_outliers(hdr, np.ones(3, bool), [])
    with pytest.raises(HdrError, match="factor"):
        transfer.reject_cluster_outliers(hdr, np.ones(4, bool), [], factor=1.0)
