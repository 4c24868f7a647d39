"""The paper's baseline environment map (§5.3) and its node, against OpenCV sampling and analytic environments."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from probeless.cameras.omnidir import OmnidirModel
from probeless.envmap.baseline import BaselineMap
from probeless.envmap.metrics import coverage
from probeless.errors import ParamError, SchemaError
from probeless.geom.cube import cube_directions, texel_direction
from probeless.messages.geometry import PoseStamped
from probeless.messages.header import Header
from probeless.messages.sensor import Image
from probeless.nodes.envmap.baseline import BaselineEnvmap as BaselineNode
from probeless.runtime.testing import run_node

W = 160
MODEL = OmnidirModel.from_fov(W, W, 185.0)


def pose(rotvec_deg, t=(0.0, 0.0, 0.0)) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(np.radians(rotvec_deg)).as_matrix()
    T[:3, 3] = t
    return T


def env_colour(d: np.ndarray) -> np.ndarray:
    """A smooth environment: colour = a function of the world direction."""
    return np.stack([(d[..., 0] + 1) / 2, (d[..., 1] + 1) / 2, (d[..., 2] + 1) / 2], axis=-1)


def fisheye_of_environment(world_from_fisheye: np.ndarray) -> np.ndarray:
    """What the fisheye sees of the distant environment (unproject every pixel, rotate to world)."""
    v, u = np.mgrid[0:W, 0:W].astype(np.float64)
    rays, valid = MODEL.unproject(np.stack([u.ravel(), v.ravel()], axis=1))
    world = np.nan_to_num(rays) @ world_from_fisheye[:3, :3].T
    img = np.where(valid[:, None], env_colour(world), 0.0)
    return np.round(img.reshape(W, W, 3) * 255).astype(np.uint8)


def test_update_samples_the_image_where_the_model_projects_the_rotated_direction():
    rng = np.random.default_rng(0)
    image = cv2.GaussianBlur(rng.integers(0, 256, (W, W, 3), dtype=np.uint8), (5, 5), 1)
    T = pose([30, -20, 50], t=(1.0, 2.0, 3.0))
    b = BaselineMap(24, MODEL, 183.0)
    written = b.update(image, T)
    d = cube_directions(24).reshape(-1, 3)  # [face, row, col] order
    uv, valid = MODEL.project(d @ T[:3, :3])  # rows of R^T d
    cos = (d @ T[:3, :3])[:, 2]
    expect_in = valid & (cos >= np.cos(np.radians(91.5)))
    np.testing.assert_array_equal(b.observed().reshape(-1), expect_in)
    assert written == expect_in.sum()
    maps = uv[expect_in].astype(np.float32)
    ref = cv2.remap(image, maps[:, 0:1], maps[:, 1:2], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    np.testing.assert_allclose(b.faces.reshape(-1, 3)[expect_in] * 255, ref[:, 0].astype(np.float64), atol=0.6)
    assert np.all(b.faces.reshape(-1, 3)[~expect_in] == np.float32(128 / 255))  # unseen: neutral grey
    # one frame covers the 183 deg cap: (1 - cos 91.5 deg) / 2 of the sphere
    assert coverage(b.observed()) == pytest.approx((1 - np.cos(np.radians(91.5))) / 2, abs=0.01)


def test_reproduces_a_distant_environment_in_world_directions_ignoring_translation():
    T = pose([0, 70, 30], t=(3.0, -1.0, 0.5))
    b = BaselineMap(32, MODEL, 170.0)
    b.update(fisheye_of_environment(T), T)
    d = cube_directions(32).reshape(6, 32, 32, 3)
    err = np.abs(b.faces - env_colour(d))[b.observed()]
    assert b.observed().sum() > 2000 and err.max() < 0.02  # quantisation + bilinear on a smooth field
    moved = BaselineMap(32, MODEL, 170.0)
    moved.update(fisheye_of_environment(T), pose([0, 70, 30], t=(-5.0, 4.0, 2.0)))
    np.testing.assert_array_equal(moved.faces, b.faces)


def test_accumulates_without_clearing_and_keeps_the_last_value():
    up, down = pose([0, 0, 0]), pose([180, 0, 0])  # optical axis +Z (ceiling), then -Z (floor)
    b = BaselineMap(16, MODEL, 150.0)
    b.update(np.full((W, W, 3), 100, np.uint8), up)
    first = b.observed().copy()
    assert first[4].all() and not first[5].any()
    b.update(np.full((W, W, 3), 200, np.uint8), down)
    assert b.observed()[5].all() and np.array_equal(b.observed() & first, first)  # nothing forgotten
    only_first = first & ~BaselineEnvmap_seen(down, 16, 150.0)
    np.testing.assert_allclose(b.faces[only_first], 100 / 255, atol=1e-6)
    np.testing.assert_allclose(b.faces[b.observed() & ~only_first], 200 / 255, atol=1e-6)
    assert coverage(b.observed()) == pytest.approx(1 - np.cos(np.radians(75)), abs=0.02)  # two 150 deg caps
    b.reset()
    assert not b.observed().any() and b.frames == 0 and np.all(b.faces == np.float32(128 / 255))


def BaselineEnvmap_seen(T, size, fov):
    """Texels within fov/2 of the optical axis of pose T (an independent in-view test)."""
    axis = T[:3, 2]
    row, col = np.meshgrid(np.arange(size), np.arange(size), indexing="ij")
    d = np.stack([texel_direction(f, row, col, size) for f in range(6)])
    return d @ axis >= np.cos(np.radians(fov / 2))


def test_rejects_wrong_image():
    b = BaselineMap(8, MODEL, 183.0)
    with pytest.raises(SchemaError, match="uint8"):
        b.update(np.zeros((W, W + 1, 3), np.uint8), np.eye(4))
    assert b.faces_as("uint8").dtype == np.uint8 and b.faces_as("float16", alpha=True).shape == (6, 8, 8, 4)


def _frames(poses):
    info = MODEL.to_camera_info("fisheye", 0)
    yield "camera_info", info
    for k, T in enumerate(poses):
        stamp = (k + 1) * 66_000_000
        yield "fisheye_pose", PoseStamped(Header(stamp, "world"), "fisheye", T)
        yield "fisheye", Image(Header(stamp, "fisheye"), fisheye_of_environment(T), "rgb8")


OBJECTS = {"object_ids": ["sphere", "probe_b"], "object_positions": [[2.2, 1.9, 0.9], [3.8, 1, 1]]}


def test_node_publishes_the_same_map_for_every_object():
    poses = [pose([0, 0, 0]), pose([0, 100, 0], t=(1, 0, 0)), pose([180, 0, 0])]
    ctx = run_node(BaselineNode, _frames(poses), {**OBJECTS, "face_size": 16, "fov_deg": 170,
                                                  "publish_every": 2, "alpha": True}, node_id="baseline")
    sphere, probe = ctx.outputs("envmap/sphere"), ctx.outputs("envmap/probe_b")
    assert len(sphere) == len(probe) == 1  # frames 2 only (publish_every 2)
    m = sphere[0]
    assert m.object_id == "sphere" and not m.linear and m.faces.dtype == np.uint8 and m.faces.shape == (6, 16, 16, 4)
    assert m.header.stamp_ns == 2 * 66_000_000 and m.header.frame_id == "world"
    np.testing.assert_array_equal(m.position, [2.2, 1.9, 0.9])
    np.testing.assert_array_equal(probe[0].faces, m.faces)
    np.testing.assert_array_equal(probe[0].position, [3.8, 1.0, 1.0])
    ref = BaselineMap(16, MODEL, 170.0)
    for T in poses[:2]:
        ref.update(fisheye_of_environment(T), T)
    np.testing.assert_array_equal(m.faces[..., :3], ref.faces_as("uint8"))
    np.testing.assert_array_equal(m.faces[..., 3] == 255, ref.observed())


def test_node_waits_for_camera_info_moves_objects_and_checks_params():
    frames = [f for f in _frames([pose([0, 0, 0])]) if f[0] != "camera_info"]
    ctx = run_node(BaselineNode, frames, {**OBJECTS, "face_size": 8, "dtype": "float16"})
    assert ctx.outputs("envmap/sphere") == []
    moves = [("object_poses", PoseStamped(Header(1, "world"), "probe_b", pose([0, 0, 0], t=(1, 2, 3)))),
             ("object_poses", PoseStamped(Header(1, "world"), "teapot", pose([0, 0, 0], t=(4, 5, 6))))]
    ctx = run_node(BaselineNode, moves + list(_frames([pose([0, 0, 0])])), {**OBJECTS, "face_size": 8,
                                                                            "dtype": "float16"})
    assert ctx.outputs("envmap/sphere")[0].faces.dtype == np.float16
    np.testing.assert_array_equal(ctx.outputs("envmap/probe_b")[0].position, [1, 2, 3])
    np.testing.assert_array_equal(ctx.outputs("envmap/teapot")[0].position, [4, 5, 6])
    for bad in ({"object_ids": ["a"], "object_positions": []}, {"object_ids": ["a"], "object_positions": [[0, 0]]},
                {"object_ids": ["a/b"], "object_positions": [[0, 0, 0]]},
                {"object_ids": ["a", "a"], "object_positions": [[0, 0, 0], [1, 1, 1]]}):
        with pytest.raises(ParamError, match="object_"):
            run_node(BaselineNode, [], bad)
