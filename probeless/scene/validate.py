"""Geometric consistency of a parsed scene: a valid floorplan (see probeless.geom.floorplan), all inside the room."""

from __future__ import annotations

import numpy as np

from probeless.errors import GeometryError
from probeless.geom import polygon
from probeless.geom.floorplan import check_floorplan
from probeless.scene.fields import Where
from probeless.scene.obj import place_mesh, read_obj
from probeless.scene.spec import Furniture, Scene

EPS = 1e-6


def check_scene(scene: Scene, top: Where, doc: dict) -> None:
    """Raise SceneError (naming the key) for the first geometric inconsistency."""
    room = doc["room"]
    fw = top.child("room", doc).child("floorplan", room)
    _check_floorplan(scene.floorplan, fw)
    for i, win in enumerate(scene.windows):
        _check_window(scene, win, top.child("room", doc).child("windows", room).child(i, room["windows"]))
    for i, light in enumerate(scene.lights):
        w = top.child("lights", doc).child(i, doc["lights"])
        half = light.size / 2
        corners = light.position[:2] + np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * half
        if not _inside(scene, corners) or not (0 < light.position[2] <= scene.ceiling_height):
            raise w.child("position", doc["lights"][i]).error("light panel is not inside the room")
    boxes = []
    for i, item in enumerate(scene.furniture):
        w = top.child("furniture", doc).child(i, doc["furniture"])
        lo, hi = _furniture_bounds(item)
        footprint = _outline(lo[:2], hi[:2]) if item.kind == "box" else _mesh_points(item)[:, :2]
        if not _inside(scene, footprint) or lo[2] < -1e-3 or hi[2] > scene.ceiling_height + EPS:
            raise w.child(item.kind, doc["furniture"][i]).error(
                f"furniture is not inside the room (bounds {np.round(lo, 3).tolist()} .. {np.round(hi, 3).tolist()})")
        boxes.append((lo, hi))
    for i, obj in enumerate(scene.virtual_objects):
        w = top.child("virtual_objects", doc).child(i, doc["virtual_objects"])
        pw = w.child("position", doc["virtual_objects"][i])
        if (not polygon.contains(scene.floorplan, obj.position[:2])[0]
                or polygon.distance_to_boundary(scene.floorplan, obj.position[:2])[0] < obj.radius
                or not obj.radius <= obj.position[2] <= scene.ceiling_height - obj.radius):
            raise pw.error(f"virtual object {obj.id!r} (radius {obj.radius}) is not inside the room")
        for j, (lo, hi) in enumerate(boxes):
            if np.linalg.norm(obj.position - np.clip(obj.position, lo, hi)) < obj.radius:
                raise pw.error(f"virtual object {obj.id!r} intersects furniture[{j}]")
    if len({o.id for o in scene.virtual_objects}) != len(scene.virtual_objects):
        raise top.child("virtual_objects", doc).error("virtual object ids must be unique")
    _check_trajectory(scene, top.child("trajectory", doc).child("keyframes", doc["trajectory"]))
    if scene.given is not None:
        _check_given(scene, top.child("given", doc))


def _check_given(scene: Scene, where: Where) -> None:
    """The given block resolves (valid perturbed floorplan, loadable files) and keeps fisheye stamps >= 0."""
    from probeless.scene.given import given_rig  # noqa: PLC0415 (avoid an import cycle)
    from probeless.scene.rig import fisheye_model  # noqa: PLC0415

    given_rig(scene.given, scene.floorplan, scene.ceiling_height, scene.fisheye_from_rgbd,
              fisheye_model(scene).to_camera_info("fisheye"), where=f"{where.file}: {where.path}")
    if scene.fisheye.time_offset_s + scene.given.clock_offset_s < 0:
        raise where.error(f"clock_offset_s {scene.given.clock_offset_s} makes the first fisheye stamp negative "
                          f"(rig.fisheye.time_offset_s is {scene.fisheye.time_offset_s})")


def _check_floorplan(poly: np.ndarray, where: Where) -> None:
    try:
        check_floorplan(poly)
    except GeometryError as exc:
        raise where.error(str(exc)) from None


def _check_window(scene: Scene, win, where: Where) -> None:
    n = len(scene.floorplan)
    if win.wall >= n:
        raise where.error(f"wall {win.wall} does not exist (the floorplan has walls 0..{n - 1})")
    length = np.linalg.norm(scene.floorplan[(win.wall + 1) % n] - scene.floorplan[win.wall])
    (u, h), (w, hh) = win.center, win.size
    if u - w / 2 < -EPS or u + w / 2 > length + EPS or h - hh / 2 < -EPS or h + hh / 2 > scene.ceiling_height + EPS:
        raise where.error(f"window does not fit on wall {win.wall} ({length:.3f} m long, "
                          f"{scene.ceiling_height} m high)")


def _check_trajectory(scene: Scene, where: Where) -> None:
    from probeless.scene.trajectory import camera_pose  # noqa: PLC0415 (avoid an import cycle)

    times = np.linspace(0.0, scene.duration, max(2, int(scene.duration * 20) + 1))
    for t in times:
        rgbd = camera_pose(scene.keyframes, t)
        fisheye = rgbd @ np.linalg.inv(scene.fisheye_from_rgbd)
        for name, pose in (("RGB-D camera", rgbd), ("fisheye camera", fisheye)):
            p = pose[:3, 3]
            if not (_inside(scene, p[None, :2]) and 0 < p[2] < scene.ceiling_height):
                raise where.error(f"the {name} leaves the room at t = {t:.2f} s (at {np.round(p, 3).tolist()})")


def _inside(scene: Scene, points: np.ndarray) -> bool:
    """All points inside the floorplan or on its boundary."""
    pts = np.atleast_2d(points)
    on_edge = polygon.distance_to_boundary(scene.floorplan, pts) < EPS
    return bool(np.all(polygon.contains(scene.floorplan, pts) | on_edge))


def _outline(lo: np.ndarray, hi: np.ndarray, step: float = 0.05) -> np.ndarray:
    """Points every ``step`` metres along the rectangle [lo, hi] (catches non-convex rooms' corners)."""
    corners = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
    pts = []
    for a, b in zip(corners, np.roll(corners, -1, axis=0)):
        n = max(2, int(np.linalg.norm(b - a) / step) + 1)
        pts.append(a + np.linspace(0, 1, n)[:, None] * (b - a))
    return np.concatenate(pts)


def _mesh_points(item: Furniture) -> np.ndarray:
    vertices, _ = read_obj(item.path)
    return place_mesh(vertices, item.up, item.scale, item.yaw_deg, item.position)


def _furniture_bounds(item: Furniture) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned bounds (lo, hi) of a piece of furniture [m, world]."""
    if item.kind == "box":
        return item.center - item.size / 2, item.center + item.size / 2
    pts = _mesh_points(item)
    return pts.min(axis=0), pts.max(axis=0)
