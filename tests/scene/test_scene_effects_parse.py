"""Scene-file keys for sensor effects, the given block, object material/mesh and ``extends``: parsing, errors that
name the file and key, and the shipped *_realistic variants."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest
import yaml
from locations import REPO
from scene_examples import BASE

from probeless.errors import SceneError
from probeless.scene.extends import deep_merge, scene_yaml
from probeless.scene.parse import load_scene

REALISTIC = sorted((REPO / "launch/scenes").glob("*_realistic.yaml"))

EFFECTS = {"seed": 3,
           "rgbd": {"auto_exposure": {"target": 0.2, "tau_s": 0.5}, "white_balance": {"gains": [1.1, 1, 0.9]},
                    "vignetting": {"model": "poly", "coeffs": [-0.2]}, "response": {"model": "gamma", "gamma": 2.2},
                    "noise": {"full_well": 4000, "read_sigma": 0.003}, "exposure_time_s": 0.016},
           "fisheye": {"vignetting": {"model": "cos4"}},
           "flicker": {"amplitude": 0.1},
           "depth": {"sigma_k": 1.425e-3, "disparity_step_px": 0.125, "edge_dropout": 0.3}}


def write(tmp_path: Path, doc: dict, name: str = "scene.yaml") -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(doc))
    return path


def with_block(**blocks) -> dict:
    doc = copy.deepcopy(BASE)
    doc.update(copy.deepcopy(blocks))
    return doc


def test_absent_blocks_are_none_and_objects_default_to_spheres(tmp_path):
    scene = load_scene(write(tmp_path, BASE))
    assert scene.sensor_effects is None and scene.given is None
    assert scene.virtual_objects[0].mesh == "sphere" and scene.virtual_objects[0].material is None


def test_sensor_effects_parse(tmp_path):
    fx = load_scene(write(tmp_path, with_block(sensor_effects=EFFECTS))).sensor_effects
    assert fx.seed == 3 and fx.rgbd.auto_exposure.target == 0.2 and fx.rgbd.auto_exposure.max == 16.0
    assert fx.rgbd.wb_gains == (1.1, 1, 0.9)
    assert fx.rgbd.vignetting.coeffs == (-0.2,) and fx.rgbd.gamma == 2.2 and fx.rgbd.noise.full_well == 4000
    assert fx.fisheye.vignetting.model == "cos4" and fx.fisheye.noise is None and fx.fisheye.gamma is None
    assert fx.flicker.frequency_hz == 100.0 and fx.depth.edge_dropout == 0.3 and fx.depth.max_incidence_deg == 90


@pytest.mark.parametrize("edit,key,message", [
    (("rgbd", "exposure"), "sensor_effects.rgbd.exposure", "unknown key"),
    (("flicker", "amplitude"), "sensor_effects.flicker.amplitude", "must be <= 1"),
    (("rgbd", "vignetting"), "sensor_effects.rgbd.vignetting.model", "is not one of cos4, poly"),
    (("depth", "edge_dropout"), "sensor_effects.depth.edge_dropout", "must be <= 1"),
    (("seed",), "sensor_effects", "missing key 'seed'"),
])
def test_bad_sensor_effects_name_file_and_key(tmp_path, edit, key, message):
    fx = copy.deepcopy(EFFECTS)
    if edit == ("seed",):
        del fx["seed"]
    elif edit[1] == "exposure":
        fx["rgbd"]["exposure"] = 2
    elif edit[1] == "vignetting":
        fx["rgbd"]["vignetting"] = {"model": "cos3"}
    else:
        fx[edit[0]][edit[1]] = 2
    path = write(tmp_path, with_block(sensor_effects=fx))
    with pytest.raises(SceneError) as exc:
        load_scene(path)
    assert str(path) in str(exc.value) and key in str(exc.value) and message in str(exc.value)


GIVEN = {"seed": 1, "floorplan": {"vertex_sigma_m": 0.03, "rotation_deg": 1.0, "ceiling_m": 0.03},
         "extrinsics": {"translation_sigma_m": 0.01, "rotation_sigma_deg": 0.5},
         "fisheye_intrinsics": {"focal_rel_sigma": 0.005, "center_sigma_px": 2}, "clock_offset_s": 0.01}


def test_given_parses(tmp_path):
    g = load_scene(write(tmp_path, with_block(given=GIVEN))).given
    assert g.seed == 1 and g.floorplan.rotation_deg == 1.0 and g.extrinsics.rotation_sigma_deg == 0.5
    assert g.fisheye_intrinsics.center_sigma_px == 2 and g.clock_offset_s == 0.01


@pytest.mark.parametrize("change,key,message", [
    ({"extrinsics": {"from_file": "ext.yaml", "translation_sigma_m": 0.01}}, "given.extrinsics.from_file",
     "from_file excludes translation_sigma_m"),
    ({"extrinsics": {"from_file": "missing.yaml"}}, "given.extrinsics.from_file", "file not found"),
    ({"fisheye_intrinsics": {"focal": 0.01}}, "given.fisheye_intrinsics.focal", "unknown key"),
    ({"clock_offset_s": -0.5}, "given", "makes the first fisheye stamp negative"),
])
def test_bad_given_names_file_and_key(tmp_path, change, key, message):
    (tmp_path / "ext.yaml").write_text("x: 1\n")
    path = write(tmp_path, with_block(given={"seed": 0, **change}))
    with pytest.raises(SceneError) as exc:
        load_scene(path)
    assert str(path) in str(exc.value) and key in str(exc.value) and message in str(exc.value)


def test_object_material_and_mesh(tmp_path):
    doc = copy.deepcopy(BASE)
    doc["virtual_objects"][0].update(material={"type": "diffuse", "albedo": [0.8, 0.2, 0.2]}, mesh="bunny")
    obj = load_scene(write(tmp_path, doc)).virtual_objects[0]
    assert obj.material == {"type": "diffuse", "albedo": [0.8, 0.2, 0.2]} and type(obj.material) is dict
    assert obj.mesh == "bunny"
    doc["virtual_objects"][0]["material"] = {"albedo": [1, 1, 1]}
    with pytest.raises(SceneError, match=r"virtual_objects\[0\].material: missing key 'type'"):
        load_scene(write(tmp_path, doc))


def test_deep_merge_merges_mappings_and_replaces_lists():
    base = {"a": {"b": 1, "c": [1, 2], "d": {"e": 1}}, "f": 2}
    over = {"a": {"c": [3], "d": {"g": 4}}, "h": 5}
    assert deep_merge(base, over) == {"a": {"b": 1, "c": [3], "d": {"e": 1, "g": 4}}, "f": 2, "h": 5}
    assert base == {"a": {"b": 1, "c": [1, 2], "d": {"e": 1}}, "f": 2}  # inputs untouched


def test_extends_merges_onto_the_base(tmp_path):
    write(tmp_path, BASE, "base.yaml")
    (tmp_path / "variants").mkdir()
    variant = write(tmp_path / "variants", {"extends": "../base.yaml", "name": "v",
                                            "rig": {"rgbd": {"fps": 15}},
                                            "virtual_objects": [{"id": "other", "position": [1, 1, 1],
                                                                 "radius": 0.1}]}, "v.yaml")
    scene, base = load_scene(variant), load_scene(tmp_path / "base.yaml")
    assert scene.name == "v" and scene.rgbd.fps == 15 and scene.rgbd.width == base.rgbd.width
    assert [o.id for o in scene.virtual_objects] == ["other"]  # lists replace
    np.testing.assert_array_equal(scene.floorplan, base.floorplan)
    merged = yaml.safe_load(scene_yaml(variant))
    assert "extends" not in merged and merged["rig"]["rgbd"]["fps"] == 15 and merged["rig"]["rgbd"]["fx"] == 50
    assert scene_yaml(tmp_path / "base.yaml") == (tmp_path / "base.yaml").read_text()


def test_relative_paths_are_relative_to_the_file_that_writes_them(tmp_path):
    lounge = REPO / "launch/scenes/l_shaped_lounge.yaml"
    variant = write(tmp_path, {"extends": str(lounge), "name": "elsewhere"}, "v.yaml")
    scene = load_scene(variant)
    assert scene.walls.texture == lounge.parent / "textures/plaster.png"
    assert scene.furniture[1].path == lounge.parent / "meshes/teapot.obj"


def test_extends_errors(tmp_path):
    write(tmp_path, {"extends": "b.yaml", "name": "a"}, "a.yaml")
    write(tmp_path, {"extends": "a.yaml", "name": "b"}, "b.yaml")
    with pytest.raises(SceneError, match="forms a cycle"):
        load_scene(tmp_path / "a.yaml")
    with pytest.raises(SceneError, match=r"c.yaml:1: extends: file not found"):
        load_scene(write(tmp_path, {"extends": "nope.yaml"}, "c.yaml"))
    write(tmp_path, BASE, "base.yaml")
    bad = write(tmp_path, {"extends": "base.yaml", "rig": {"rgbd": {"fsp": 30}}}, "d.yaml")
    with pytest.raises(SceneError) as exc:
        load_scene(bad)
    assert "d.yaml (extends" in str(exc.value) and "rig.rgbd.fsp: unknown key" in str(exc.value)


@pytest.mark.parametrize("path", REALISTIC, ids=[p.stem for p in REALISTIC])
def test_realistic_variants_turn_everything_on_and_reload_from_their_merged_yaml(path, tmp_path):
    scene = load_scene(path)
    base = load_scene(path.parent / path.name.replace("_realistic", ""))
    fx, given = scene.sensor_effects, scene.given
    assert fx.rgbd.auto_exposure and fx.fisheye.noise and fx.flicker and fx.depth.sigma_k == pytest.approx(1.425e-3)
    assert given.floorplan.rotation_deg == 1.0 and given.clock_offset_s == pytest.approx(0.01)
    assert scene.rgbd.depth_noise_m == 0.0 and scene.rgbd.K.tolist() == base.rgbd.K.tolist()
    np.testing.assert_array_equal(scene.floorplan, base.floorplan)  # the truth is the base's
    copy_path = tmp_path / "merged.yaml"  # elsewhere: the base's asset paths were made absolute
    copy_path.write_text(scene_yaml(path))
    again = load_scene(copy_path)
    assert again.sensor_effects == scene.sensor_effects and again.given == scene.given
    np.testing.assert_array_equal(again.fisheye_from_rgbd, scene.fisheye_from_rgbd)


def test_scene_check_reports_what_is_told(capsys):
    from argparse import Namespace

    from scipy.spatial.transform import Rotation

    from probeless.scene.cli import cmd_check
    from probeless.scene.given import given_rig
    from probeless.scene.rig import fisheye_model

    path = REPO / "launch/scenes/light_switch_realistic.yaml"
    assert cmd_check(Namespace(scene=str(path))) == 0
    out = capsys.readouterr().out
    scene = load_scene(path)
    told = given_rig(scene.given, scene.floorplan, scene.ceiling_height, scene.fisheye_from_rgbd,
                     fisheye_model(scene).to_camera_info()).fisheye_from_rgbd
    truth = scene.fisheye_from_rgbd
    angle = np.degrees(Rotation.from_matrix(told[:3, :3] @ truth[:3, :3].T).magnitude())
    assert f"{np.linalg.norm(told[:3, 3] - truth[:3, 3]) * 100:.2f} cm / {angle:.2f} deg off" in out
    assert "sensor effects (seed 17)" in out and "clock +10.0 ms" in out and "ceiling +3.0 cm" in out
