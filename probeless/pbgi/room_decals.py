"""Decal rooms: the ``red_wall`` room with three decals, coplanar with their surface or a few millimetres in front.

A scanned room is full of thin things on surfaces: posters, switch plates, rugs, lamp covers. In the cloud each is
a patch of points a millimetre or so in front of the surface it sits on. ``decals`` has three, each cut out of its
surface (no overlap, as the room's lamp): a pale poster on the red panel (30 cm from the sphere), a blue rug on the
floor under the sphere and the ceiling lamp. ``decals_0.5mm``, ``decals_1mm`` and ``decals_5mm`` move each decal
that far along its surface normal, into the room, and put the surface's own texture in the hole behind it with
``in_cloud = False``: Mitsuba renders it (it shows only through the thin gap at a decal's edge) but the cloud, like a
scan, has no points there. A step of a few millimetres changes the true lighting by far less than 1 %, so a
renderer should draw the three rooms alike (``probeless eval pbgi``, tests/pbgi/test_decals.py).

Holes are whole texels of the surface's texture (:data:`probeless.pbgi.room.TEXEL`); the pieces around a hole keep
the surface's texels, so both sides of the comparison see the same radiance.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from probeless.errors import PbgiError
from probeless.pbgi.room import TEXEL, Patch, ReferenceRoom, _patch, reference_room

OFFSETS = {"decals": 0.0, "decals_0.5mm": 0.0005, "decals_1mm": 0.001, "decals_5mm": 0.005}  # [m]
POSTER = (1.3, 1.2, 0.85)   # pale poster radiance on the red panel (times a stripe pattern)
RUG = (0.05, 0.12, 0.45)    # blue rug radiance on the floor


def decal_offset(name: str) -> float:
    """The decal offset [m] of a decal room's name."""
    if name not in OFFSETS:
        raise PbgiError(f"unknown decal room {name!r}; expected one of {', '.join(OFFSETS)}")
    return OFFSETS[name]


def _crop(patch: Patch, name: str, c0: int, c1: int, r0: int, r1: int, **kw) -> Patch:
    """The part of ``patch`` over texel columns c0..c1 and rows r0..r1 (ends excluded), its texels kept."""
    h, w = patch.radiance.shape[:2]
    eu, ev = patch.edge_u / w, patch.edge_v / h
    return Patch(name, patch.origin + c0 * eu + r0 * ev, (c1 - c0) * eu, (r1 - r0) * ev,
                 np.ascontiguousarray(patch.radiance[r0:r1, c0:c1]), **kw)


def _cut(patch: Patch, hole: tuple[int, int, int, int]) -> tuple[list[Patch], Patch]:
    """(pieces of ``patch`` around the texel rectangle ``hole`` = (c0, c1, r0, r1), the hole's own crop)."""
    h, w = patch.radiance.shape[:2]
    c0, c1, r0, r1 = hole
    parts = [("bottom", 0, w, 0, r0), ("top", 0, w, r1, h), ("left", 0, c0, r0, r1), ("right", c1, w, r0, r1)]
    pieces = [_crop(patch, f"{patch.name}_{tag}", a, b, c, d) for tag, a, b, c, d in parts if b > a and d > c]
    return pieces, _crop(patch, f"{patch.name}_behind", c0, c1, r0, r1)


def _decal(name: str, behind: Patch, field, offset: float, texel: float) -> list[Patch]:
    """The decal over ``behind`` moved ``offset`` along the normal, and (offset > 0) ``behind`` for Mitsuba only."""
    decal = _patch(name, behind.origin + offset * behind.normal, behind.edge_u, behind.edge_v, field, texel)
    return [decal] + ([dataclasses.replace(behind, in_cloud=False)] if offset > 0 else [])


def _stripes(base, period: float = 0.08):
    base = np.asarray(base, np.float64)
    return lambda p: base * (1 + 0.25 * np.sin(2 * np.pi * (p[:, 1:2] + p[:, 2:3]) / period))


def decal_room(offset: float = 0.0, *, texel: float = TEXEL) -> ReferenceRoom:
    """The ``red_wall`` room with a poster on its panel, a rug under the sphere and the ceiling lamp as decals
    ``offset`` [m] (0 to 1 cm) in front of their surfaces (module docstring)."""
    if not 0.0 <= offset <= 0.01:
        raise PbgiError(f"decal offset must be in [0, 0.01] m, got {offset}")
    base = reference_room("red_wall", texel=texel)
    patches, extra = [], []
    for p in base.patches:
        if p.name == "floor":  # the rug: x 1.30..2.14 m, y 1.50..2.30 m at 2 cm texels
            w, h = p.radiance.shape[1], p.radiance.shape[0]
            hole = (round(1.30 / 4.0 * w), round(2.14 / 4.0 * w), round(1.50 / 3.5 * h), round(2.30 / 3.5 * h))
            pieces, behind = _cut(p, hole)
            patches += pieces
            extra += _decal("rug", behind, lambda q: np.asarray(RUG) * (1 + 0 * q), offset, texel)
        elif p.name == "ceiling_light":  # the lamp (already cut out of the ceiling) becomes a cover below it
            patches.append(dataclasses.replace(p, origin=p.origin + offset * p.normal))
            if offset > 0:
                grey = np.mean([q.radiance.reshape(-1, 3).mean(0) for q in base.patches
                                if q.name.startswith("ceiling_") and q is not p], axis=0)
                extra.append(dataclasses.replace(p, name="ceiling_behind", in_cloud=False,
                                                 radiance=np.broadcast_to(grey, (2, 2, 3)).astype(np.float32)))
        else:
            patches.append(p)
    panel = base.panels[0]  # 1 x 1 m; the poster: 0.5 m wide, 0.5 m high, 0.4 m above the floor
    w, h = panel.radiance.shape[1], panel.radiance.shape[0]
    pieces, behind = _cut(panel, (round(0.2 * w), round(0.7 * w), round(0.4 * h), round(0.9 * h)))
    panels = pieces + _decal("poster", behind, _stripes(POSTER), offset, texel)
    name = next((k for k, v in OFFSETS.items() if v == offset), f"decals_{offset * 1000:g}mm")
    return dataclasses.replace(base, name=name, patches=tuple(patches + extra), panels=tuple(panels))
