"""The ``pbgi_renderer`` node (nodes/pbgi/renderer.py) driven without a bus."""

from __future__ import annotations

import numpy as np
import pytest

from probeless.coarse.view import look_at
from probeless.errors import ParamError, SchemaError
from probeless.messages import Header, PointCloud
from probeless.messages.geometry import PoseStamped
from probeless.messages.lighting import Cubemap
from probeless.messages.sensor import CameraInfo, Image
from probeless.nodes.pbgi.renderer import PbgiRendererNode
from probeless.pbgi.bsh import synthetic_room
from probeless.runtime.testing import run_node

pytestmark = pytest.mark.gl
W, H = 96, 72
K = np.array([[80.0, 0, (W - 1) / 2], [0, 80.0, (H - 1) / 2], [0, 0, 1]])
CENTRE = [3.0, 2.0, 1.5]
POSE = look_at(np.array([1.6, 1.2, 1.6]), np.array(CENTRE))
OBJECTS = [{"id": "ball", "mesh": "sphere", "position": CENTRE, "radius": 0.3,
            "material": {"type": "diffuse", "albedo": [0.8, 0.8, 0.8]}}]
PARAMS = {"objects": OBJECTS, "micro": 16}
FRAME = np.random.default_rng(0).integers(0, 255, (H, W, 3), dtype=np.uint8)


def _cloud(n: int = 20_000, seed: int = 0) -> PointCloud:
    pts, col, nrm = synthetic_room(n, seed)
    return PointCloud(Header(1, "world"), pts.astype(np.float32), np.clip(col, 0, 1).astype(np.float32),
                      nrm.astype(np.float32))


def _frame(stamp: int) -> list:
    return [("rgb", Image(Header(stamp, "rgb"), FRAME, "rgb8")), ("pose", PoseStamped(Header(stamp, "world"), "rgb",
                                                                                     POSE))]


def _info() -> tuple:
    return ("camera_info", CameraInfo(Header(0, "rgb"), W, H, "pinhole", K))


def _run(inputs, params=None):
    ctx = run_node(PbgiRendererNode, inputs, dict(PARAMS, **(params or {})), node_id="pbgi")
    return [m.data for m in ctx.outputs("image")]


def test_frames_pass_through_before_the_cloud_and_are_composited_after(caplog):
    with caplog.at_level("INFO", logger="pbgi"):
        out = _run([_info(), *_frame(10), ("cloud", _cloud()), *_frame(20)])
    assert len(out) == 2
    np.testing.assert_array_equal(out[0], FRAME)  # no cloud yet
    changed = np.any(out[1] != FRAME, axis=2)
    assert 300 < changed.sum() < 0.5 * W * H       # the sphere, nothing else
    assert changed[H // 2, W // 2] and not changed[0, 0]
    assert "'no_cloud': 1" in caplog.text and "'frames': 1" in caplog.text and "'bsh_builds': 1" in caplog.text


def test_near_field_with_a_ball_holding_the_room_is_full_and_with_an_empty_ball_is_the_envmap():
    inputs = [_info(), ("cloud", _cloud()), *_frame(10)]
    full, = _run(inputs, {"mode": "full"})
    near_all, = _run(inputs, {"mode": "near_field", "near_radius": 10.0})
    near_none, = _run(inputs, {"mode": "near_field", "near_radius": 0.05})
    envmap, = _run(inputs, {"mode": "envmap"})
    obj = np.any(full != FRAME, axis=2)
    for img in (near_all, near_none, envmap):
        np.testing.assert_array_equal(img[~obj], FRAME[~obj])   # they differ only on the object
    np.testing.assert_array_equal(near_all, full)
    assert np.abs(near_none.astype(int) - envmap.astype(int)).max() <= 2
    assert np.abs(full[obj].astype(int) - envmap[obj].astype(int)).mean() > 1  # and PBGI is not the envmap


def test_the_bsh_is_rebuilt_only_when_the_cloud_grew_and_empty_clouds_are_counted(caplog):
    empty = PointCloud(Header(0, "world"), np.zeros((0, 3), np.float32), np.zeros((0, 3), np.uint8))
    clouds = [("cloud", c) for c in (empty, _cloud(10_000), _cloud(10_500, 1), _cloud(11_500, 2))]
    with caplog.at_level("INFO", logger="pbgi"):
        _run(clouds, {"min_growth": 0.1})
    assert "'bsh_builds': 2" in caplog.text and "'clouds_kept_old': 1" in caplog.text
    assert "'empty_clouds': 1" in caplog.text


def test_an_envmap_input_lights_the_envmap_mode_without_a_cloud():
    faces = np.full((6, 8, 8, 3), 0.5, np.float32)
    env = Cubemap(Header(5, "world"), "ball", np.array(CENTRE), faces)
    out, = _run([_info(), ("envmap", env), *_frame(10)], {"mode": "envmap", "exposure": 1.0})
    obj = np.any(out != FRAME, axis=2)
    # a white furnace: a diffuse sphere of albedo 0.8 in radiance 0.5 everywhere is 0.4 everywhere: sRGB code 170
    assert obj.sum() > 300 and np.abs(np.median(out[obj], axis=0) - 170).max() <= 3


def test_bad_inputs_raise_naming_the_input_and_bad_params_fail_at_load():
    with pytest.raises(SchemaError, match="'cloud'"):
        _run([("cloud", Image(Header(0, "x"), FRAME, "rgb8"))])
    nan = _cloud(100)
    nan.points[7] = np.nan
    with pytest.raises(SchemaError, match="'cloud'.*'points'"):
        _run([("cloud", nan)])
    with pytest.raises(SchemaError, match="'rgb'"):
        _run([_info(), ("cloud", _cloud(1000)), ("rgb", Image(Header(3, "rgb"), FRAME[..., ::-1].copy(), "bgr8")),
              ("pose", PoseStamped(Header(3, "world"), "rgb", POSE))])
    glass = [dict(OBJECTS[0], material={"type": "glass"})]
    with pytest.raises(ParamError, match="glass"):
        _run([], {"objects": glass})
    with pytest.raises(ParamError, match="micro"):
        _run([], {"micro": 20})
