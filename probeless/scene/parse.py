"""Read and validate a scene YAML file into a :class:`~probeless.scene.spec.Scene`.

Every problem raises :class:`~probeless.errors.SceneError` naming the file, line and key path.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from probeless.errors import SceneError
from probeless.geom.rotation import rotation_from_rpy
from probeless.scene.extends import load_scene_doc, plain
from probeless.scene.fields import Where, boolean, integer, mapping, number, sequence, string, vector
from probeless.scene.parse_effects import parse_given, parse_sensor_effects
from probeless.scene.spec import (
    FisheyeCamera,
    Furniture,
    Keyframe,
    Light,
    Material,
    RgbdCamera,
    Scene,
    VirtualObject,
    Window,
)
from probeless.scene.validate import check_scene

DEFAULT_COLORS = {"walls": (0.7, 0.7, 0.68), "floor": (0.35, 0.25, 0.18), "ceiling": (0.85, 0.85, 0.83)}


def load_scene(path: str | Path) -> Scene:
    """Parse and validate the scene file at ``path``."""
    path = Path(path)
    if not path.is_file():
        raise SceneError(f"{path}: scene file not found")
    doc, chain = load_scene_doc(path)
    top = Where(f"{path} (extends {', '.join(str(p) for p in chain)})" if chain else str(path))
    mapping(doc, top, ("name", "room", "rig", "trajectory"),
            ("lights", "furniture", "virtual_objects", "sensor_effects", "given"))
    room = mapping(doc["room"], top.child("room", doc), ("floorplan", "ceiling_height"), ("materials", "windows"))
    rw = top.child("room", doc)
    floor = np.array([vector(v, rw.child("floorplan", room).child(i, room["floorplan"]), 2)
                      for i, v in enumerate(sequence(room["floorplan"], rw.child("floorplan", room), min_len=3))])
    mats = room.get("materials") or {}
    mw = rw.child("materials", room)
    mapping(mats, mw, (), ("walls", "floor", "ceiling"))
    scene = Scene(
        name=string(doc["name"], top.child("name", doc)), path=path, floorplan=floor,
        ceiling_height=number(room["ceiling_height"], rw.child("ceiling_height", room), min=0, strict_min=True),
        **{k: _material(mats.get(k), mw.child(k, mats), path.parent, DEFAULT_COLORS[k]) for k in DEFAULT_COLORS},
        windows=tuple(_window(w, rw.child("windows", room).child(i, room["windows"]))
                      for i, w in enumerate(_list(room, "windows", rw))),
        lights=tuple(_light(v, top.child("lights", doc).child(i, doc["lights"]))
                     for i, v in enumerate(_list(doc, "lights", top))),
        furniture=tuple(_furniture(v, top.child("furniture", doc).child(i, doc["furniture"]), path.parent)
                        for i, v in enumerate(_list(doc, "furniture", top))),
        virtual_objects=tuple(_virtual(v, top.child("virtual_objects", doc).child(i, doc["virtual_objects"]))
                              for i, v in enumerate(_list(doc, "virtual_objects", top))),
        **_rig(doc["rig"], top.child("rig", doc)),
        keyframes=_trajectory(doc["trajectory"], top.child("trajectory", doc)),
        sensor_effects=(parse_sensor_effects(doc["sensor_effects"], top.child("sensor_effects", doc))
                        if doc.get("sensor_effects") is not None else None),
        given=parse_given(doc["given"], top.child("given", doc), path.parent) if doc.get("given") is not None else None,
    )
    check_scene(scene, top, doc)
    return scene


def _list(container: dict, key: str, where: Where) -> list:
    return sequence(container[key], where.child(key, container)) if container.get(key) is not None else []


def _material(value, where: Where, root: Path, default) -> Material:
    if value is None:
        return Material(np.array(default, np.float64))
    mapping(value, where, (), ("color", "texture", "tile_m"))
    if "color" not in value and "texture" not in value:
        raise where.error("needs 'color' or 'texture'")
    color = vector(value["color"], where.child("color", value), 3, min=0) if "color" in value else np.ones(3)
    if np.any(color > 1):
        raise where.child("color", value).error(f"albedo must be within 0..1, got {color.tolist()}")
    texture = None
    if "texture" in value:
        texture = root / string(value["texture"], where.child("texture", value))
        if not texture.is_file():
            raise where.child("texture", value).error(f"texture file not found: {texture}")
    tile = number(value.get("tile_m", 1.0), where.child("tile_m", value), min=0, strict_min=True)
    return Material(color, texture, tile)


def _window(v, where: Where) -> Window:
    mapping(v, where, ("wall", "center", "size", "radiance"))
    return Window(integer(v["wall"], where.child("wall", v), min=0), vector(v["center"], where.child("center", v), 2),
                  vector(v["size"], where.child("size", v), 2, min=0, strict_min=True),
                  vector(v["radiance"], where.child("radiance", v), 3, min=0))


def _light(v, where: Where) -> Light:
    mapping(v, where, ("position", "size", "radiance"), ("schedule",))
    sw = where.child("schedule", v)
    schedule = []
    for i, entry in enumerate(sequence(v.get("schedule", [[0.0, True]]), sw, min_len=1)):
        ew = sw.child(i, v.get("schedule"))
        if not isinstance(entry, list) or len(entry) != 2:
            raise ew.error(f"expected [t_seconds, on], got {entry!r}")
        schedule.append((number(entry[0], ew), boolean(entry[1], ew)))
        if i and schedule[-1][0] <= schedule[-2][0]:
            raise ew.error("schedule times must increase")
    return Light(vector(v["position"], where.child("position", v), 3),
                 vector(v["size"], where.child("size", v), 2, min=0, strict_min=True),
                 vector(v["radiance"], where.child("radiance", v), 3, min=0), tuple(schedule))


def _furniture(v, where: Where, root: Path) -> Furniture:
    mapping(v, where, ("color",), ("box", "mesh"))
    color = vector(v["color"], where.child("color", v), 3, min=0)
    if ("box" in v) == ("mesh" in v):
        raise where.error("needs exactly one of 'box' or 'mesh'")
    if "box" in v:
        bw = where.child("box", v)
        b = mapping(v["box"], bw, ("center", "size"))
        return Furniture("box", color, center=vector(b["center"], bw.child("center", b), 3),
                         size=vector(b["size"], bw.child("size", b), 3, min=0, strict_min=True))
    mw = where.child("mesh", v)
    m = mapping(v["mesh"], mw, ("path", "position"), ("scale", "yaw_deg", "up"))
    mesh_path = root / string(m["path"], mw.child("path", m))
    if not mesh_path.is_file():
        raise mw.child("path", m).error(f"mesh file not found: {mesh_path}")
    return Furniture("mesh", color, path=mesh_path, position=vector(m["position"], mw.child("position", m), 3),
                     scale=number(m.get("scale", 1.0), mw.child("scale", m), min=0, strict_min=True),
                     yaw_deg=number(m.get("yaw_deg", 0.0), mw.child("yaw_deg", m)),
                     up=string(m.get("up", "y"), mw.child("up", m), ("y", "z")))


def _virtual(v, where: Where) -> VirtualObject:
    mapping(v, where, ("id", "position", "radius"), ("material", "mesh"))
    oid = string(v["id"], where.child("id", v))
    if not oid.replace("_", "").replace("-", "").isalnum():
        raise where.child("id", v).error(f"{oid!r}: use letters, digits, '_' and '-' (it becomes a topic name)")
    material = None
    if v.get("material") is not None:
        mw = where.child("material", v)
        material = mapping(v["material"], mw, ("type",), tuple(k for k in v["material"] if k != "type"))
        string(material["type"], mw.child("type", material))
        material = plain(material)
    return VirtualObject(oid, vector(v["position"], where.child("position", v), 3),
                         number(v["radius"], where.child("radius", v), min=0, strict_min=True), material,
                         string(v.get("mesh", "sphere"), where.child("mesh", v)))


def _rig(v, where: Where) -> dict:
    mapping(v, where, ("rgbd", "fisheye", "fisheye_from_rgbd"))
    rw, fw, tw = where.child("rgbd", v), where.child("fisheye", v), where.child("fisheye_from_rgbd", v)
    r = mapping(v["rgbd"], rw, ("width", "height", "fx", "fy", "cx", "cy", "fps"),
                ("depth_noise_m", "depth_max_m", "exposure"))
    num = lambda d, w, k, **kw: number(d[k], w.child(k, d), **kw)  # noqa: E731
    K = np.array([[num(r, rw, "fx", min=0, strict_min=True), 0, num(r, rw, "cx")],
                  [0, num(r, rw, "fy", min=0, strict_min=True), num(r, rw, "cy")], [0, 0, 1]])
    rgbd = RgbdCamera(integer(r["width"], rw.child("width", r), min=1, max=8192),
                      integer(r["height"], rw.child("height", r), min=1, max=8192), K,
                      num(r, rw, "fps", min=0, strict_min=True),
                      number(r.get("depth_noise_m", 0.0), rw.child("depth_noise_m", r), min=0),
                      number(r.get("depth_max_m", 10.0), rw.child("depth_max_m", r), min=0, strict_min=True),
                      number(r.get("exposure", 1.0), rw.child("exposure", r), min=0, strict_min=True))
    f = mapping(v["fisheye"], fw, ("model", "width", "height", "fov_deg", "fps"), ("time_offset_s", "exposure", "xi"))
    fisheye = FisheyeCamera(string(f["model"], fw.child("model", f), ("omnidir", "kannala_brandt")),
                            integer(f["width"], fw.child("width", f), min=1, max=8192),
                            integer(f["height"], fw.child("height", f), min=1, max=8192),
                            number(f["fov_deg"], fw.child("fov_deg", f), min=10, max=240),
                            num(f, fw, "fps", min=0, strict_min=True),
                            number(f.get("time_offset_s", 0.0), fw.child("time_offset_s", f)),
                            number(f.get("exposure", 1.0), fw.child("exposure", f), min=0, strict_min=True),
                            number(f.get("xi", 1.0), fw.child("xi", f), min=0))
    t = mapping(v["fisheye_from_rgbd"], tw, ("translation", "rpy_deg"))
    T = np.eye(4)
    T[:3, :3] = rotation_from_rpy(vector(t["rpy_deg"], tw.child("rpy_deg", t), 3))
    T[:3, 3] = vector(t["translation"], tw.child("translation", t), 3)
    return {"rgbd": rgbd, "fisheye": fisheye, "fisheye_from_rgbd": T}


def _trajectory(v, where: Where) -> tuple[Keyframe, ...]:
    mapping(v, where, ("keyframes",))
    kw = where.child("keyframes", v)
    out: list[Keyframe] = []
    for i, k in enumerate(sequence(v["keyframes"], kw, min_len=1)):
        w = kw.child(i, v["keyframes"])
        mapping(k, w, ("t", "position", "look_at"))
        key = Keyframe(number(k["t"], w.child("t", k), min=0), vector(k["position"], w.child("position", k), 3),
                       vector(k["look_at"], w.child("look_at", k), 3))
        if out and key.t <= out[-1].t:
            raise w.child("t", k).error(f"keyframe times must increase ({key.t} after {out[-1].t})")
        if np.linalg.norm(key.look_at - key.position) < 1e-6:
            raise w.child("look_at", k).error("look_at equals position")
        out.append(key)
    return tuple(out)


__all__ = ["load_scene"]
