"""The probe spheres of ``probeless eval hdr-expand --renderer pbgi``: lit by point-based GI (paper 001, §5).

:class:`PbgiProbes` draws the two spheres of :class:`probeless.ibl.probes.ProbeRenderer` (same mesh, centre,
radius, viewpoints and size) with :class:`probeless.pbgi.render.PbgiRenderer` instead of a cubemap: ``diffuse``
(``Brdf("lambert")``, albedo 1) and ``ggx`` (``Brdf("ggx")``, f0 1, so Fresnel 1; alpha = roughness²), lit by the
bounding-sphere hierarchy of the cloud's points with the radiance given to :meth:`PbgiProbes.render`. The sphere is
the receiver inside the cloud, so nearby surfaces subtend what they really do from each of its points (the cubemap
path sees the room from the centre only). No far field: directions no point covers read black, as the cubemap's
holes do. The normals, which the synthetic clouds lack, are estimated once
(:func:`probeless.pbgi.cloud.estimate_normals`) and turned towards the sphere's centre (the surfaces the object
sees face it); every radiance then gets its own hierarchy over the same points and normals.

The hierarchy is built with colour threshold ``tc`` = :data:`BSH_TC` = 0 by default, not the paper's 0.01: then no
sub-tree is pruned for its uniform colour, the tree depends on the points and normals only, and the rendering is
linear in the radiance, so two clouds' renderings differ by their lighting alone. With 0.01 the pruning follows the
colours (a brighter cloud varies more, so fewer nodes are pruned): on light_switch (the tests' small cloud) 1.1 x the
true radiance then moves the GGX sphere by RMS 0.094 instead of the linear 0.055, 0.6 of what the LDR cloud does
(0.158; hybrid, 24² micro-buffers), so the change of the tree would blur the expansion's.
"""

from __future__ import annotations

import numpy as np

from probeless.ibl.probes import OBJECTS

# probeless.pbgi.microbuffer.VARIANTS without "envmap" (no gathering), spelled out: importing it at CLI start costs 1 s
VARIANTS = ("classic", "mipmapped", "hybrid")
MICRO_SIZES = (16, 24, 32)  # micro-buffer sides of the paper, as `probeless pbgi render --micro`
BSH_TC = 0.0  # colour threshold of the hierarchy's pruning (module docstring; the paper's is 0.01)


class PbgiProbes:
    """The diffuse and the GGX sphere at ``centre`` (``radius``) lit by PBGI from the cloud ``points`` (N, 3) [m],
    one :class:`PbgiRenderer` each on the shared context ``ctx``, rendered from ``cameras`` [(K, world_from_camera)]
    at ``size`` px (``variant``, ``micro``: the renderer's settings; ``tc``: :func:`build_bsh`'s)."""

    def __init__(self, ctx, points, centre, radius: float, roughness: float, cameras, size: int, *,
                 variant: str = "hybrid", micro: int = 24, tc: float = BSH_TC):
        from probeless.ibl.mesh_io import place, uv_sphere
        from probeless.pbgi.cloud import estimate_normals
        from probeless.pbgi.materials import Brdf
        from probeless.pbgi.render import PbgiObject, PbgiRenderer

        centre = np.asarray(centre, np.float64)
        mesh = place(*uv_sphere(), centre, radius=float(radius))
        brdfs = {"diffuse": Brdf("lambert", (1.0, 1.0, 1.0)), "ggx": Brdf("ggx", (1.0, 1.0, 1.0), float(roughness))}
        self.points = np.asarray(points, np.float64)
        self.normals = estimate_normals(self.points, centre)
        self.renderers = {k: PbgiRenderer([PbgiObject(k, mesh, brdfs[k])], variant=variant, micro=micro, ctx=ctx)
                          for k in OBJECTS}
        self.cameras, self.size = cameras, int(size)
        self.settings = {"variant": variant, "micro": int(micro), "tc": float(tc)}

    def render(self, radiance: np.ndarray) -> dict[str, list[tuple[np.ndarray, np.ndarray]]]:
        """{object: [(colour (H, W, 3) float64, mask (H, W) bool) per viewpoint]} lit by the points with
        ``radiance`` (N, 3) linear [cloud units]."""
        from probeless.pbgi.bsh import build_bsh

        bsh = build_bsh(self.points, radiance, self.normals, tc=self.settings["tc"])
        out = {}
        for k, r in self.renderers.items():
            r.set_cloud(bsh)
            out[k] = []
            for K, pose in self.cameras:
                res = r.render(K, pose, self.size, self.size)
                out[k].append((res.color.astype(np.float64), res.mask.copy()))
        return out

    def scene_info(self) -> dict:
        """Nothing per scene (the settings are the run's); the cubemap path reports its holes here."""
        return {}

    def release(self) -> None:
        """Free the renderers' GL resources (not the shared context)."""
        for r in self.renderers.values():
            r.release()
        self.renderers = {}
