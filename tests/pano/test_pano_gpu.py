"""GPU inverse tone mapping and diffuse maps against the numpy operators, cv2 and analytic integrals."""

import cv2
import numpy as np
import pytest

from probeless.color import from_srgb8
from probeless.errors import ProbelessError
from probeless.gl.context import create_context
from probeless.pano import diffuse, equirect, itmo
from probeless.pano.gpu_diffuse import GpuDiffuse
from probeless.pano.gpu_itmo import GpuItmo

pytestmark = [pytest.mark.gl]


@pytest.fixture(scope="module")
def gl():
    ctx = create_context()
    yield ctx
    ctx.release()


def frame(h=40, w=80, seed=0):
    rng = np.random.default_rng(seed)
    img = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    img[0, :4] = [[0, 0, 0], [255, 255, 255], [255, 0, 0], [128, 128, 128]]
    return img


@pytest.mark.graph
@pytest.mark.parametrize("shape", [(40, 80), (33, 67)])  # 67: rows not 4-byte aligned
def test_gpu_paper_itmo_matches_numpy(gl, shape):
    img = frame(*shape)
    out = GpuItmo(gl).apply(img)
    ref = itmo.paper_itmo(img.astype(np.float32) / 255)
    assert out.dtype == np.float32 and out.shape == img.shape
    np.testing.assert_allclose(out, ref, rtol=2e-6, atol=1e-6)
    assert out[0, 1, 0] == pytest.approx(11.8, rel=1e-6)  # white: Ls = 10 + 1.8


@pytest.mark.graph
def test_gpu_other_operators_match_numpy(gl):
    img = frame()
    ldr = img.astype(np.float32) / 255
    landis = GpuItmo(gl, "landis", max_lum=20.0, threshold=0.6, alpha=1.5, linearize=True).apply(img)
    np.testing.assert_allclose(landis, itmo.landis_itmo(itmo.gamma_decode(ldr), 20.0, 0.6, 1.5), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(GpuItmo(gl, "none").apply(img), from_srgb8(img), rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(GpuItmo(gl, "ldr").apply(img), ldr, rtol=1e-6)
    with pytest.raises(ProbelessError, match="no GPU version.*akyuz"):
        GpuItmo(gl, "akyuz")


@pytest.mark.graph
def test_gpu_itmo_half_readback_and_area_downsample(gl):
    img = frame(64, 128)
    g = GpuItmo(gl)
    full, small = g.run(img, (32, 16))
    half, odd = g.run(img, (20, 10), dtype=np.float16)  # 128 / 20: partly covered texels
    assert half.dtype == np.float16
    np.testing.assert_array_equal(half, full.astype(np.float16))
    np.testing.assert_allclose(small, cv2.resize(full, (32, 16), interpolation=cv2.INTER_AREA), rtol=1e-5)
    np.testing.assert_allclose(odd, cv2.resize(full, (20, 10), interpolation=cv2.INTER_AREA), rtol=1e-5)
    with pytest.raises(ProbelessError, match="uint8"):
        g.apply(img.astype(np.float32))


def smooth_env(w, h, sun=0.0):
    d = equirect.pixel_directions(w, h)
    s = np.array([0.5, 0.3, 0.6]) / np.linalg.norm([0.5, 0.3, 0.6])
    lum = 0.5 + 0.3 * d[..., 2] + 0.2 * np.exp(3 * (d @ s - 1)) + sun * (d @ s > np.cos(np.radians(4.0)))
    return (lum[..., None] * np.array([1.0, 0.9, 0.8])).astype(np.float32)


@pytest.mark.graph
@pytest.mark.parametrize("out_size,in_size", [((32, 16), (128, 64)), ((16, 8), (64, 32))])
def test_gpu_diffuse_matches_matmul_and_bruteforce(gl, out_size, in_size):
    env = smooth_env(256, 128, sun=50.0)
    gpu = GpuDiffuse(gl, out_size, in_size).apply(env)
    ref = diffuse.diffuse_map(env, out_size, in_size=in_size)
    assert gpu.shape == ref.shape and gpu.dtype == np.float32
    # same weights: sub-texel midpoints at the horizon, the exact moment elsewhere (O(h^2) apart)
    np.testing.assert_allclose(gpu, ref, rtol=5e-5)
    idx = np.array([0, 5, out_size[0] * out_size[1] // 2 + 3, out_size[0] * out_size[1] - 1])
    brute = diffuse.diffuse_map_bruteforce(env, out_size, texels=idx)
    np.testing.assert_allclose(gpu.reshape(-1, 3)[idx], brute, rtol=0.01)


@pytest.mark.graph
def test_gpu_diffuse_full_frame_and_half_input_are_area_averaged_on_gpu(gl):
    env = smooth_env(256, 128, sun=20.0).astype(np.float16)
    g = GpuDiffuse(gl, (16, 8), (64, 32))
    small = cv2.resize(env.astype(np.float32), (64, 32), interpolation=cv2.INTER_AREA)
    np.testing.assert_allclose(g.apply(env), diffuse.diffuse_map(small, (16, 8), in_size=(64, 32)), rtol=5e-5)


def zenith_linear_env(w, h):
    """L = 1 + w.z averaged exactly over each texel: mean z = int sin t cos t dt / int sin t dt."""
    t = np.linspace(0.0, np.pi, h + 1)
    zmean = np.diff(np.sin(t) ** 2 / 2) / (np.cos(t[:-1]) - np.cos(t[1:]))
    return np.broadcast_to((1.0 + zmean)[:, None, None], (h, w, 3)).astype(np.float32)


@pytest.mark.graph
@pytest.mark.parametrize("kw", [{}, {"normalize": "pi"}, {"weights": "paper"}])
def test_gpu_diffuse_analytic(gl, kw):
    const = GpuDiffuse(gl, (16, 8), (64, 32), **kw).apply(np.full((32, 64, 3), [2.0, 1.0, 0.5], np.float32))
    np.testing.assert_allclose(const, np.broadcast_to([2.0, 1.0, 0.5], const.shape),
                               rtol=3e-3 if kw.get("normalize") == "pi" else 1e-5)
    # L = 1 + w.z: D(n) = (pi + n.z int_{n.w>0} (n.w)^2 dw) / pi = 1 + (2/3) n.z; the residual is the
    # piecewise-constant-texel model, O(texel^2): a quarter when the input texels halve
    expect = 1.0 + (2.0 / 3.0) * equirect.pixel_directions(16, 8)[..., 2]
    errs = [np.abs(GpuDiffuse(gl, (16, 8), (2 * h, h), **kw).apply(zenith_linear_env(2 * h, h))[..., 0]
                   - expect).max() for h in (32, 64)]
    assert errs[0] < 1.5e-3 and errs[1] < errs[0] / 3.5, errs


@pytest.mark.graph
def test_gpu_diffuse_paper_weights_close_to_exact(gl):
    env = smooth_env(64, 32, sun=50.0)
    paper = GpuDiffuse(gl, (16, 8), (64, 32), weights="paper").apply(env)
    exact = diffuse.diffuse_map(env, (16, 8), in_size=(64, 32))
    rel = np.abs(paper - exact) / exact
    assert 1e-5 < rel.max() < 0.02, rel.max()  # midpoint weights: different, but close


@pytest.mark.graph
def test_gpu_diffuse_bad_input(gl):
    g = GpuDiffuse(gl, (16, 8), (64, 32))
    with pytest.raises(ProbelessError, match="equirectangular"):
        g.apply(np.zeros((32, 60, 3), np.float32))
    with pytest.raises(ProbelessError, match="float RGB"):
        g.apply(np.zeros((32, 64, 3), np.uint8))
    with pytest.raises(ProbelessError, match="cannot be reduced"):
        g.apply(np.zeros((16, 32, 3), np.float32))
    with pytest.raises(ProbelessError, match="out_size"):
        GpuDiffuse(gl, (30, 16))


@pytest.mark.graph
def test_gpu_diffuse_moments_near_exact(gl):
    from probeless.pano.diffuse_eval import exact_diffuse

    env = smooth_env(512, 256, sun=200.0)
    exact = exact_diffuse(env, (16, 8))
    errs = {}
    for weights in ("subtexel", "moments"):
        fast = GpuDiffuse(gl, (16, 8), (64, 32), weights=weights).apply(env)
        errs[weights] = np.max(np.abs(fast - exact) / exact)
    assert errs["moments"] < 2e-3 and errs["moments"] < errs["subtexel"] / 4, errs
    const = GpuDiffuse(gl, (16, 8), (32, 16), weights="moments").apply(np.full((64, 128, 3), 3.0, np.float32))
    np.testing.assert_allclose(const, 3.0, rtol=1e-5)
    with pytest.raises(ProbelessError, match="at least 256x128"):
        GpuDiffuse(gl, (16, 8), (64, 32), weights="moments").apply(env[::4, ::4])
