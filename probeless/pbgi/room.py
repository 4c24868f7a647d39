"""A synthetic reference room lit only by its own emitting surfaces, its point cloud and object cameras.

The room is an axis-aligned box (world frame, metres, z up, floor at z = 0) tiled by one-sided
rectangular :class:`Patch` es that emit linear HDR radiance [W sr^-1 m^-2, linear RGB] into the
room. Bright lights (a ceiling lamp, a window) are patches of their own, cut out of the surface they
sit in, so no two patches overlap and a light can be sampled on its own. The virtual object is a
sphere inside the room; ``"red_wall"`` adds a saturated panel 30 cm from the sphere's surface.

The same room is rendered by Mitsuba (:mod:`probeless.pbgi.reference`), every patch an area emitter
with a bitmap radiance texture, and sampled into a coloured cloud (:func:`sample_cloud`) whose colours
are exactly what that emitter returns at each point.

Texture convention (shared by both sides): texel (row r, column c) of a patch's ``radiance`` image
is centred on ``origin + (c + 0.5) / W * edge_u + (r + 0.5) / H * edge_v``; a point's value is the
bilinear interpolation of the four nearest texel centres, clamped at the border. This is Mitsuba's
``bitmap`` texture with ``filter_type="bilinear"`` and ``wrap_mode="clamp"`` on a ``rectangle`` whose
local x runs along ``edge_u`` and local y along ``edge_v`` (uv = ((x + 1) / 2, (y + 1) / 2)).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from probeless.errors import PbgiError
from probeless.scene.trajectory import look_at

ROOM_NAMES = ("plain", "red_wall", "decals", "decals_0.5mm", "decals_1mm", "decals_5mm")  # decals: room_decals
TEXEL = 0.02                       # default texel size of the room textures [m]
CEILING_LIGHT = (40.0, 36.0, 30.0)  # warm lamp radiance (HDR) [linear RGB]
RED = (0.9, 0.05, 0.05)            # red panel colour, times PANEL_GAIN
PANEL_GAIN = 2.0


@dataclass(frozen=True, eq=False)
class Patch:
    """A one-sided emitting rectangle; it emits along ``normal`` = unit(edge_u x edge_v)."""

    name: str
    origin: np.ndarray    # (3,) corner where texel (0, 0) sits [m, world]
    edge_u: np.ndarray    # (3,) side along the image columns [m, world]
    edge_v: np.ndarray    # (3,) side along the image rows [m, world]
    radiance: np.ndarray  # (H, W, 3) float32 linear RGB radiance texture
    in_cloud: bool = True  # False: rendered by Mitsuba only (a surface hidden behind a decal, no scanner sees it)

    @property
    def normal(self) -> np.ndarray:
        """Unit emitting direction (into the room) [world]."""
        n = np.cross(self.edge_u, self.edge_v)
        return n / np.linalg.norm(n)

    @property
    def area(self) -> float:
        """Area [m^2]."""
        return float(np.linalg.norm(np.cross(self.edge_u, self.edge_v)))

    def at(self, uv: np.ndarray) -> np.ndarray:
        """World points (N, 3) of patch coordinates ``uv`` (N, 2) in [0, 1]^2."""
        uv = np.asarray(uv, np.float64)
        return self.origin + uv[:, :1] * self.edge_u + uv[:, 1:] * self.edge_v


@dataclass(frozen=True, eq=False)
class ReferenceRoom:
    """Box room ``[0, size]`` [m, world, z up] of emitting patches around a sphere object."""

    name: str
    size: np.ndarray                # (3,) room extent x, y, z [m]
    patches: tuple[Patch, ...]      # the room's surfaces (walls, floor, ceiling, lights)
    object_centre: np.ndarray       # (3,) sphere centre [m, world]
    object_radius: float = 0.15     # sphere radius [m]
    panels: tuple[Patch, ...] = ()  # extra emitting panels inside the room (one-sided)

    @property
    def all_patches(self) -> tuple[Patch, ...]:
        """Room surfaces then panels."""
        return self.patches + self.panels


def radiance_at(patch: Patch, uv: np.ndarray) -> np.ndarray:
    """(N, 3) float32 radiance at patch coordinates ``uv`` (N, 2): bilinear, clamped (module doc)."""
    img = patch.radiance
    h, w = img.shape[:2]
    x = np.clip(np.asarray(uv[:, 0], np.float64) * w - 0.5, 0, w - 1)
    y = np.clip(np.asarray(uv[:, 1], np.float64) * h - 0.5, 0, h - 1)
    x0, y0 = np.minimum(x.astype(np.int64), max(w - 2, 0)), np.minimum(y.astype(np.int64), max(h - 2, 0))
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    top = img[y0, x0] * (1 - fx) + img[y0, x1] * fx
    bottom = img[y1, x0] * (1 - fx) + img[y1, x1] * fx
    return (top * (1 - fy) + bottom * fy).astype(np.float32)


def _pattern(rng: np.random.Generator, base, amplitude: float = 0.12, planks: bool = False):
    """A smooth, mildly coloured radiance field p (N, 3) -> (N, 3): ``base`` times low-frequency waves."""
    waves = [(rng.normal(size=3) * rng.uniform(2, 10), rng.uniform(0, 2 * np.pi, 3)) for _ in range(4)]
    base = np.asarray(base, np.float64)

    def field(p: np.ndarray) -> np.ndarray:
        s = np.zeros((len(p), 3))
        for k, phase in waves:
            s += np.sin((p @ k)[:, None] + phase) / len(waves)
        out = base * (1 + amplitude * 2 * s)
        if planks:  # 20 cm boards of alternating brightness
            out *= (1 + 0.1 * (-1.0) ** np.floor(p[:, 1:2] / 0.2))
        return out
    return field


def _lamp(base, gradient: float = 0.0):
    """Radiance field of a light: ``base``, brighter towards +z by ``gradient`` per metre (window sky)."""
    base = np.asarray(base, np.float64)
    return lambda p: base * (1 + gradient * (p[:, 2:3] - 1.5))


def _patch(name: str, origin, edge_u, edge_v, field, texel: float) -> Patch:
    """A patch whose texture samples ``field`` (world points -> radiance) at its texel centres."""
    origin, edge_u, edge_v = (np.asarray(a, np.float64) for a in (origin, edge_u, edge_v))
    w = max(2, int(round(np.linalg.norm(edge_u) / texel)))
    h = max(2, int(round(np.linalg.norm(edge_v) / texel)))
    u, v = np.meshgrid((np.arange(w) + 0.5) / w, (np.arange(h) + 0.5) / h)
    p = origin + u.reshape(-1, 1) * edge_u + v.reshape(-1, 1) * edge_v
    return Patch(name, origin, edge_u, edge_v, field(p).reshape(h, w, 3).astype(np.float32))


def _surface(name, origin, edge_u, edge_v, field, texel, hole=None, hole_field=None) -> list[Patch]:
    """A rectangle as patches; ``hole`` = (u0, u1, v0, v1) in [0, 1] becomes its own patch (a light)."""
    if hole is None:
        return [_patch(name, origin, edge_u, edge_v, field, texel)]
    origin, edge_u, edge_v = (np.asarray(a, np.float64) for a in (origin, edge_u, edge_v))
    u0, u1, v0, v1 = hole
    pieces = [("bottom", 0, 1, 0, v0), ("top", 0, 1, v1, 1), ("left", 0, u0, v0, v1), ("right", u1, 1, v0, v1)]
    out = [_patch(f"{name}_{tag}", origin + a * edge_u + c * edge_v, (b - a) * edge_u, (d - c) * edge_v, field, texel)
           for tag, a, b, c, d in pieces if b > a and d > c]
    out.append(_patch(f"{name}_light", origin + u0 * edge_u + v0 * edge_v, (u1 - u0) * edge_u, (v1 - v0) * edge_v,
                      hole_field, texel / 2))
    return out


def _box(size: np.ndarray, texel: float) -> list[Patch]:
    """Floor, ceiling (with a lamp) and four walls (a window in x = 0), all emitting inwards."""
    X, Y, Z = size
    rng = np.random.default_rng(7)
    lamp = (0.5, 0.65, 0.5, 0.68)  # ceiling lamp x 2.0..2.6, y 1.12..1.75 in the 4 x 3.5 room
    window = (0.35, 0.75, 0.35, 0.8)  # y 1.23..2.63, z 0.91..2.08 in the wall x = 0
    return (
        _surface("floor", (0, 0, 0), (X, 0, 0), (0, Y, 0), _pattern(rng, (0.30, 0.22, 0.15), planks=True), texel)
        + _surface("ceiling", (0, Y, Z), (X, 0, 0), (0, -Y, 0), _pattern(rng, (0.55, 0.55, 0.52), 0.05), texel,
                   lamp, _lamp(CEILING_LIGHT))
        + _surface("wall_x0", (0, 0, 0), (0, Y, 0), (0, 0, Z), _pattern(rng, (0.40, 0.42, 0.45)), texel,
                   window, _lamp((6.0, 7.0, 9.0), gradient=0.3))
        + _surface("wall_x1", (X, Y, 0), (0, -Y, 0), (0, 0, Z), _pattern(rng, (0.45, 0.40, 0.33)), texel)
        + _surface("wall_y0", (X, 0, 0), (-X, 0, 0), (0, 0, Z), _pattern(rng, (0.42, 0.45, 0.40)), texel)
        + _surface("wall_y1", (0, Y, 0), (X, 0, 0), (0, 0, Z), _pattern(rng, (0.48, 0.46, 0.40)), texel)
    )


def reference_room(name: str = "plain", *, texel: float = TEXEL) -> ReferenceRoom:
    """The named room (``"plain"`` or ``"red_wall"``), 4 x 3.5 x 2.6 m, sphere r = 0.15 m at (1.8, 1.9, 0.5).

    ``"red_wall"`` adds a 1 x 1 m panel of radiance ``RED * PANEL_GAIN`` in the plane x = 2.25 (30 cm
    from the sphere's surface), y in [1.4, 2.4], z in [0, 1], emitting towards -x (the sphere) only.
    Its back is black but opaque in Mitsuba (it shadows the wall x = 4 behind it) and absent from the
    cloud. ``texel`` is the texture resolution [m per texel].
    """
    if name not in ROOM_NAMES:
        raise PbgiError(f"unknown reference room {name!r}; expected one of {', '.join(ROOM_NAMES)}")
    if name.startswith("decals"):
        from probeless.pbgi.room_decals import decal_offset, decal_room

        return decal_room(decal_offset(name), texel=texel)
    size = np.array([4.0, 3.5, 2.6])
    centre, radius = np.array([1.8, 1.9, 0.5]), 0.15
    room = ReferenceRoom(name, size, tuple(_box(size, texel)), centre, radius)
    if name == "red_wall":
        x = centre[0] + radius + 0.30
        red = np.array(RED) * PANEL_GAIN
        panel = _patch("red_panel", (x, centre[1] + 0.5, 0.0), (0, -1.0, 0), (0, 0, 1.0), lambda p: red + 0 * p, texel)
        room = dataclasses.replace(room, panels=(panel,))
    return room


def uniform_room(room: ReferenceRoom, radiance) -> ReferenceRoom:
    """``room`` with every patch (panels included) emitting the constant ``radiance`` (3,) (furnace tests)."""
    rgb = np.asarray(radiance, np.float32)

    def flat(p: Patch) -> Patch:
        return dataclasses.replace(p, radiance=np.broadcast_to(rgb, p.radiance.shape).copy())
    return dataclasses.replace(room, patches=tuple(map(flat, room.patches)), panels=tuple(map(flat, room.panels)))


def sample_cloud(room: ReferenceRoom, spacing: float = 0.01, seed: int = 0, jitter: bool = False):
    """The room as a coloured point cloud: a grid of cell centres ``spacing`` [m] apart on every patch.

    Returns ``(points (N, 3) float64 [m, world], colors (N, 3) float32 linear radiance, normals (N, 3)
    float64 unit, emitting side = into the room)``. Colours are the patch texture at each point, looked
    up exactly as Mitsuba's emitter does (module doc); patches with ``in_cloud`` False (hidden behind a decal)
    are left out. ``jitter`` moves each point uniformly within its
    cell (seeded by ``seed``). At 1 cm the default rooms give about 0.68 M points.
    """
    if not spacing > 0:
        raise PbgiError(f"cloud spacing must be > 0, got {spacing}")
    rng = np.random.default_rng(seed)
    pts, cols, nrm = [], [], []
    for patch in (p for p in room.all_patches if p.in_cloud):
        nu = max(1, int(round(np.linalg.norm(patch.edge_u) / spacing)))
        nv = max(1, int(round(np.linalg.norm(patch.edge_v) / spacing)))
        u, v = np.meshgrid(np.arange(nu) + 0.5, np.arange(nv) + 0.5)
        uv = np.stack([u.ravel(), v.ravel()], axis=1)
        if jitter:
            uv += rng.uniform(-0.5, 0.5, uv.shape)
        uv /= (nu, nv)
        pts.append(patch.at(uv))
        cols.append(radiance_at(patch, uv))
        nrm.append(np.broadcast_to(patch.normal, (len(uv), 3)))
    return np.concatenate(pts), np.concatenate(cols), np.concatenate(nrm).copy()


VIEWS = {"front": (30.0, 10.0), "side": (90.0, 10.0), "wall": (-30.0, 10.0)}  # (azimuth from -y towards -x,
# elevation) [deg]


def object_camera(room: ReferenceRoom, size, view: str = "front", *, distance: float = 1.2, margin: float = 1.25):
    """``(K (3, 3), world_from_camera (4, 4))`` of an OpenCV pinhole framing the object sphere.

    ``size`` is the image side [px] or ``(width, height)``; the principal point is the image centre
    ((W - 1) / 2, (H - 1) / 2), pixel centres at integer coordinates. The sphere's silhouette spans
    ``1 / margin`` of the image's smaller side. ``"front"`` looks from 30 deg left of -y so that the
    red panel (``"red_wall"``) shows right of the sphere and lights its visible right side; ``"side"``
    looks along +x (the panel, if any, is behind the sphere); ``"wall"`` looks from 30 deg right of -y, past
    the panel's edge, at the side of the sphere the panel lights. ``distance`` [m] is from the centre.
    """
    if view not in VIEWS:
        raise PbgiError(f"unknown object view {view!r}; expected one of {', '.join(VIEWS)}")
    width, height = (size, size) if np.isscalar(size) else size
    az, el = np.radians(VIEWS[view])
    direction = np.array([-np.sin(az) * np.cos(el), -np.cos(az) * np.cos(el), np.sin(el)])
    position = room.object_centre + distance * direction
    half_angle = np.arcsin(room.object_radius / distance)
    f = min(width, height) / 2 / (np.tan(half_angle) * margin)
    K = np.array([[f, 0, (width - 1) / 2], [0, f, (height - 1) / 2], [0, 0, 1.0]])
    return K, look_at(position, room.object_centre)
