"""The GGX-prefiltered radiance chain of a cubemap, on the GPU (split-sum radiance, Karis 2013).

Level k >= 1 of the chain (face size S >> k) holds the map prefiltered for perceptual roughness
``r_k = 2^(-(levels - 1 - k) / 2)`` (GGX alpha = r² doubles from level to level: 1/32, 1/16, ..., 1 for seven
levels; level 0 is the map itself), so a lookup at ``lod = levels - 1 + 2 log2(roughness)`` with trilinear filtering
blends the two levels that bracket the roughness. Rougher lobes than ``r_1`` read the chain; smoother ones are
importance-sampled from the map itself (``ibl_specular.glsl``), where blending with a mirror would be wrong. Each
level is computed by ``ggx_prefilter.comp.glsl`` from the map's box mip chain by filtered importance sampling
(``SAMPLES`` per texel).

The split sum (this chain x the DFG term, the renderer's ``split_sum`` lobe) is 10-26 % RMS off a path tracer at
roughness 0.2-0.8 on real panoramas (``probeless eval ibl --lobe split_sum``): its lobe is the n = v = r one. The
renderer's default ``hybrid`` lobe instead takes the map's brightest texels out (:func:`extract_lights`), sums them
with the exact BRDF, and importance-samples the bounded-contrast residual.
"""

from __future__ import annotations

from pathlib import Path

import moderngl
import numpy as np

from probeless.errors import ProbelessError
from probeless.gl.programs import load_program
from probeless.gl.textures import FILTERS, GL_RGBA32F, upload_cube

SHADERS = Path(__file__).with_name("shaders")
MAX_LEVELS = 7            # levels incl. the base (256 -> 4 texels a face at the roughest) [count]
SAMPLES = (0, 128, 256, 512, 512, 512, 512)  # GGX samples per texel of each level [count]


def chain_levels(size: int) -> int:
    """Levels of the chain of an S = ``size`` cubemap: MAX_LEVELS, fewer when S is too small to halve that often."""
    return max(2, min(MAX_LEVELS, int(np.log2(max(int(size), 1))) + 1))


def level_roughness(levels: int) -> np.ndarray:
    """(levels,) perceptual roughness each level is prefiltered for (level 0: 0, the map)."""
    k = np.arange(levels, dtype=np.float64)
    return np.where(k == 0, 0.0, 2.0 ** (-(levels - 1 - k) / 2))


class GgxPrefilter:
    """Builds the chain of cubemap faces on a GL context (the program is compiled once)."""

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        self.prog = load_program(ctx, "ggx_prefilter", shader_dir=SHADERS)

    def chain(self, faces: np.ndarray) -> tuple[moderngl.TextureCube, int]:
        """(RGBA32F cube texture with the chain in its mip levels, trilinear; number of levels) of faces
        (6, S, S, 3) linear radiance."""
        f = np.asarray(faces, np.float32)
        if f.ndim != 4 or f.shape[0] != 6 or f.shape[1] != f.shape[2] or f.shape[3] < 3:
            raise ProbelessError(f"GGX prefilter: expected (6, S, S, 3) faces, got {f.shape}")
        size, levels = f.shape[1], chain_levels(f.shape[1])
        source = upload_cube(self.ctx, f[..., :3])  # box mips: what the samples read
        rgba = np.concatenate([f[..., :3], np.ones(f.shape[:3] + (1,), np.float32)], axis=-1)
        chain = self.ctx.texture_cube((size, size), 4, rgba.tobytes(), dtype="f4")
        chain.build_mipmaps(0, levels - 1)  # allocates the levels (overwritten below)
        source.use(0)
        p = self.prog
        p["source"], p["source_size"] = 0, float(size)
        for k, rough in enumerate(level_roughness(levels)[1:], start=1):
            s = max(1, size >> k)
            chain.bind_to_image(0, read=False, write=True, level=k, format=GL_RGBA32F)
            p["size"], p["roughness"], p["samples"] = s, float(rough), SAMPLES[min(k, len(SAMPLES) - 1)]
            p.run((s + 7) // 8, (s + 7) // 8, 6)
            self.ctx.memory_barrier()
        source.release()
        chain.filter = FILTERS["trilinear"]
        return chain, levels


LIGHT_FACE = 32    # face size at which bright texels become lights [texels]
LIGHTS = 128       # lights taken out of a map at most (ibl_specular.glsl's IBL_MAX_LIGHTS) [count]


def extract_lights(faces: np.ndarray, count: int = LIGHTS, face: int = LIGHT_FACE
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(residual faces (6, S, S, 3), light directions (n, 3), light powers (n, 3) [radiance x sr]) of a map.

    The map at ``face`` texels a side is cut at the luminance of its ``count + 1``-th brightest texel: what every
    brighter texel holds above that level leaves the map and becomes one light (its solid-angle-weighted centroid
    direction, its integrated radiance), so the map minus the lights is the residual exactly. The renderer sums the
    lights with the exact BRDF and reads the residual, whose contrast is now bounded, through the prefiltered chain.
    """
    from probeless.color import REC709_Y
    from probeless.geom.cube import cube_directions, cube_solid_angles

    f = np.asarray(faces, np.float32)[..., :3]
    size = f.shape[1]
    k = size // face if size >= face and size % face == 0 else 0
    if count <= 0 or k == 0:
        return f, np.zeros((0, 3), np.float32), np.zeros((0, 3), np.float32)
    dw = cube_solid_angles(size).astype(np.float32)
    small = (f * dw[..., None]).reshape(6, face, k, face, k, 3).sum(axis=(2, 4))
    small /= dw.reshape(6, face, k, face, k).sum(axis=(2, 4))[..., None]
    y = small @ REC709_Y
    flat = np.sort(y.ravel())
    if len(flat) <= count:
        return f, np.zeros((0, 3), np.float32), np.zeros((0, 3), np.float32)
    level = float(flat[-count - 1])
    keep = np.where(y > level, level / np.maximum(y, 1e-30), 1.0).astype(np.float32)  # residual / map per texel
    keep_full = np.repeat(np.repeat(keep, k, axis=1), k, axis=2)[..., None]
    residual = f * keep_full
    excess = (f - residual) * dw[..., None]  # radiance x sr per texel
    weight = excess @ REC709_Y
    lit = np.argwhere(y > level)
    dirs = cube_directions(size)
    dirs = dirs / np.linalg.norm(dirs, axis=-1, keepdims=True)
    out_d, out_p = [], []
    for fc, r, c in lit:
        sl = (fc, slice(r * k, (r + 1) * k), slice(c * k, (c + 1) * k))
        w = weight[sl]
        centroid = (dirs[sl] * w[..., None]).sum(axis=(0, 1))
        out_d.append(centroid / max(np.linalg.norm(centroid), 1e-30))
        out_p.append(excess[sl].sum(axis=(0, 1)))
    return residual, np.asarray(out_d, np.float32), np.asarray(out_p, np.float32)
