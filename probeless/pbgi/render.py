"""Point-based global illumination of virtual objects (paper 001 §5): G-buffer, micro-buffers, shading.

:class:`PbgiRenderer` draws placed meshes with :class:`~probeless.pbgi.materials.Brdf` materials, lit by a coloured
point cloud's bounding-sphere hierarchy (:func:`~probeless.pbgi.bsh.build_bsh`; colours are linear radiance) and,
optionally, a far-field cubemap for the directions the gathered points leave empty::

    r = PbgiRenderer([PbgiObject("ball", mesh, Brdf("ggx", (1, 1, 1), 0.3, 0.0))], variant="hybrid", micro=24)
    r.set_cloud(build_bsh(points, radiance, normals))
    out = r.render(K, world_from_camera, 256, 256)   # PbgiResult: linear colour, mask, depth, stats

``supersample`` (default 2) rasterises and shades each micro-buffer at ``micro * supersample`` texels a side while the
cut stays the one Eq. 5 gives for ``micro``; ``supersample=1`` is the paper's micro-buffer.
``near=(centre, radius)`` at render gathers only the points within ``radius`` of ``centre`` and takes the rest from
the far field (the ``near_field`` mode of the ``pbgi_renderer`` node).
"""

from __future__ import annotations

from dataclasses import dataclass

import moderngl
import numpy as np

from probeless.errors import PbgiError
from probeless.gl.context import GL_TEXTURE_CUBE_MAP_SEAMLESS, create_context, current_context
from probeless.gl.textures import upload_cube
from probeless.pbgi.gbuffer import GBuffer, GBufferRenderer, pixel_pyramid
from probeless.pbgi.microbuffer import MAT_DTYPE, VARIANTS, MicroBufferRenderer, MicroStats

# Texels per micro-buffer texel side: the cut is chosen for `micro` (Eq. 5 at 4 omega) but splatted and shaded at
# micro * SUPERSAMPLE texels, which removes the banding that point-sampled coverage of small bright nodes (a lamp)
# leaves at 24^2 (Mitsuba error of a Lambert sphere 9.6 % -> 2.0 %, `probeless eval pbgi`; docs/pbgi).
SUPERSAMPLE = 2


@dataclass(frozen=True)
class PbgiObject:
    """A virtual object: an id, a placed mesh (probeless.ibl.mesh_io.PlacedMesh) and its BRDF."""

    id: str
    mesh: object
    brdf: object


@dataclass(frozen=True)
class PbgiResult:
    """One rendered view; pixels (row, col) of the camera image."""

    color: np.ndarray   # (H, W, 3) float32 linear radiance x exposure [the cloud's units]
    mask: np.ndarray    # (H, W) bool, an object covers the pixel
    depth: np.ndarray   # (H, W) float32 camera z [m]; inf where mask is False
    gbuffer: GBuffer
    stats: MicroStats | None  # None when no object is in view


class PbgiRenderer:
    """Renders a fixed set of :class:`PbgiObject` lit by a point cloud (see the module docstring)."""

    def __init__(self, objects: list[PbgiObject], *, variant: str = "hybrid", micro: int = 24,
                 hybrid_factor: float = 32.0, is_roughness: float = 0.2, is_samples: int = 64,
                 budget: int = 64 << 20, supersample: int = SUPERSAMPLE, exposure: float = 1.0, near: float = 0.02,
                 far: float = 100.0,
                 ctx: moderngl.Context | None = None):
        if variant not in VARIANTS:
            raise PbgiError(f"unknown PBGI variant {variant!r} (known: {', '.join(VARIANTS)})")
        self.own_ctx = ctx is None
        self.ctx = ctx or create_context()
        self.ctx.__enter__()
        self.ctx.enable_direct(GL_TEXTURE_CUBE_MAP_SEAMLESS)
        self.variant, self.exposure, self.near, self.far = variant, float(exposure), float(near), float(far)
        self.objects = list(objects)
        self.gbuf = GBufferRenderer(self.ctx)
        self.gbuf.set_objects([(o.mesh, o.brdf) for o in self.objects])
        self.micro = MicroBufferRenderer(self.ctx, micro=micro, hybrid_factor=hybrid_factor,
                                         is_roughness=is_roughness, is_samples=is_samples, budget=budget,
                                         supersample=supersample)
        self.far_field = None
        self.has_cloud = False

    @current_context
    def set_objects(self, objects: list[PbgiObject]) -> None:
        """Draw ``objects`` from now on instead of the current ones."""
        self.objects = list(objects)
        self.gbuf.set_objects([(o.mesh, o.brdf) for o in self.objects])

    @current_context
    def set_cloud(self, bsh) -> None:
        """Light by the hierarchy ``bsh`` (a :class:`~probeless.pbgi.bsh.Bsh` or its ``nodes`` records)."""
        self.micro.set_nodes(getattr(bsh, "nodes", bsh))
        self.has_cloud = True

    @current_context
    def set_far_field(self, faces: np.ndarray | None) -> None:
        """The cubemap (6, S, S, 3) of linear radiance empty micro-texels read (None: they read black)."""
        if self.far_field is not None:
            self.far_field.release()
            self.far_field = None
        if faces is not None:
            f = np.asarray(faces, np.float32)
            if f.ndim != 4 or f.shape[0] != 6 or f.shape[1] != f.shape[2] or f.shape[3] not in (3, 4):
                raise PbgiError(f"far field: expected cubemap faces (6, S, S, 3), got {f.shape}")
            self.far_field = upload_cube(self.ctx, f, filter="linear")

    @current_context
    def render(self, K: np.ndarray, world_from_camera: np.ndarray, width: int, height: int, *,
               variant: str | None = None, near: tuple | None = None) -> PbgiResult:
        """Draw every object seen from ``world_from_camera`` (OpenCV axes) through pinhole ``K``."""
        variant = variant or self.variant
        if variant != "envmap" and not self.has_cloud:
            raise PbgiError("render: no point cloud yet (set_cloud)")
        g = self.gbuf.render(K, world_from_camera, width, height, self.near, self.far)
        color = np.zeros((height, width, 3), np.float32)
        if not g.mask.any():
            return PbgiResult(color, g.mask, g.depth, g, None)
        pyr = pixel_pyramid(g.mask, g.position, g.normal, self.micro.tile_levels)
        r, c = pyr.rows, pyr.cols
        mats = np.zeros(pyr.n_pixels, MAT_DTYPE)
        mats["base"], mats["roughness"] = g.base_color[r, c], g.roughness[r, c]
        mats["metalness"], mats["model"] = g.metalness[r, c], g.model[r, c]
        rad, stats = self.micro.render(pyr, mats, world_from_camera[:3, 3], variant, far_field=self.far_field,
                                       near=near)
        color[r, c] = rad * self.exposure
        return PbgiResult(color, g.mask, g.depth, g, stats)

    @current_context
    def release(self) -> None:
        """Free every GL resource (the context too when this renderer created it)."""
        self.gbuf.release()
        self.micro.release()
        self.set_far_field(None)
        if self.own_ctx:
            self.ctx.release()
