"""PBGI BRDF descriptions (probeless.pbgi.materials) and material texture maps (probeless.pbgi.textures)."""

from __future__ import annotations

import re

import cv2
import numpy as np
import pytest
from scipy import ndimage

from probeless.errors import PbgiError
from probeless.ibl.materials import Diffuse, Glass, Metal, Mirror, Mix, Principled, material_from_dict
from probeless.pbgi import brdf
from probeless.pbgi.materials import MIRROR_ROUGHNESS, MODEL_IDS, Brdf, brdf_from_material
from probeless.pbgi.textures import load_material_maps, sample_map


def test_model_ids_match_the_glsl_defines():
    text = (brdf.SHADER_DIR / "brdf.glsl").read_text()
    defines = {name.lower(): int(v) for name, v in re.findall(r"#define BRDF_(LAMBERT|GGX|DISNEY) (\d+)", text)}
    assert defines == MODEL_IDS and set(MODEL_IDS) == set(brdf.MODELS)


def test_each_opaque_material_maps_to_its_brdf():
    assert brdf_from_material(Diffuse((0.2, 0.3, 0.4), shadowed=True)) == Brdf("lambert", (0.2, 0.3, 0.4), 1.0)
    assert brdf_from_material(Metal((0.9, 0.6, 0.5), 0.35)) == Brdf("ggx", (0.9, 0.6, 0.5), 0.35)
    mirror = brdf_from_material(Mirror((0.7, 0.7, 0.7)))
    assert mirror == Brdf("ggx", (0.7, 0.7, 0.7), MIRROR_ROUGHNESS) and MIRROR_ROUGHNESS == 0.05
    p = brdf_from_material(material_from_dict({"type": "principled", "base_color": [0.5, 0.4, 0.3],
                                               "roughness": 0.2, "metalness": 0.7}))
    assert p == Brdf("disney", (0.5, 0.4, 0.3), 0.2, 0.7) and p.model_id == 2 and not p.textured
    assert len({p, Brdf("disney", (0.5, 0.4, 0.3), 0.2, 0.7, roughness_map=np.zeros((2, 2), np.float32))}) == 1
    with pytest.raises(PbgiError, match="phong"):
        Brdf("phong", (1.0, 1.0, 1.0))


@pytest.mark.parametrize("material,name", [(Glass(), "glass"), (Mix(((1.0, Diffuse()),)), "mix")])
def test_glass_and_mix_have_no_pbgi_brdf(material, name):
    with pytest.raises(PbgiError, match=name):
        brdf_from_material(material)


def test_principled_maps_are_read_and_decoded(tmp_path):
    base = np.zeros((4, 6, 3), np.uint8)
    base[..., 2], base[..., 1], base[..., 0] = 255, 128, 0  # OpenCV writes BGR: the file's red is 255
    cv2.imwrite(str(tmp_path / "base.png"), base)
    rough = np.full((4, 6), 32768, np.uint16)
    cv2.imwrite(str(tmp_path / "rough.png"), rough)
    metal = np.zeros((4, 6, 3), np.uint8)
    metal[..., 2] = 51  # red channel 0.2; the others are not read
    metal[..., :2] = 200
    cv2.imwrite(str(tmp_path / "metal.png"), metal)
    m = Principled(base_color_map=str(tmp_path / "base.png"), roughness_map=str(tmp_path / "rough.png"),
                   metalness_map=str(tmp_path / "metal.png"))
    b = brdf_from_material(m)
    assert b.textured and b.base_color_map.shape == (4, 6, 3) and b.base_color_map.dtype == np.float32
    # sRGB 128/255 = 0.50196 -> ((0.50196 + 0.055) / 1.055) ** 2.4 = 0.21586
    np.testing.assert_allclose(b.base_color_map[0, 0], [1.0, 0.21586, 0.0], atol=1e-5)
    np.testing.assert_allclose(b.roughness_map, 32768 / 65535, rtol=1e-6)
    np.testing.assert_allclose(b.metalness_map, 0.2, rtol=1e-6)
    assert load_material_maps(Principled(roughness_map=str(tmp_path / "rough.png"))).keys() == {"roughness_map"}
    linear = np.full((3, 2, 3), [0.1, 0.5, 2.0], np.float32)  # BGR; a float file is linear already (and HDR)
    cv2.imwrite(str(tmp_path / "base.tiff"), linear)
    got = load_material_maps(Principled(base_color_map=str(tmp_path / "base.tiff")))["base_color_map"]
    np.testing.assert_array_equal(got, np.full((3, 2, 3), [2.0, 0.5, 0.1], np.float32))
    (tmp_path / "broken.png").write_bytes(b"not an image")
    with pytest.raises(PbgiError, match="base_color_map.*broken.png"):
        load_material_maps(Principled(base_color_map=str(tmp_path / "broken.png")))


def test_sample_map_is_bilinear_and_wraps():
    rng = np.random.default_rng(0)
    img = rng.random((5, 7, 3))
    uv = rng.uniform(-1.5, 2.5, (200, 2))
    got = sample_map(img, uv)
    # independent reference: texel centre (r, c) at u = (c + 0.5) / W, v = 1 - (r + 0.5) / H, periodic
    rows, cols = (1 - uv[:, 1]) * 5 - 0.5, uv[:, 0] * 7 - 0.5
    ref = np.stack([ndimage.map_coordinates(img[..., k], [rows, cols], order=1, mode="grid-wrap")
                    for k in range(3)], axis=-1)
    np.testing.assert_allclose(got, ref, atol=1e-12)
    np.testing.assert_allclose(sample_map(img[..., 0], [(2.5 / 7, 1 - 3.5 / 5)]), [img[3, 2, 0]], atol=1e-12)
