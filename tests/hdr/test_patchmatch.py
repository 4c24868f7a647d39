"""Generalized PatchMatch (paper 001, §4.1; Barnes et al. 2010): quality against the exact field, recovery of known
translations and of a rotation + scale, HDR fetch through a field, argument checks."""

from __future__ import annotations

import math

import cv2
import numba
import numpy as np
import pytest

from probeless.errors import HdrError
from probeless.hdr import patchmatch_kernels as _k
from probeless.hdr.patchmatch import (
    Field,
    exhaustive_nnf,
    fetch,
    identity_field,
    patchmatch,
    synthetic_texture,
    time_patchmatch,
)

R = 3  # radius of the default 7x7 patch


@pytest.fixture(scope="module")
def texture() -> np.ndarray:
    return synthetic_texture(160, 288, seed=11)


@pytest.mark.slow
@pytest.mark.parametrize("mode", ["rgb", "lum"])
def test_translation_quality_vs_exhaustive(texture, mode):
    # two disjoint 128^2 crops of one texture: the exact field has no zero-SSD matches
    src = texture[:128, :128]
    tgt = texture[16:144, 152:280]
    exact = exhaustive_nnf(src, tgt, 7, mode=mode)
    field = patchmatch(src, tgt, angles=None, scales=None, mode=mode)  # 5 iterations, as expand_cloud
    # the exact field is a lower bound everywhere (same SSD definition)
    assert np.all(field.ssd >= exact.ssd - 1e-4)
    quality = float(exact.ssd.mean() / field.ssd.mean())
    # measured 0.967 (rgb), 0.917 (lum; 0.83 before the global samples); goal >= 0.9 (issue 15)
    assert quality >= 0.9, quality
    assert field.xy.dtype == np.float32 and field.xy.shape == (128, 128, 2)
    assert np.all(field.xy == np.round(field.xy)) and np.all(field.angle == 0) and np.all(field.scale == 1)
    assert (field.patch, field.iterations, field.mode, field.target_shape) == (7, 5, mode, (128, 128))
    # the generalized field searches a superset: measured 0.86 (rgb), 0.91 (lum) of the exact translation SSD
    general = patchmatch(src, tgt, mode=mode)
    assert general.ssd.mean() < 1.0 * exact.ssd.mean()


def test_box_means_and_mean_bound():
    rng = np.random.default_rng(4)
    t = rng.random((23, 31, 4)).astype(np.float32)
    sizes = np.array([3, 7, 11], np.int64)
    got = _k.box_means(t, sizes).reshape(3, 23, 31, 4)
    for k, q in enumerate(sizes):
        r = int(q) // 2
        padded = np.pad(t.astype(np.float64), ((r, r), (r, r), (0, 0)), mode="edge")
        ref = sum(padded[j:j + 23, i:i + 31] for j in range(q) for i in range(q)) / q ** 2
        np.testing.assert_allclose(got[k], ref, atol=1e-6)
    # the mean test's bound p^2 |mean difference|^2 never exceeds the SSD of a translated (edge-padded) patch pair
    src, tgt = t[:16, :16, :3], t[5:, 9:, :3]
    means = _k.box_means(np.ascontiguousarray(tgt), np.array([7], np.int64))
    sp = np.pad(src, ((R, R), (R, R), (0, 0)), mode="edge")
    tp = np.pad(tgt, ((R, R), (R, R), (0, 0)), mode="edge")
    for (y, x), (ty, tx) in zip(rng.integers(0, 16, (50, 2)), rng.integers(0, (18, 22), (50, 2))):
        a, b = sp[y:y + 7, x:x + 7], tp[ty:ty + 7, tx:tx + 7]
        mu = a.reshape(-1, 3).mean(0).astype(np.float64)
        bound = _k._mean_bound(mu, means, (ty * tgt.shape[1] + tx) * 3, 3, 49.0)
        assert bound <= float(((a - b) ** 2).sum()) * (1 + 1e-5) + 1e-9


@pytest.mark.parametrize("mode", ["rgb", "lum"])
def test_recovers_known_translation(texture, mode):
    dy, dx = 9, -14
    src = texture[12:140, 20:148]
    tgt = texture[12 + dy:140 + dy, 20 + dx:148 + dx]  # tgt[y - dy, x - dx] == src[y, x]
    field = patchmatch(src, tgt, angles=None, scales=None, mode=mode)
    ys, xs = np.mgrid[0:128, 0:128]
    ex, ey = xs - dx, ys - dy
    interior = (ex >= R) & (ex < 128 - R) & (ey >= R) & (ey < 128 - R)
    interior &= (xs >= R) & (xs < 128 - R) & (ys >= R) & (ys < 128 - R)
    hit = (field.xy[..., 0] == ex) & (field.xy[..., 1] == ey)
    assert hit[interior].mean() >= 0.95
    assert np.all(field.ssd[hit & interior] < 1e-9)


@pytest.fixture(scope="module")
def rotated() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    n = 128
    src = synthetic_texture(n, n, seed=3)
    m = cv2.getRotationMatrix2D((n / 2, n / 2), 20, 1.2)  # tgt(M p) = src(p)
    tgt = cv2.warpAffine(src, m, (n, n), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    ys, xs = np.mgrid[0:n, 0:n]
    ex = m[0, 0] * xs + m[0, 1] * ys + m[0, 2]
    ey = m[1, 0] * xs + m[1, 1] * ys + m[1, 2]
    margin = R * 1.2 * math.sqrt(2) + 2
    interior = (ex > margin) & (ex < n - 1 - margin) & (ey > margin) & (ey < n - 1 - margin)
    interior &= (xs >= R) & (xs < n - R) & (ys >= R) & (ys < n - R)
    return src, tgt, ex, ey, interior


def test_generalized_recovers_rotation_and_scale(rotated):
    src, tgt, ex, ey, interior = rotated
    field = patchmatch(src, tgt)  # defaults: angles +-45 deg, scales 0.67..1.5
    # cv2 turns counter-clockwise on screen for +20 deg: a = -20 deg in the field's convention
    angle_err = np.degrees(np.abs(field.angle - math.radians(-20)))[interior]
    scale_err = np.abs(field.scale / 1.2 - 1)[interior]
    pos_err = np.hypot(field.xy[..., 0] - ex, field.xy[..., 1] - ey)[interior]
    assert np.median(angle_err) < 3.0
    assert np.median(scale_err) < 0.05
    assert np.median(pos_err) < 1.0 and (pos_err < 1.0).mean() > 0.8
    assert field.angle.min() >= -math.pi / 4 - 1e-6 and field.angle.max() <= math.pi / 4 + 1e-6
    assert field.scale.min() >= 0.67 - 1e-6 and field.scale.max() <= 1.5 + 1e-6
    translation = patchmatch(src, tgt, angles=None, scales=None)
    # measured: ~0.0035 vs ~0.074 mean SSD on the interior
    assert field.ssd[interior].mean() < 0.2 * translation.ssd[interior].mean()


@pytest.mark.parametrize("general", [False, True])
def test_large_images_recover_known_warp(general):
    # 256^2: the generalized search is matched at half resolution first, then upsampled (coarse to fine);
    # translation-only matching stays at full resolution
    n = 256
    src = synthetic_texture(n, n, seed=5)
    deg, k = (15, 0.9) if general else (0, 1.0)
    m = cv2.getRotationMatrix2D((n / 2, n / 2), deg, k)
    m[:, 2] += (-11, 7) if not general else (0, 0)
    tgt = cv2.warpAffine(src, m, (n, n), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    ys, xs = np.mgrid[0:n, 0:n]
    ex = m[0, 0] * xs + m[0, 1] * ys + m[0, 2]
    ey = m[1, 0] * xs + m[1, 1] * ys + m[1, 2]
    margin = R * 1.5 + 2
    interior = (ex > margin) & (ex < n - 1 - margin) & (ey > margin) & (ey < n - 1 - margin)
    interior &= (xs >= R) & (xs < n - R) & (ys >= R) & (ys < n - R)
    kw = {} if general else {"angles": None, "scales": None}
    field = patchmatch(src, tgt, **kw)
    if general:
        pos_err = np.hypot(field.xy[..., 0] - ex, field.xy[..., 1] - ey)[interior]
        assert np.median(pos_err) < 1.0
        assert np.median(np.degrees(np.abs(field.angle - math.radians(-deg)))[interior]) < 3.0
        assert np.median(np.abs(field.scale / k - 1)[interior]) < 0.05
        assert field.ssd[interior].mean() < 0.02  # measured 0.008 (0.014 at full resolution only)
        before = numba.get_num_threads()
        numba.set_num_threads(1)
        try:  # the coarse level keeps the field independent of the number of threads
            again = patchmatch(src, tgt, **kw)
        finally:
            numba.set_num_threads(before)
        np.testing.assert_array_equal(again.xy, field.xy)
        np.testing.assert_array_equal(again.ssd, field.ssd)
    else:
        # exact matches everywhere (the reflected border gives some pixels a second, equally exact one)
        assert np.all(field.xy == np.round(field.xy))
        assert (field.ssd[interior] < 1e-9).mean() > 0.99


def test_deterministic_and_thread_independent(rotated):
    src, tgt = rotated[0][:64, :96], rotated[1][:80, :64]
    a = patchmatch(src, tgt, seed=5, iterations=2)
    before = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        b = patchmatch(src, tgt, seed=5, iterations=2)
    finally:
        numba.set_num_threads(before)
    for name in ("xy", "angle", "scale", "ssd"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    c = patchmatch(src, tgt, seed=6, iterations=2)
    assert not np.array_equal(a.xy, c.xy)
    assert a.target_shape == (80, 64) and a.shape == (64, 96)


@pytest.mark.parametrize("general", [False, True])
def test_tiny_images_clamp(general):
    rng = np.random.default_rng(1)
    src = rng.random((2, 5, 3)).astype(np.float32)
    for tgt in (rng.random((1, 1, 3)).astype(np.float32), src):
        kw = {} if general else {"angles": None, "scales": None}
        field = patchmatch(src, tgt, patch=5, mode="lum", **kw)
        assert field.xy.shape == (2, 5, 2) and np.isfinite(field.ssd).all() and (field.ssd >= 0).all()
        assert (field.xy[..., 0] >= 0).all() and (field.xy[..., 0] <= tgt.shape[1] - 1).all()
        assert (field.xy[..., 1] >= 0).all() and (field.xy[..., 1] <= tgt.shape[0] - 1).all()
    if not general:
        np.testing.assert_array_equal(exhaustive_nnf(src, src, 5).ssd, np.zeros((2, 5), np.float32))


def test_fetch_identity_returns_image():
    rng = np.random.default_rng(0)
    hdr = (rng.random((40, 56, 3)) * 50).astype(np.float32)
    field = identity_field(40, 56)
    np.testing.assert_array_equal(fetch(field, hdr), hdr)
    np.testing.assert_array_equal(fetch(field, hdr[..., 1]), hdr[..., 1])


def test_fetch_is_bilinear_and_transfers_hdr(texture):
    img = np.arange(12, dtype=np.float32).reshape(3, 4)
    base = identity_field(3, 4)
    half = Field(**{**base.__dict__, "xy": base.xy + np.float32(0.5)})
    out = fetch(half, img)
    assert out[0, 0] == pytest.approx((0 + 1 + 4 + 5) / 4)
    assert out[2, 3] == img[2, 3]  # clamped at the border
    # HDR transfer (paper 001, Eq. 1): match on I_LDR = clamp(alpha I_HDR), read I_HDR through the field
    src = texture[12:140, 20:148]
    hdr = texture[21:149, 6:134] * 8.0
    field = patchmatch(src, np.clip(hdr / 8.0, 0, 1), angles=None, scales=None)
    got = fetch(field, hdr)
    assert got.shape == src.shape and got.dtype == np.float32
    assert np.median(np.abs(got - src * 8.0)) < 1e-5


def test_time_patchmatch_smoke():
    d = time_patchmatch(32, iterations=1)
    assert d["source_shape"] == (32, 32) and d["target_shape"] == (16, 32) and d["seconds"] > 0


GOOD = np.full((8, 8, 3), 0.5, np.float32)


@pytest.mark.parametrize("kwargs, word", [
    ({"source": np.zeros((8, 8), np.float32)}, "source"),
    ({"target": np.zeros((8, 8, 4), np.float32)}, "target"),
    ({"source": np.zeros((8, 8, 3), np.uint8)}, "source"),
    ({"target": np.where(np.eye(8)[..., None] > 0, np.nan, GOOD).astype(np.float32)}, "target"),
    ({"source": [[0.5, 0.5, 0.5]]}, "source"),
    ({"patch": 4}, "patch"),
    ({"patch": 1}, "patch"),
    ({"patch": True}, "patch"),
    ({"patch": 7.0}, "patch"),
    ({"mode": "xyz"}, "mode"),
    ({"iterations": -1}, "iterations"),
    ({"seed": -3}, "seed"),
    ({"angles": (1.0, -1.0)}, "angles"),
    ({"angles": (0.0, 4.0)}, "angles"),
    ({"angles": 0.5}, "angles"),
    ({"scales": (0.0, 1.5)}, "scales"),
    ({"scales": (1.0, float("nan"))}, "scales"),
])
def test_bad_inputs_raise(kwargs, word):
    args = {"source": GOOD, "target": GOOD, **kwargs}
    src, tgt = args.pop("source"), args.pop("target")
    with pytest.raises(HdrError, match=word):
        patchmatch(src, tgt, **args)


def test_bad_inputs_exhaustive_and_fetch():
    with pytest.raises(HdrError, match="patch"):
        exhaustive_nnf(GOOD, GOOD, 6)
    with pytest.raises(HdrError, match="source"):
        exhaustive_nnf(np.full((8, 8, 3), np.inf, np.float32), GOOD, 3)
    field = identity_field(8, 8)
    with pytest.raises(HdrError, match="image"):
        fetch(field, np.zeros((8, 9, 3), np.float32))
    with pytest.raises(HdrError, match="image"):
        fetch(field, np.full((8, 8), np.nan, np.float32))
    with pytest.raises(HdrError, match="field"):
        fetch("not a field", GOOD)
    with pytest.raises(HdrError, match="height"):
        identity_field(0, 5)
