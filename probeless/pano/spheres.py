"""Orthographic images of lit spheres in numpy: diffuse, glossy and mirror balls under an equirect map.

Independent of the GPU renderer; used to compare lighting maps (:mod:`probeless.pano.itmo_eval`).
A :class:`SphereView` is a unit sphere seen by an orthographic camera looking along ``forward``
(world ``z`` up, as in :mod:`probeless.pano.equirect`): per pixel the normal and the mirror
direction ``r = 2 (n . v) n - v`` with ``v = -forward`` the direction towards the viewer.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from probeless.errors import ProbelessError
from probeless.pano import glossy
from probeless.pano.mips import sample_equirect

OBJECTS = ("diffuse", "glossy", "mirror")


@dataclass(frozen=True)
class SphereView:
    """Pixels of a unit sphere filling an ``size`` x ``size`` orthographic image."""

    mask: np.ndarray  # (S, S) bool: pixel centre on the sphere
    normals: np.ndarray  # (N, 3) unit normals of the masked pixels (row-major order)
    reflect: np.ndarray  # (N, 3) unit mirror directions of the masked pixels

    def image(self, values: np.ndarray) -> np.ndarray:
        """(S, S, C) float32 image with ``values`` (N, C) on the sphere, 0 elsewhere."""
        out = np.zeros(self.mask.shape + (values.shape[-1],), np.float32)
        out[self.mask] = values
        return out


def sphere_view(size: int, forward: tuple[float, float, float] = (1.0, 0.0, 0.0)) -> SphereView:
    """The sphere seen along ``forward`` (not vertical); image up is world ``z``, odd sizes have a centre pixel."""
    f = np.asarray(forward, np.float64)
    f = f / np.linalg.norm(f)
    right = np.cross(f, [0.0, 0.0, 1.0])
    if int(size) < 1 or np.linalg.norm(right) < 1e-6:
        raise ProbelessError(f"sphere_view: need size >= 1 and a non-vertical forward, got {size}, {forward}")
    right /= np.linalg.norm(right)
    up = np.cross(right, f)
    c = (np.arange(size) + 0.5) / size * 2.0 - 1.0
    x, y = np.meshgrid(c, -c)
    mask = x * x + y * y < 1.0
    x, y = x[mask], y[mask]
    z = np.sqrt(1.0 - x * x - y * y)
    n = x[:, None] * right + y[:, None] * up - z[:, None] * f
    v = -f
    r = 2.0 * (n @ v)[:, None] * n - v
    return SphereView(mask, n, r / np.linalg.norm(r, axis=1, keepdims=True))


def shade(obj: str, normals: np.ndarray, reflect: np.ndarray, env: np.ndarray, diffuse: np.ndarray | None = None,
          levels=None, roughness: float = 0.1, albedo: float = 0.8, specular: float = 1.0) -> np.ndarray:
    """(N, 3) radiance of surface points with (N, 3) ``normals`` and mirror directions ``reflect``
    for material ``obj`` (one of :data:`OBJECTS`), lit by the equirect ``env``.

    diffuse: ``albedo`` x bilinear lookup of the ``diffuse`` map per normal; mirror: ``specular`` x
    :func:`glossy.mirror` (bilinear, level 0); glossy: ``specular`` x :func:`glossy.glossy_ring`
    with ``roughness``. ``levels``: the map's mip chain (``glossy.mip_levels(env)``, made if None).
    """
    if obj not in OBJECTS:
        raise ProbelessError(f"shade: unknown object {obj!r}; choices: {', '.join(OBJECTS)}")
    if obj == "diffuse":
        if diffuse is None:
            raise ProbelessError("shade: the diffuse sphere needs a diffuse map")
        return np.float32(albedo) * sample_equirect([diffuse], normals)
    lv = glossy.mip_levels(env) if levels is None else levels
    if obj == "mirror":
        return np.float32(specular) * glossy.mirror(lv, reflect)
    return np.float32(specular) * glossy.glossy_ring(lv, reflect, roughness)
