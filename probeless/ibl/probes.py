"""Probe objects for comparing lighting: a diffuse and a GGX sphere lit by a cubemap, seen from viewpoints.

:class:`ProbeRenderer` draws both spheres with the IBL renderer (:class:`probeless.ibl.render.IblRenderer`, no
contact shadow, exposure 1): ``diffuse`` (:class:`Diffuse`, albedo 1, 5-band SH irradiance of the cubemap) and
``ggx`` (:class:`Metal`, colour 1, a roughness; it reads the :func:`probeless.ibl.ggx.ggx_prefilter` level of
the cubemap; no Fresnel or shadowing-masking term), from given cameras.
"""

from __future__ import annotations

import numpy as np

from probeless.ibl.ggx import ggx_prefilter

OBJECTS = ("diffuse", "ggx")


def lighting(faces: np.ndarray, roughness: float):
    """The :class:`Lighting` of a cubemap: SH (5 bands) for the diffuse sphere, a GGX level for the GGX one."""
    from probeless.envmap.sh import project_cubemap
    from probeless.ibl.lighting import Lighting

    f = np.asarray(faces, np.float32)
    return Lighting(f, project_cubemap(f, 5), ((float(roughness), ggx_prefilter(f, roughness)),))


class ProbeRenderer:
    """The diffuse and the GGX sphere at ``centre`` (``radius``), each with its own :class:`IblRenderer`
    on the shared context ``ctx``, rendered from ``cameras`` [(K, world_from_camera)] at ``size`` px."""

    def __init__(self, ctx, centre, radius: float, roughness: float, cameras, size: int):
        from probeless.ibl.materials import Diffuse, Metal
        from probeless.ibl.mesh_io import place, uv_sphere
        from probeless.ibl.render import IblObject, IblRenderer

        mesh = place(*uv_sphere(), np.asarray(centre, np.float64), radius=float(radius))
        materials = {"diffuse": Diffuse(albedo=(1.0, 1.0, 1.0)),
                     "ggx": Metal(colour=(1.0, 1.0, 1.0), roughness=float(roughness))}
        self.renderers = {k: IblRenderer([IblObject(k, mesh, m, contact_shadow=False)], ctx=ctx)
                          for k, m in materials.items()}
        self.roughness, self.cameras, self.size = float(roughness), cameras, int(size)

    def render(self, faces: np.ndarray) -> dict[str, list[tuple[np.ndarray, np.ndarray]]]:
        """{object: [(colour (H, W, 3) float64, mask (H, W) bool) per viewpoint]} lit by cubemap ``faces``."""
        light = lighting(faces, self.roughness)
        out = {}
        for k, r in self.renderers.items():
            r.set_lighting(k, light)
            out[k] = []
            for K, pose in self.cameras:
                res = r.render(K, pose, self.size, self.size)
                out[k].append((res.color.astype(np.float64), res.mask.copy()))
        return out

    def release(self) -> None:
        for r in self.renderers.values():
            r.release()
