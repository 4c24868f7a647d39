"""The rig with ``sensor_effects`` and ``given``: all-off blocks change nothing, given values change what is told
but not what is rendered, effects reach the images, and the rig publishes and records ``fisheye_from_rgbd``."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest
import yaml
from scene_examples import BASE

from probeless.bag.reader import BagReader
from probeless.cli import main as cli
from probeless.runtime.params import load_params
from probeless.runtime.testing import RecordingContext
from probeless.scene.parse import load_scene
from probeless.scene.rig import FISHEYE_FRAME, RGBD_FRAME, FrameEvent, Rig
from probeless.scene.sensor_effects import encode, flicker_factor, response_lut
from probeless.wire import decode

EVENTS = (FrameEvent(RGBD_FRAME, 3, 0.1), FrameEvent(FISHEYE_FRAME, 1, 0.1), FrameEvent(RGBD_FRAME, 40, 1.3333),
          FrameEvent(FISHEYE_FRAME, 20, 1.3333))
GIVEN = {"seed": 2, "floorplan": {"vertex_sigma_m": 0.03, "rotation_deg": 1.0, "ceiling_m": 0.03},
         "extrinsics": {"translation_sigma_m": 0.01, "rotation_sigma_deg": 0.5},
         "fisheye_intrinsics": {"focal_rel_sigma": 0.005, "center_sigma_px": 2}, "clock_offset_s": 0.01}
EFFECTS = {"seed": 1,
           "rgbd": {"auto_exposure": {"target": 0.2, "tau_s": 0.3}, "white_balance": {"gains": [1.1, 1, 0.9]},
                    "vignetting": {"model": "cos4"}, "noise": {"full_well": 2000, "read_sigma": 0.004}},
           "fisheye": {"auto_exposure": {"target": 0.3, "tau_s": 0.5}, "white_balance": {"gains": [0.9, 1, 1.1]},
                       "response": {"model": "gamma", "gamma": 2.2}, "vignetting": {"model": "poly", "coeffs": [-0.3]},
                       "noise": {"full_well": 6000}},
           "flicker": {"amplitude": 0.2},
           "depth": {"sigma_k": 1.425e-3, "disparity_step_px": 0.125, "max_incidence_deg": 80, "edge_dropout": 0.5}}


def scene_file(tmp_path: Path, name: str = "scene.yaml", **blocks) -> Path:
    doc = copy.deepcopy(BASE)
    doc["rig"]["rgbd"].update(width=160, height=120, fx=130, fy=130, cx=79.5, cy=59.5, depth_noise_m=0.003)
    doc["rig"]["fisheye"].update(width=128, height=128)
    doc.update(copy.deepcopy(blocks))
    tmp_path.mkdir(parents=True, exist_ok=True)
    (tmp_path / name).write_text(yaml.safe_dump(doc))
    return tmp_path / name


def messages(path: Path, events=EVENTS) -> list[list[tuple[str, object]]]:
    rig = Rig(load_scene(path), envmap_size=8, fisheye_cube_size=64)
    out = [[("floorplan", rig.floorplan()), ("fisheye_from_rgbd", rig.fisheye_from_rgbd_message())]]
    out += [list(rig.messages(e)) for e in events]
    rig.release()
    return out


@pytest.fixture(scope="module")
def plain(tmp_path_factory):
    return messages(scene_file(tmp_path_factory.mktemp("plain")))


@pytest.mark.gl
@pytest.mark.graph
def test_blocks_with_nothing_on_render_bit_for_bit_as_without(tmp_path, plain):
    same = messages(scene_file(tmp_path, sensor_effects={"seed": 7}, given={"seed": 3}))
    for a, b in zip(plain, same):
        assert [o for o, _ in a] == [o for o, _ in b]
        for (output, x), (_, y) in zip(a, b):
            for field in ("data", "faces", "K", "vertices", "target_from_source"):
                if hasattr(x, field):
                    np.testing.assert_array_equal(getattr(x, field), getattr(y, field), err_msg=output)
            assert x.header == y.header, output


@pytest.mark.gl
@pytest.mark.graph
def test_given_changes_what_is_told_not_what_is_rendered(tmp_path, plain):
    path = scene_file(tmp_path, given=GIVEN)
    told = messages(path)
    scene, rig = load_scene(path), Rig(load_scene(path), envmaps=False)
    rig.release()
    start = dict(told[0])
    assert start["floorplan"].header.stamp_ns == 0 and start["fisheye_from_rgbd"].header.frame_id == "fisheye"
    assert start["fisheye_from_rgbd"].child_frame_id == "rgbd"
    np.testing.assert_array_equal(start["fisheye_from_rgbd"].target_from_source, rig.given.fisheye_from_rgbd)
    moved = np.linalg.norm(rig.given.fisheye_from_rgbd[:3, 3] - scene.fisheye_from_rgbd[:3, 3])
    assert 0 < moved < 0.06
    np.testing.assert_array_equal(dict(plain[0])["fisheye_from_rgbd"].target_from_source, scene.fisheye_from_rgbd)
    assert 0 < np.abs(start["floorplan"].vertices - scene.floorplan).max() < 0.2
    assert start["floorplan"].ceiling_height == pytest.approx(scene.ceiling_height + 0.03)
    fisheye, truth = dict(told[4]), dict(plain[4])
    np.testing.assert_array_equal(fisheye["fisheye"].data, truth["fisheye"].data)  # rendered with the true model
    assert not np.allclose(fisheye["fisheye/camera_info"].K, truth["fisheye/camera_info"].K)
    np.testing.assert_array_equal(fisheye["fisheye/camera_info"].K, rig.given.fisheye_info.K)
    true_ns = EVENTS[3].stamp_ns
    for output in ("fisheye", "fisheye/camera_info", "gt/fisheye_pose", "gt/fisheye_exposure"):
        assert fisheye[output].header.stamp_ns == true_ns + 10_000_000, output
    np.testing.assert_array_equal(fisheye["gt/fisheye_pose"].target_from_source,
                                  truth["gt/fisheye_pose"].target_from_source)  # the pose at the true time
    assert fisheye["gt/envmap/ball"].header.stamp_ns == true_ns
    assert dict(told[3])["rgb"].header.stamp_ns == true_ns


@pytest.mark.gl
@pytest.mark.graph
def test_effects_reach_the_images_and_the_ground_truth_ldr(tmp_path, plain):
    path = scene_file(tmp_path, sensor_effects=EFFECTS)
    out = messages(path)
    rgbd, clean_rgbd = dict(out[3]), dict(plain[3])
    depth, clean = rgbd["depth"].data.astype(float), clean_rgbd["depth"].data.astype(float)
    assert 0.0 < np.mean(depth == 0) < 0.2  # edge dropouts and grazing floor/ceiling far away
    both = (depth > 0) & (clean > 0)
    assert np.abs(depth - clean)[both].mean() > 2  # more than the base 3 mm: k z^2 and quantisation at 1-4 m
    assert not np.array_equal(rgbd["rgb"].data, clean_rgbd["rgb"].data)
    fish = dict(out[4])
    gains = fish["gt/fisheye_exposure"].data.reshape(3)
    assert fish["gt/fisheye_exposure"].encoding == "rgbf32" and gains[0] / gains[2] == pytest.approx(0.9 / 1.1)
    faces = fish["gt/envmap/ball"].faces.astype(np.float32)
    ldr = fish["gt/envmap_ldr/ball"].faces
    want = encode(faces * gains, response_lut(2.2))  # current exposure x white balance, gamma 2.2, no noise
    assert np.abs(ldr.astype(int) - want.astype(int)).max() <= 1  # float16 truth
    assert not np.array_equal(fish["fisheye"].data, dict(plain[4])["fisheye"].data)
    # outside the image circle stays black despite the read noise
    corner = fish["fisheye"].data[:6, :6]
    assert corner.max() == 0


@pytest.mark.gl
@pytest.mark.graph
def test_flicker_scales_the_ceiling_lights_by_the_shutter_average(tmp_path):
    rig = Rig(load_scene(scene_file(tmp_path, sensor_effects={"seed": 0, "flicker": {"amplitude": 0.3},
                                                              "fisheye": {"exposure_time_s": 0.002}})),
              envmaps=False)
    rig.release()
    t = 1.2345
    assert rig.light_scale(t, FISHEYE_FRAME)[0] == pytest.approx(flicker_factor(t, 0.002, 0.3, 100.0))
    assert rig.light_scale(t, RGBD_FRAME)[0] == pytest.approx(flicker_factor(t, 0.01, 0.3, 100.0))
    assert rig.light_scale(t)[0] == 1.0 and rig.light_scale(t, FISHEYE_FRAME)[1] == 1.0  # truth, window


@pytest.mark.gl
@pytest.mark.graph
def test_node_publishes_fisheye_from_rgbd_after_the_floorplan(tmp_path):
    from probeless.nodes.sensors.synthetic_rig import SyntheticRig

    path = scene_file(tmp_path, given=GIVEN)
    ctx = RecordingContext("rig", SyntheticRig)
    node = SyntheticRig(ctx, load_params(SyntheticRig.Params, {"scene": str(path), "rate": 0, "duration_s": 0.05,
                                                               "envmap_size": 8, "fisheye_cube_size": 32},
                                         node_id="rig"))
    node.setup()
    for _ in range(20):
        if ctx.stopped:
            break
        ctx.timers[0][1]()
    node.close()
    assert [o for o, _ in ctx.published[:2]] == ["floorplan", "fisheye_from_rgbd"]
    (pose,) = ctx.outputs("fisheye_from_rgbd")
    np.testing.assert_array_equal(pose.target_from_source, node.rig.given.fisheye_from_rgbd)
    assert pose.header.stamp_ns == 0 and len(ctx.outputs("gt/fisheye_exposure")) == len(ctx.outputs("fisheye"))


@pytest.mark.gl
@pytest.mark.graph
def test_scene_render_records_fisheye_from_rgbd_and_the_merged_scene(tmp_path):
    scene_file(tmp_path, "base.yaml")
    variant = tmp_path / "variant.yaml"
    variant.write_text(yaml.safe_dump({"extends": "base.yaml", "name": "variant", "given": GIVEN}))
    out = tmp_path / "seq.mcap"
    assert cli(["scene", "render", str(variant), "-o", str(out), "--duration", "0.04", "--no-envmaps"]) == 0
    with BagReader(str(out)) as reader:
        topics = reader.topics()
        assert topics["rig/fisheye_from_rgbd"].count == 1 and topics["rig/gt/fisheye_exposure"].count == 1
        _, _, pose = decode(next(reader.messages(topics=["rig/fisheye_from_rgbd"])).frames)
        meta = reader.metadata()["probeless.scene"]
    rig = Rig(load_scene(variant), envmaps=False)
    rig.release()
    np.testing.assert_array_equal(pose.target_from_source, rig.given.fisheye_from_rgbd)
    merged = yaml.safe_load(meta["yaml"])
    assert "extends" not in merged and merged["given"]["seed"] == 2 and merged["rig"]["rgbd"]["width"] == 160


# Every *_realistic scene renders: tests/scene/test_synthetic_rig.py::test_every_shipped_scene_renders.
