"""Scene files: parsing, validation errors naming the key, geometry building, trajectory, frame schedule."""

from __future__ import annotations

import copy
import glob
from pathlib import Path

import numpy as np
import pytest
import yaml
from locations import REPO
from matplotlib.path import Path as MplPath
from scene_examples import BASE
from scipy.spatial.transform import Rotation

from probeless.errors import SceneError
from probeless.geom import polygon
from probeless.geom.rotation import rotation_from_rpy
from probeless.scene.build import build_geometry
from probeless.scene.obj import read_obj
from probeless.scene.parse import load_scene
from probeless.scene.rig import frame_schedule
from probeless.scene.tessellate import triangulate
from probeless.scene.trajectory import camera_pose

ROOT = REPO
SCENES = sorted(glob.glob(str(ROOT / "launch/scenes/*.yaml")))

def write_scene(tmp_path: Path, doc: dict) -> Path:
    path = tmp_path / "scene.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def edited(**changes) -> dict:
    """BASE with dotted-path edits, e.g. ``edited(**{"room.ceiling_height": 3})``."""
    doc = copy.deepcopy(BASE)
    for dotted, value in changes.items():
        *parents, last = dotted.split(".")
        node = doc
        for key in parents:
            node = node[int(key)] if key.isdigit() else node[key]
        node[int(last) if last.isdigit() else last] = value
    return doc


@pytest.mark.parametrize("path", SCENES, ids=[Path(p).stem for p in SCENES])
def test_shipped_scenes_parse_and_build(path):
    scene = load_scene(path)
    geometry = build_geometry(scene)
    floor = next(s for s in geometry.surfaces if s.name == "floor")
    p = floor.positions.reshape(-1, 3, 3).astype(np.float64)
    area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum()
    assert area == pytest.approx(polygon.signed_area(scene.floorplan), rel=1e-6)
    assert len(geometry.lights) == len(scene.lights) + len(scene.windows)


def test_shipped_scene_kinds():
    scenes = {Path(p).stem: load_scene(p) for p in SCENES}
    convex = [s for s in scenes.values() if _is_convex(s.floorplan)]
    non_convex = [s for s in scenes.values() if not _is_convex(s.floorplan)]
    switching = [s for s in scenes.values() if any(len({on for _, on in li.schedule}) > 1 for li in s.lights)]
    assert convex and non_convex and switching


def _is_convex(poly: np.ndarray) -> bool:
    d = np.roll(poly, -1, axis=0) - poly
    cross = d[:, 0] * np.roll(d[:, 1], -1) - d[:, 1] * np.roll(d[:, 0], -1)
    return bool(np.all(cross >= -1e-12))


@pytest.mark.parametrize("changes, where", [
    ({"room.colour": 1}, "room.colour"),
    ({"room.floorplan": [[0, 0], [0, 3], [4, 3], [4, 0]]}, "counter-clockwise"),
    ({"room.floorplan": [[0, 0], [4, 0], [0, 3], [4, 3]]}, "self-intersecting"),
    ({"furniture.0.box": {"center": [3.9, 1.5, 0.35], "size": [1.0, 0.6, 0.7]}}, "furniture[0].box"),
    ({"virtual_objects.0.position": [2.0, 1.5, 0.72]}, "intersects furniture[0]"),
    ({"virtual_objects.0.position": [5.0, 1.5, 0.9]}, "virtual_objects[0].position"),
    ({"room.windows.0.size": [5.0, 0.8]}, "room.windows[0]"),
    ({"room.windows.0.wall": 7}, "wall 7 does not exist"),
    ({"lights.0.schedule": [[2, True], [1, False]]}, "schedule times must increase"),
    ({"rig.fisheye.model": "equisolid"}, "rig.fisheye.model"),
    ({"rig.rgbd.fx": -5}, "rig.rgbd.fx"),
    ({"trajectory.keyframes.1.position": [6.0, 0.6, 1.4]}, "leaves the room"),
    ({"furniture.0": {"mesh": {"path": "nope.obj", "position": [1, 1, 0]}, "color": [1, 1, 1]}}, "mesh file not found"),
    ({"virtual_objects.0.id": "a b"}, "virtual_objects[0].id"),
])
def test_scene_errors_name_the_key(tmp_path, changes, where):
    path = write_scene(tmp_path, edited(**changes))
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert where in str(info.value) and str(path) in str(info.value)


def test_scene_error_has_line_number(tmp_path):
    path = write_scene(tmp_path, edited(**{"rig.rgbd.fps": "fast"}))
    with pytest.raises(SceneError, match=r"scene\.yaml:\d+: rig\.rgbd\.fps"):
        load_scene(path)


def test_rpy_matches_scipy():
    rng = np.random.default_rng(1)
    for rpy in rng.uniform(-180, 180, (20, 3)):
        expected = Rotation.from_euler("xyz", rpy, degrees=True).as_matrix()
        np.testing.assert_allclose(rotation_from_rpy(rpy), expected, atol=1e-12)


def test_fisheye_looks_up_when_rgbd_is_level(tmp_path):
    doc = edited(**{"trajectory.keyframes": [{"t": 0, "position": [1, 1, 1.4], "look_at": [3, 1, 1.4]}]})
    scene = load_scene(write_scene(tmp_path, doc))
    world_from_fisheye = camera_pose(scene.keyframes, 0.0) @ np.linalg.inv(scene.fisheye_from_rgbd)
    np.testing.assert_allclose(world_from_fisheye[:3, 2], [0, 0, 1], atol=1e-12)  # optical axis = world up
    # 6 cm forward of and 2 cm above the RGB-D camera (forward = +x here)
    np.testing.assert_allclose(world_from_fisheye[:3, 3], [1.06, 1.0, 1.42], atol=1e-12)


def test_trajectory_hits_keyframes_and_looks_at_target():
    scene = load_scene(SCENES[0])
    for key in scene.keyframes:
        T = camera_pose(scene.keyframes, key.t)
        np.testing.assert_allclose(T[:3, 3], key.position, atol=1e-12)
        forward = (key.look_at - key.position) / np.linalg.norm(key.look_at - key.position)
        np.testing.assert_allclose(T[:3, 2], forward, atol=1e-12)
    for t in np.linspace(0, scene.duration, 13):
        R = camera_pose(scene.keyframes, t)[:3, :3]
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
        assert np.linalg.det(R) == pytest.approx(1.0)
        assert R[2, 0] == pytest.approx(0.0, abs=1e-12)  # no roll: the x axis stays horizontal
        assert R[2, 1] < 0  # image y points down in the world


def test_trajectory_is_smooth():
    scene = load_scene(SCENES[0])
    ts = np.linspace(0, scene.duration, 2001)
    p = np.array([camera_pose(scene.keyframes, t)[:3, 3] for t in ts])
    v = np.diff(p, axis=0) / np.diff(ts)[:, None]
    assert np.max(np.abs(np.diff(v, axis=0))) < 0.01  # no velocity jumps at keyframes
    np.testing.assert_allclose(v[0], 0, atol=0.01)  # eases in


def test_frame_schedule_rates_and_offset():
    scene = load_scene(next(p for p in SCENES if "lounge" in p))
    events = frame_schedule(scene)
    rgbd = [e.t for e in events if e.kind == "rgbd"]
    fish = [e.t for e in events if e.kind == "fisheye"]
    assert len(rgbd) == int(scene.duration * 30) + 1 and len(fish) == int((scene.duration - 0.013) * 15) + 1
    np.testing.assert_allclose(np.diff(rgbd), 1 / 30)
    np.testing.assert_allclose(np.diff(fish), 1 / 15)
    assert fish[0] == pytest.approx(0.013)
    assert [e.t for e in events] == sorted(e.t for e in events)


def test_contains_matches_matplotlib():
    poly = np.array([[0, 0], [6, 0], [6, 3], [3, 3], [3, 5], [0, 5]], float)
    pts = np.random.default_rng(0).uniform(-1, 7, (2000, 2))
    expected = MplPath(poly).contains_points(pts)
    near_edge = polygon.distance_to_boundary(poly, pts) < 1e-6
    assert np.array_equal(polygon.contains(poly, pts)[~near_edge], expected[~near_edge])


@pytest.mark.parametrize("seed", range(5))
def test_triangulation_covers_polygon(seed):
    rng = np.random.default_rng(seed)
    n = 12
    angles = np.sort(rng.uniform(0, 2 * np.pi, n))
    radii = rng.uniform(0.3, 1.0, n)  # star-shaped, usually non-convex
    poly = np.stack([radii * np.cos(angles), radii * np.sin(angles)], axis=1)
    tris = triangulate(poly)
    assert len(tris) == n - 2
    a, b, c = poly[tris[:, 0]], poly[tris[:, 1]], poly[tris[:, 2]]
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    assert np.all(cross > 0)
    assert cross.sum() / 2 == pytest.approx(polygon.signed_area(poly))
    centroids = (a + b + c) / 3
    assert MplPath(poly).contains_points(centroids).all()


def test_teapot_obj_counts():
    v, f = read_obj(ROOT / "launch/scenes/meshes/teapot.obj")
    assert (len(v), len(f)) == (3644, 6320)  # as stated in the data README


def test_ambient_is_the_integrating_sphere_estimate(tmp_path):
    scene = load_scene(write_scene(tmp_path, BASE))
    g = build_geometry(scene)
    # independent: room surfaces + box faces, all plain colours
    room_area = 2 * 12 + 2 * (4 + 3) * 2.5
    box_area = 2 * (1.0 * 0.6 + 1.0 * 0.7 + 0.6 * 0.7)
    walls, floor, ceil = np.array([0.7, 0.7, 0.68]), np.array([0.35, 0.25, 0.18]), np.array([0.85, 0.85, 0.83])
    rho = (walls * 2 * 7 * 2.5 + floor * 12 + ceil * 12 + np.array([0.5, 0.4, 0.3]) * box_area) / (room_area + box_area)
    expected = rho / (1 - rho) * 20 * 0.25 / (room_area + box_area)
    np.testing.assert_allclose(g.lights[0].ambient, expected, rtol=1e-5)
