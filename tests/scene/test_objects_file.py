"""Virtual objects from a scene file or an objects file (probeless.scene.objects_file)."""

from __future__ import annotations

import pytest

from probeless.errors import SceneError
from probeless.ibl.objects import object_from_dict
from probeless.scene.objects_file import load_objects, objects_file_problem
from tests.locations import REPO

LOUNGE = REPO / "launch/scenes/l_shaped_lounge.yaml"


def test_a_scene_files_virtual_objects_become_spheres_with_the_default_material():
    objects = load_objects(LOUNGE, {"type": "diffuse", "albedo": [0.5, 0.5, 0.5]})
    assert [o["id"] for o in objects] == ["sphere"]
    o = objects[0]
    assert o["position"] == [1.8, 1.5, 0.9] and o["radius"] == 0.12 and o["mesh"] == "sphere"
    assert o["material"] == {"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}
    assert object_from_dict(o).id == "sphere"  # what the compositor builds


def test_an_objects_file_resolves_meshes_against_its_folder(tmp_path):
    (tmp_path / "meshes").mkdir()
    mesh = REPO / "launch/scenes/meshes/teapot.obj"
    (tmp_path / "meshes/teapot.obj").write_bytes(mesh.read_bytes())
    path = tmp_path / "objects.yaml"
    path.write_text("objects:\n"
                    "  - {id: ball, position: [1, 2, 0.5], radius: 0.2}\n"
                    "  - {id: pot, mesh: meshes/teapot.obj, position: [0, 0, 0.7], scale: 0.05, up: y,\n"
                    "     material: {type: metal, roughness: 0.3}}\n")
    ball, pot = load_objects(path)
    assert ball["material"] == {"type": "mirror"} and ball["mesh"] == "sphere"
    assert pot["mesh"] == str(tmp_path / "meshes/teapot.obj") and pot["material"]["type"] == "metal"
    assert object_from_dict(pot).mesh.vertices.shape[1] == 3


@pytest.mark.parametrize("text, match", [
    ("objects: {id: a}\n", "'objects' must be a list"),
    ("objects:\n  - {position: [0, 0, 0]}\n", r"objects\[0\]: missing key 'id'"),
    ("objects:\n  - {id: a, position: [0, nan, 0]}\n", r"objects\[0\].position: need 3 finite"),
    ("objects:\n  - {id: a/b, position: [0, 0, 0]}\n", r"objects\[0\].id"),
    ("objects:\n  - {id: a, position: [0, 0, 0]}\n  - {id: a, position: [1, 0, 0]}\n", "'a' appears twice"),
    ("- 1\n", "expected a mapping"),
])
def test_bad_objects_files_name_the_file_and_the_key(tmp_path, text, match):
    path = tmp_path / "objects.yaml"
    path.write_text(text)
    with pytest.raises(SceneError, match=match) as info:
        load_objects(path)
    assert str(path) in str(info.value)
    assert objects_file_problem(str(path)) == str(info.value)


def test_a_missing_file_is_named():
    with pytest.raises(SceneError, match="nowhere.yaml: objects file not found"):
        load_objects("nowhere.yaml")
    assert objects_file_problem("") is None
