"""GGX prefiltering (probeless.ibl.ggx) against Karis' (2013) importance-sampled estimator."""

from __future__ import annotations

import numpy as np


def cube(size: int, fn) -> np.ndarray:
    from probeless.geom.cube import cube_directions

    return fn(cube_directions(size)).astype(np.float32)


def karis_prefiltered(fn, r: np.ndarray, roughness: float, n: int = 1 << 14) -> np.ndarray:
    """Karis (2013) PrefilterEnvMap with N = V = R: GGX-importance-sampled h (Hammersley), l = reflect(-v, h),
    sum L(l) (n.l) / sum (n.l); ``fn`` maps (M, 3) unit directions to (M, 3) radiance."""
    a = roughness ** 2
    i = np.arange(n)
    u1 = (i + 0.5) / n
    u2 = np.array([int(format(k, "032b")[::-1], 2) for k in i]) / 2.0 ** 32  # radical inverse, base 2
    phi = 2 * np.pi * u2
    cos_t = np.sqrt((1 - u1) / (1 + (a * a - 1) * u1))
    sin_t = np.sqrt(1 - cos_t ** 2)
    t = np.cross(r, [0.0, 0.0, 1.0] if abs(r[2]) < 0.9 else [1.0, 0.0, 0.0])
    t /= np.linalg.norm(t)
    b = np.cross(r, t)
    h = (sin_t * np.cos(phi))[:, None] * t + (sin_t * np.sin(phi))[:, None] * b + cos_t[:, None] * r
    ln = 2 * (h @ r)[:, None] * h - r
    nl = ln @ r
    keep = nl > 0
    return (fn(ln[keep]) * nl[keep, None]).sum(axis=0) / nl[keep].sum()


def test_ggx_prefilter_matches_karis_importance_sampling_and_keeps_a_constant():
    from probeless.geom.cube import texel_direction
    from probeless.ibl.ggx import ggx_prefilter, ggx_weights

    a = np.array([0.6, -0.3, 0.74])

    def fn(d):
        return np.stack([np.exp(3 * d @ a), 1 + d[..., 0] ** 2, np.exp(-2 * d[..., 2])], axis=-1)

    faces = cube(32, fn)
    pre = ggx_prefilter(faces, 0.3)
    assert pre.shape == (6, 32, 32, 3) and pre.dtype == np.float32
    np.testing.assert_allclose(ggx_weights(32, 0.3).sum(axis=1), 1.0, atol=1e-5)
    for f, row, col in [(0, 5, 9), (2, 16, 16), (4, 0, 31), (5, 20, 3), (3, 31, 31)]:
        r = texel_direction(f, row, col, 32)
        ref = karis_prefiltered(fn, r, 0.3)
        np.testing.assert_allclose(pre[f, row, col], ref, rtol=1e-3)
        assert np.abs(faces[f, row, col] / ref - 1).max() > 0.02  # the lobe did blur (the map, unfiltered, differs)
    # a rougher lobe moves the prefiltered value further from the texel's own radiance
    small = cube(16, fn)
    err = [np.abs(ggx_prefilter(small, rough) - small).mean() for rough in (0.15, 0.3, 0.6)]
    assert err[0] < err[1] < err[2]
    # 64-px faces are box-averaged to 32 first; a constant stays constant
    const = ggx_prefilter(np.full((6, 64, 64, 3), [0.5, 2.0, 7.0], np.float32), 0.3)
    assert const.shape == (6, 32, 32, 3)
    np.testing.assert_allclose(const, np.broadcast_to([0.5, 2.0, 7.0], const.shape), rtol=1e-5)
