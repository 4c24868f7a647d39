"""The itmo and diffuse_map nodes, run without a bus, against the numpy operators and cv2."""

import cv2
import numpy as np
import pytest

from probeless.color import from_srgb8
from probeless.errors import ParamError, SchemaError
from probeless.messages.header import Header
from probeless.messages.sensor import Image
from probeless.nodes.pano.lighting import DiffuseMap, InverseToneMap
from probeless.pano import diffuse, equirect, itmo
from probeless.runtime.testing import run_node

HEADER = Header(123_456_789, "pano", 7)


def ldr_frame(h=64, w=128, seed=3):
    d = equirect.pixel_directions(w, h)
    sky = 0.35 + 0.3 * d[..., 2:3] + 0.05 * np.random.default_rng(seed).random((h, w, 3))
    img = np.clip(sky * 255, 0, 255).astype(np.uint8)
    img[h // 4 - 2:h // 4 + 2, w // 3:w // 3 + 4] = 255  # a clipped sun
    return img


def area(img, size):
    return cv2.resize(img.astype(np.float32), size, interpolation=cv2.INTER_AREA)


@pytest.mark.gl
@pytest.mark.graph
@pytest.mark.parametrize("gpu", [True, False])
def test_itmo_paper_full_and_small(gpu):
    img = ldr_frame()
    ctx = run_node(InverseToneMap, [("image", Image(HEADER, img, "rgb8"))], {"gpu": gpu, "small_size": [32, 16]})
    (hdr,), (small,) = ctx.outputs("hdr"), ctx.outputs("hdr_small")
    ref = itmo.paper_itmo(img.astype(np.float32) / 255)
    assert hdr.encoding == "rgbf16" and hdr.data.shape == img.shape and hdr.header.stamp_ns == HEADER.stamp_ns
    np.testing.assert_allclose(hdr.data.astype(np.float32), ref, rtol=1e-3)  # half precision
    assert small.encoding == "rgbf32" and small.data.shape == (16, 32, 3) and small.header == HEADER
    np.testing.assert_allclose(small.data, area(ref, (32, 16)), rtol=1e-5)
    assert {"itmo", "downsample"} <= set(ctx.timings.windows)


@pytest.mark.gl
@pytest.mark.graph
@pytest.mark.parametrize("operator", ["landis", "akyuz", "banterle", "none", "ldr"])
def test_itmo_operators_match_numpy(operator):
    img = ldr_frame()
    params = {"operator": operator, "small_size": [64, 32], "max_lum": 20.0, "full": False}
    (small,) = run_node(InverseToneMap, [("image", Image(HEADER, img, "rgb8"))], params).outputs("hdr_small")
    lin = itmo.gamma_decode(img.astype(np.float32) / 255, 2.2)
    ref = {"landis": lambda: itmo.landis_itmo(lin, max_lum=20.0), "akyuz": lambda: itmo.akyuz_itmo(lin, 20.0),
           "banterle": lambda: itmo.banterle_expand_map(lin, max_lum=20.0),
           "none": lambda: from_srgb8(img), "ldr": lambda: img / np.float32(255)}[operator]()
    np.testing.assert_allclose(small.data, area(ref, (64, 32)), rtol=1e-4, atol=1e-6)


@pytest.mark.gl
@pytest.mark.graph
def test_itmo_only_small_when_full_is_off():
    ctx = run_node(InverseToneMap, [("image", Image(HEADER, ldr_frame(), "rgb8"))], {"full": False})
    assert ctx.outputs("hdr") == [] and ctx.outputs("hdr_small")[0].data.shape == (64, 128, 3)


@pytest.mark.gl
@pytest.mark.graph
def test_itmo_errors_name_node_and_input():
    with pytest.raises(SchemaError, match="itmo: input 'image' must be rgb8, got 'rgbf32'"):
        run_node(InverseToneMap, [("image", Image(HEADER, np.zeros((8, 16, 3), np.float32), "rgbf32"))])
    with pytest.raises(SchemaError, match="itmo: input 'image' is 120x64, not an equirectangular"):
        run_node(InverseToneMap, [("image", Image(HEADER, np.zeros((64, 120, 3), np.uint8), "rgb8"))])
    with pytest.raises(SchemaError, match="smaller than small_size"):
        run_node(InverseToneMap, [("image", Image(HEADER, np.zeros((32, 64, 3), np.uint8), "rgb8"))])
    with pytest.raises(ParamError, match="small_size must be"):
        run_node(InverseToneMap, [], {"small_size": [100, 64]})


def hdr_frame(h=64, w=128):
    d = equirect.pixel_directions(w, h)
    s = np.array([0.6, -0.2, 0.5]) / np.linalg.norm([0.6, -0.2, 0.5])
    lum = 0.3 + 0.2 * d[..., 2] + 30.0 * (d @ s > np.cos(np.radians(6.0)))
    return (lum[..., None] * np.array([1.0, 0.8, 0.6])).astype(np.float32)


@pytest.mark.gl
@pytest.mark.graph
@pytest.mark.parametrize("method", ["gpu", "matmul", "sh9", "fast"])
def test_diffuse_node_methods(method):
    env = hdr_frame()
    params = {"method": method, "out_size": [16, 8], "in_size": [64, 32]}
    (out,) = run_node(DiffuseMap, [("hdr", Image(HEADER, env, "rgbf32"))], params).outputs("diffuse")
    if method == "fast":  # the exact convolution of the full frame, within the 1 % gate
        exact = diffuse.diffuse_map_bruteforce(env, (16, 8))
        assert out.data.shape == (8, 16, 3) and np.max(np.abs(out.data - exact) / exact) < 0.01
        return
    small = area(env, (64, 32))
    ref = (diffuse.sh9_irradiance_map(small, (16, 8)) if method == "sh9"
           else diffuse.diffuse_map(small, (16, 8), in_size=(64, 32)))
    assert out.encoding == "rgbf32" and out.data.shape == (8, 16, 3) and out.header == HEADER
    np.testing.assert_allclose(out.data, ref, rtol=5e-5)


@pytest.mark.gl
@pytest.mark.graph
def test_diffuse_node_small_input_as_is_and_half_full_frame():
    env = hdr_frame(128, 256)
    params = {"out_size": [16, 8], "in_size": [64, 32]}
    small = area(env, (64, 32))
    (a,) = run_node(DiffuseMap, [("hdr", Image(HEADER, small, "rgbf32"))], params).outputs("diffuse")
    (b,) = run_node(DiffuseMap, [("hdr", Image(HEADER, env.astype(np.float16), "rgbf16"))], params).outputs("diffuse")
    np.testing.assert_allclose(a.data, diffuse.diffuse_map(small, (16, 8), in_size=(64, 32)), rtol=5e-5)
    np.testing.assert_allclose(b.data, a.data, rtol=2e-3)  # half-precision input
    exact = diffuse.diffuse_map_bruteforce(env, (16, 8))
    assert np.max(np.abs(a.data - exact) / exact) < 0.02


@pytest.mark.gl
@pytest.mark.graph
def test_itmo_into_diffuse_chain():
    img = ldr_frame()
    (small,) = run_node(InverseToneMap, [("image", Image(HEADER, img, "rgb8"))],
                        {"full": False, "small_size": [64, 32]}).outputs("hdr_small")
    (out,) = run_node(DiffuseMap, [("hdr", small)], {"out_size": [16, 8], "in_size": [64, 32]}).outputs("diffuse")
    assert out.data.shape == (8, 16, 3) and out.header.stamp_ns == HEADER.stamp_ns
    ref = diffuse.diffuse_map(itmo.paper_itmo(img / np.float32(255)), (16, 8), in_size=(64, 32))
    np.testing.assert_allclose(out.data, ref, rtol=1e-4)


def test_diffuse_node_errors():
    with pytest.raises(SchemaError, match="diffuse_map: input 'hdr' must be rgbf32 or rgbf16, got 'rgb8'"):
        run_node(DiffuseMap, [("hdr", Image(HEADER, np.zeros((64, 128, 3), np.uint8), "rgb8"))],
                 {"method": "matmul"})
    with pytest.raises(SchemaError, match="not an equirectangular"):
        run_node(DiffuseMap, [("hdr", Image(HEADER, np.zeros((64, 100, 3), np.float32), "rgbf32"))],
                 {"method": "matmul"})
    with pytest.raises(SchemaError, match="smaller than in_size"):
        run_node(DiffuseMap, [("hdr", Image(HEADER, np.zeros((32, 64, 3), np.float32), "rgbf32"))],
                 {"method": "sh9"})
    with pytest.raises(ParamError, match="out_size must be"):
        run_node(DiffuseMap, [], {"out_size": [32, 8]})
