"""Poisson filling (paper 001 §4.2, Eq. 2-3) against brute-force kNN, a dense loop-built system,
nearest-neighbour copying, and exactly reproducible fields."""

import numpy as np
import pytest
from scipy.spatial import cKDTree
from scipy.spatial.distance import cdist

from probeless.errors import HdrError
from probeless.hdr import poisson


def _brute_knn(p, k):
    d = cdist(p, p)
    np.fill_diagonal(d, np.inf)
    return [set(np.argsort(d[i], kind="stable")[:k]) for i in range(len(p))]


def test_knn_graph_matches_brute_force_and_excludes_self():
    p = np.random.default_rng(0).uniform(0, 1, (300, 3))
    nb = poisson.knn_graph(p, k=16)
    assert nb.shape == (300, 16)
    assert not (nb == np.arange(300)[:, None]).any()
    assert [set(r) for r in nb] == _brute_knn(p, 16)


def test_knn_graph_duplicates_and_small_clouds():
    p = np.zeros((5, 3))
    nb = poisson.knn_graph(p, k=16)  # k clipped to N - 1; coincident points, still never self
    assert nb.shape == (5, 4)
    assert all(set(r) == set(range(5)) - {i} for i, r in enumerate(nb))
    with pytest.raises(HdrError, match="at least 2"):
        poisson.knn_graph(np.zeros((1, 3)))


def _dense_reference(p, hdr, ldr, valid, k, symmetric):
    """Eq. 2 built point by point with Python loops and solved densely (np.linalg.solve)."""
    nbrs = _brute_knn(p, k)
    if symmetric:
        nbrs = [nbrs[i] | {j for j in range(len(p)) if i in nbrs[j]} for i in range(len(p))]
    omega = np.flatnonzero(~valid)
    col = {q: c for c, q in enumerate(omega)}
    a = np.zeros((len(omega), len(omega)))
    b = np.zeros((len(omega), 3))
    for r, i in enumerate(omega):
        a[r, r] = len(nbrs[i])
        for q in nbrs[i]:
            if valid[q]:
                b[r] += hdr[q]
            else:
                a[r, col[q]] -= 1
            b[r] += ldr[i] - ldr[q]
    out = np.where(valid[:, None], hdr, 0.0)
    out[omega] = np.linalg.solve(a, b)
    return out


@pytest.mark.parametrize("symmetric", [True, False])
def test_matches_dense_loop_built_system(symmetric):
    rng = np.random.default_rng(1)
    p = rng.uniform(0, 1, (80, 3))
    ldr = rng.uniform(0, 1, (80, 3))
    hdr = ldr + rng.uniform(0, 2, (80, 3))
    valid = p[:, 0] > 0.3  # a slab of Omega, anchored on one side
    out, rep = poisson.poisson_fill(p, hdr, ldr, valid, k=6, symmetric=symmetric)
    ref = _dense_reference(p, hdr, ldr, valid, 6, symmetric)
    if rep.clipped_negative == 0:
        np.testing.assert_allclose(out, ref, rtol=1e-5, atol=1e-5)
    else:
        np.testing.assert_allclose(out, np.maximum(ref, 0), rtol=1e-5, atol=1e-5)
    assert rep.filled == int((~valid).sum()) and rep.left_ldr == 0 and rep.unanchored_components == 0


def _field(p, amp):
    """Smooth RGB field: a Gaussian bump of height ``amp`` on a slow wave, 0.2 .. ~0.6 + amp."""
    x, y, z = p.T
    base = 0.2 + amp * np.exp(-((x - 0.5) ** 2 + (y - 0.5) ** 2) / 0.08) + 0.3 * np.sin(3 * z + 2 * x)
    return np.stack([base + 0.3 * z, 0.9 * base + 0.2 * y, 0.7 * base + 0.4 * x], 1)


def _fill_vs_copy(seed, amp):
    """RMS of the fill and of the nearest-valid copy on 20k points, LDR = clamp(HDR, 0, 1), 30 % removed
    in blobs (the points nearest to 12 random centres)."""
    rng = np.random.default_rng(seed)
    p = rng.uniform(0, 1, (20000, 3))
    hdr = _field(p, amp)
    ldr = np.clip(hdr, 0, 1)
    d, _ = cKDTree(rng.uniform(0.1, 0.9, (12, 3))).query(p)
    valid = d > np.quantile(d, 0.3)
    out, rep = poisson.poisson_fill(p, np.where(valid[:, None], hdr, np.nan), ldr, valid, k=16)
    miss = ~valid
    _, j = cKDTree(p[valid]).query(p[miss])
    np.testing.assert_array_equal(out[valid], hdr[valid].astype(np.float32))
    assert rep.filled == int(miss.sum()) and rep.left_ldr == 0 and rep.components >= 1
    return np.sqrt(np.mean((out[miss] - hdr[miss]) ** 2)), np.sqrt(np.mean((hdr[valid][j] - hdr[miss]) ** 2))


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_fill_beats_nearest_valid_copy_by_half(seed):
    """Bump up to 1.17 (about 4 % of the points clipped in the LDR): fill RMS <= 0.5 x copy RMS.

    (Measured: 0.08, 0.17, 0.08 of the copy's RMS for seeds 0-2; 0.04-0.25 for seeds 0-11.)
    """
    rms, rms_copy = _fill_vs_copy(seed, amp=0.6)
    assert rms <= 0.5 * rms_copy


@pytest.mark.parametrize("seed", [0, 1])
def test_fill_beats_copy_under_heavy_clipping(seed):
    """Bump up to 1.77 (about 21 % clipped): inside a clipped blob the LDR has no gradient, Eq. 2 is
    Laplace's equation there and no bump can be recovered, so we only ask fill RMS < copy RMS.

    (Measured: 0.38, 0.61 of the copy's RMS for seeds 0-1; 0.32-0.84 for seeds 0-9.)
    """
    rms, rms_copy = _fill_vs_copy(seed, amp=1.2)
    assert rms < rms_copy


@pytest.mark.parametrize("mode", ["rgb", "lum"])
@pytest.mark.parametrize("symmetric", [True, False])
def test_field_with_ldr_gradient_is_reproduced_exactly(mode, symmetric):
    """HDR = LDR + constant: Eq. 2 holds exactly for the true values, so they are the solution."""
    rng = np.random.default_rng(2)
    p = rng.uniform(0, 1, (3000, 3))
    grey = 0.3 + 0.2 * np.sin(4 * p[:, 0]) * np.cos(3 * p[:, 1])
    ldr = np.stack([grey, grey, grey], 1) if mode == "lum" else rng.uniform(0.1, 0.6, (3000, 3))
    hdr = ldr + 0.75
    valid = np.linalg.norm(p - 0.5, axis=1) > 0.3
    out, rep = poisson.poisson_fill(p, hdr, ldr, valid, mode=mode, symmetric=symmetric)
    np.testing.assert_allclose(out, hdr, rtol=1e-5, atol=1e-5)
    assert rep.clipped_negative == 0


def test_unanchored_component_keeps_ldr_and_is_counted():
    rng = np.random.default_rng(3)
    main = rng.uniform(0, 1, (500, 3))
    island = rng.uniform(0, 0.05, (30, 3)) + 10.0  # far away: its 16 neighbours are its own 29 points
    p = np.vstack([main, island])
    ldr = rng.uniform(0, 1, (530, 3))
    hdr = ldr * 3
    valid = np.ones(530, bool)
    valid[500:] = False
    valid[:40] = False  # an anchored hole in the main cloud as well
    out, rep = poisson.poisson_fill(p, hdr, ldr, valid)
    np.testing.assert_array_equal(out[500:], ldr[500:].astype(np.float32))
    assert rep.left_ldr == 30 and rep.unanchored_components == 1
    assert rep.filled == 40 and rep.components >= 2
    assert rep.as_dict()["left_ldr"] == 30


def test_all_valid_is_unchanged():
    rng = np.random.default_rng(4)
    p, ldr = rng.uniform(0, 1, (100, 3)), rng.uniform(0, 1, (100, 3))
    hdr = ldr * 5
    out, rep = poisson.poisson_fill(p, hdr, ldr, np.ones(100, bool))
    np.testing.assert_array_equal(out, hdr.astype(np.float32))
    assert rep.as_dict() == {"filled": 0, "left_ldr": 0, "components": 0, "unanchored_components": 0,
                             "clipped_negative": 0}


def test_bad_input():
    p = np.zeros((4, 3))
    c = np.ones((4, 3))
    with pytest.raises(HdrError, match="valid"):
        poisson.poisson_fill(p, c, c, np.ones(4))
    with pytest.raises(HdrError, match="ldr"):
        poisson.poisson_fill(p, c, np.full((4, 3), np.nan), np.ones(4, bool))
    with pytest.raises(HdrError, match="mode"):
        poisson.poisson_fill(p, c, c, np.ones(4, bool), mode="hsv")
