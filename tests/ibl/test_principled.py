"""The principled material (parsing, IBL shading) and meshes with texture coordinates (OBJ vt, the UV sphere)."""

from __future__ import annotations

import numpy as np
import pytest
from locations import SHARED_DATA

from probeless.errors import SceneError
from probeless.ibl.materials import Diffuse, Mix, Principled, material_from_dict, shading
from probeless.ibl.mesh_io import load_mesh, load_mesh_uv, place, uv_sphere_uv
from probeless.ibl.objects import object_from_dict

SPOT = SHARED_DATA / "meshes" / "spot.obj"


# --- principled material ----------------------------------------------------------------------------------------


def test_principled_from_a_mapping_with_defaults_and_maps(tmp_path):
    assert material_from_dict({"type": "principled"}) == Principled((0.8, 0.8, 0.8), 0.5, 0.0, None, None, None)
    (tmp_path / "rough.png").write_bytes(b"not checked here")
    m = material_from_dict({"type": "principled", "base_color": [0.9, 0.5, 0.1], "roughness": 0.25, "metalness": 1,
                            "roughness_map": str(tmp_path / "rough.png")})
    assert m == Principled((0.9, 0.5, 0.1), 0.25, 1.0, None, str(tmp_path / "rough.png"), None)


@pytest.mark.parametrize("spec,key", [
    ({"sheen": 0.5}, "sheen"),
    ({"roughness": 1.5}, "roughness"),
    ({"roughness": -0.1}, "roughness"),
    ({"metalness": "shiny"}, "metalness"),
    ({"metalness": True}, "metalness"),
    ({"base_color": [0.5, 0.5]}, "base_color"),
    ({"base_color": [0.5, 0.5, 1.5]}, "base_color"),
    ({"base_color": "red"}, "base_color"),
    ({"base_color_map": 3}, "base_color_map"),
])
def test_bad_principled_keys_and_values_name_the_key(spec, key):
    with pytest.raises(SceneError, match=key):
        material_from_dict({"type": "principled", **spec}, "objects[2].material")


def test_a_missing_map_file_names_the_key_and_the_path(tmp_path):
    missing = tmp_path / "nowhere" / "metal.png"
    with pytest.raises(SceneError, match=rf"objects\[0\]\.material\.metalness_map: .*{missing}"):
        material_from_dict({"type": "principled", "metalness_map": str(missing)}, "objects[0].material")


def test_principled_shading_splits_diffuse_and_specular_by_metalness():
    s = shading(Principled((0.8, 0.4, 0.2), roughness=0.3, metalness=0.25))
    np.testing.assert_allclose(s.kd, [0.6, 0.3, 0.15])
    np.testing.assert_allclose(s.ks, [0.75 * 0.04 + 0.2, 0.75 * 0.04 + 0.1, 0.75 * 0.04 + 0.05])
    assert s.roughness == 0.3 and not s.kt.any()
    metal = shading(Principled((0.9, 0.6, 0.3), roughness=0.7, metalness=1.0))
    np.testing.assert_allclose(metal.kd, 0)
    np.testing.assert_allclose(metal.ks, [0.9, 0.6, 0.3])
    mixed = shading(Mix(((0.5, Principled((1, 1, 1), 0.4, 0.0)), (0.5, Diffuse((0.2, 0.2, 0.2))))))
    np.testing.assert_allclose(mixed.kd, 0.6)
    np.testing.assert_allclose(mixed.ks, 0.02)


# --- texture coordinates ----------------------------------------------------------------------------------------


def obj_corners(path):
    """Independent parse: positions, texcoords and per fanned-triangle-corner (v, vt) 0-based indices."""
    v, vt, corners = [], [], []
    for line in path.read_text().splitlines():
        p = line.split()
        if p and p[0] == "v":
            v.append([float(x) for x in p[1:4]])
        elif p and p[0] == "vt":
            vt.append([float(x) for x in p[1:3]])
        elif p and p[0] == "f":
            c = [tuple(int(i) - 1 for i in q.split("/")[:2]) for q in p[1:]]
            for k in range(1, len(c) - 1):
                corners += [c[0], c[k], c[k + 1]]
    return np.array(v), np.array(vt), np.array(corners)


def test_spot_uvs_give_each_corner_the_files_position_and_texcoord():
    v, f, uv = load_mesh_uv(SPOT)
    pos, vt, corners = obj_corners(SPOT)
    assert len(v) >= len(pos) and len(uv) == len(v) and len(f) * 3 == len(corners)
    np.testing.assert_array_equal(v[f.reshape(-1)], pos[corners[:, 0]])
    np.testing.assert_array_equal(uv[f.reshape(-1)], vt[corners[:, 1]])
    assert np.all(uv >= vt.min(axis=0)) and np.all(uv <= vt.max(axis=0))
    v0, f0 = load_mesh(SPOT)  # unchanged for callers that want no UVs
    assert len(v0) == len(pos) and np.array_equal(v0[f0], v[f])


def test_a_vertex_with_two_texcoords_is_split(tmp_path):
    obj = tmp_path / "quad.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
                   "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 0.5 0.5\n"
                   "f 1/1 2/2 3/3\nf 1/5 3/3 4/4\n")  # vertex 1 has vt 1 in one face, vt 5 in the other
    v, f, uv = load_mesh_uv(obj)
    assert len(v) == 5
    np.testing.assert_array_equal(uv[f], [[[0, 0], [1, 0], [1, 1]], [[0.5, 0.5], [1, 1], [0, 1]]])
    np.testing.assert_array_equal(v[f][:, :, :2], [[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]])
    (tmp_path / "plain.obj").write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nf 1 2 3\n")
    assert load_mesh_uv(tmp_path / "plain.obj")[2] is None


def test_uv_sphere_has_outward_triangles_and_longitude_latitude_uvs():
    v, f, uv = uv_sphere_uv(2.0, rings=12, segments=24)
    a, b, c = (v[f[:, k]] for k in range(3))
    normal = np.cross(b - a, c - a)
    assert np.all(np.linalg.norm(normal, axis=1) > 1e-6) and np.all(np.sum(normal * (a + b + c), axis=1) > 0)
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), 2.0)
    inside = (uv[:, 1] > 0) & (uv[:, 1] < 1) & (uv[:, 0] < 1)  # not a pole, not the seam's second copy
    np.testing.assert_allclose(uv[inside, 1], 1 - np.arccos(v[inside, 2] / 2) / np.pi, atol=1e-12)
    np.testing.assert_allclose(uv[inside, 0], np.mod(np.arctan2(v[inside, 1], v[inside, 0]), 2 * np.pi) / (2 * np.pi),
                               atol=1e-12)
    areas = 0.5 * np.linalg.norm(normal, axis=1).sum()
    assert areas == pytest.approx(4 * np.pi * 4, rel=0.05)


def test_place_carries_uvs_and_normals_have_no_seam():
    v, f, uv = load_mesh_uv("sphere")
    placed = place(v, f, [1.0, 2.0, 3.0], radius=0.5, uvs=uv)
    np.testing.assert_array_equal(placed.uvs, uv)
    radial = (placed.vertices - placed.centre) / 0.5
    assert np.min(np.sum(placed.normals * radial, axis=1)) > 0.9999  # seam and pole copies share the normal
    assert place(*load_mesh("sphere"), [0, 0, 0]).uvs is None
    with pytest.raises(SceneError, match="uvs"):
        place(v, f, [0, 0, 0], uvs=uv[:-1])


def test_an_object_with_texture_maps_gets_uvs(tmp_path):
    (tmp_path / "base.png").write_bytes(b"read by the PBGI renderer")
    spec = {"id": "spot", "mesh": str(SPOT), "position": [0, 0, 0], "radius": 0.2,
            "material": {"type": "principled", "base_color_map": str(tmp_path / "base.png")}}
    assert object_from_dict(spec).mesh.uvs.shape == (len(object_from_dict(spec).mesh.vertices), 2)
    assert object_from_dict({**spec, "material": {"type": "principled"}}).mesh.uvs is None
    (tmp_path / "plain.obj").write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n")
    with pytest.raises(SceneError, match="texture coordinates"):
        object_from_dict({**spec, "mesh": str(tmp_path / "plain.obj")})
