"""The fast diffuse map (FFT along longitude + the brightest texels from the full frame) against Algorithm 1's
dense weight matrix, the exact convolution of the full frame, and an analytic constant."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from probeless.errors import ProbelessError
from probeless.pano import diffuse, equirect
from probeless.pano.diffuse_eval import GATE, exact_diffuse, rel_errors
from probeless.pano.diffuse_fast import diffuse_map_fast
from probeless.pano.sources import HDRI_DIR, read_panorama


def suns(w: int = 512, h: int = 256, n: int = 5, seed: int = 0) -> np.ndarray:
    """A dim sky over a darker ground with ``n`` small (2x2 px) suns thousands of times brighter: the case an
    area average gets wrong (not one of the shared panoramas)."""
    rng = np.random.default_rng(seed)
    d = equirect.pixel_directions(w, h)
    img = (0.02 + 0.05 * np.clip(d[..., 2:3], 0, 1)) * np.array([0.8, 0.9, 1.0])
    for _ in range(n):
        y, x = rng.integers(0, h - 2), rng.integers(0, w - 2)
        img[y:y + 2, x:x + 2] = rng.uniform(2e3, 2e4) * rng.uniform(0.6, 1.0, 3)
    return img.astype(np.float32)


@pytest.mark.parametrize("normalize", ["weights", "pi"])
def test_without_hot_texels_it_is_the_dense_weight_matrix(normalize):
    """The FFT evaluation is the same linear operator as diffuse_map's matrix (built independently)."""
    env = suns(256, 128, n=3, seed=1) + np.random.default_rng(2).random((128, 256, 3), np.float32)
    fast = diffuse_map_fast(env, (32, 16), in_size=(64, 32), hot_texels=0, normalize=normalize)
    dense = diffuse.diffuse_map(env, (32, 16), in_size=(64, 32), normalize=normalize)
    assert fast.shape == dense.shape == (16, 32, 3) and fast.dtype == np.float32
    np.testing.assert_allclose(fast, dense, rtol=2e-5, atol=1e-6 * float(dense.max()))


def test_constant_environment_gives_itself():
    env = np.full((256, 512, 3), [2.0, 1.0, 0.5], np.float32)
    np.testing.assert_allclose(diffuse_map_fast(env, (64, 32)), np.broadcast_to([2.0, 1.0, 0.5], (32, 64, 3)),
                               rtol=1e-5)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_small_bright_suns_within_the_gate_of_the_exact_convolution(seed):
    env = suns(seed=seed)
    exact = exact_diffuse(env, (64, 32))
    assert rel_errors(diffuse_map_fast(env, (64, 32)), exact)["max_rel_error"] <= GATE
    # the area average alone (Algorithm 1 on diffuse_map's 128x64, the same operator: first test) fails here
    alone = diffuse_map_fast(env, (64, 32), in_size=(128, 64), hot_texels=0)
    assert rel_errors(alone, exact)["max_rel_error"] > GATE


@pytest.mark.skipif(not (HDRI_DIR / "studio_small_03_1k.hdr").is_file(), reason="shared HDR panoramas absent")
def test_studio_panorama_within_the_gate():
    """The panorama where the 128x64 average is 9.6 % off (small bright lights in a dark studio)."""
    hdr = read_panorama(str(HDRI_DIR / "studio_small_03_1k.hdr"))
    exact = exact_diffuse(hdr, (64, 32))
    assert rel_errors(diffuse_map_fast(hdr, (64, 32)), exact)["max_rel_error"] <= GATE


def test_frame_of_another_size_and_one_channel():
    env = suns(500, 250, n=2, seed=3)  # not a multiple of 256x128: averaged to 256x128 first
    exact = exact_diffuse(env, (32, 16))
    assert rel_errors(diffuse_map_fast(env, (32, 16)), exact)["max_rel_error"] < 0.05
    one = diffuse_map_fast(env[..., :1], (32, 16))
    assert one.shape == (16, 32, 1)
    np.testing.assert_allclose(one[..., 0], diffuse_map_fast(env, (32, 16))[..., 0], rtol=1e-5)


def test_too_few_hot_texels_warn_with_the_count(caplog):
    env = suns(n=40, seed=4)
    with caplog.at_level(logging.WARNING, logger="probeless.pano.diffuse_fast"):
        diffuse_map_fast(env, (64, 32), in_size=(128, 64), hot_texels=2)
    assert "2 hot texels" in caplog.text and "raise hot_texels" in caplog.text
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="probeless.pano.diffuse_fast"):
        diffuse_map_fast(suns(n=3, seed=4), (64, 32))
    assert not caplog.text


def test_bad_sizes_are_named():
    env = np.zeros((64, 128, 3), np.float32)
    with pytest.raises(ProbelessError, match="out_size"):
        diffuse_map_fast(env, (30, 16))
    with pytest.raises(ProbelessError, match="in_size"):
        diffuse_map_fast(env, (32, 16), in_size=(100, 50))
