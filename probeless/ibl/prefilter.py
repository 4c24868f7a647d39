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
LIGHT_SPLIT = 4    # each light is also split into LIGHT_SPLIT^2 parts, for lobes narrower than a light [count]


def extract_lights(faces: np.ndarray, count: int = LIGHTS, face: int = LIGHT_FACE
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(residual faces (6, S, S, 3), light directions (n, 3), light powers (n, 3) [radiance x sr]) of a map.

    The map at ``face`` texels a side is cut at the luminance of its ``count + 1``-th brightest texel: what every
    brighter texel holds above that level leaves the map and becomes one light (its solid-angle-weighted centroid
    direction, its integrated radiance), so the map minus the lights is the residual exactly. The renderer sums the
    lights with the exact BRDF and reads the residual, whose contrast is now bounded, through the prefiltered chain.
    """
    residual, dirs, powers, _, _ = extract_light_parts(faces, count, face, 1)
    return residual, dirs, powers


def extract_light_parts(faces: np.ndarray, count: int = LIGHTS, face: int = LIGHT_FACE, split: int = LIGHT_SPLIT
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`extract_lights` plus each light cut into ``split`` x ``split`` parts: (residual, directions (n, 3),
    powers (n, 3), part directions (n, split², 3), part powers (n, split², 3)); a light's parts add up to it.

    A light is a texel of ``face`` (2.8 degrees at 32 px): as a point it is right for lobes much wider than that, but a
    roughness-0.2 lobe is as narrow as the texel, and the window or lamp inside it is smaller still. Its parts (each
    the solid-angle-weighted centroid and integrated excess of a sub-block of the map's texels) are what such a lobe
    sums. ``split`` must divide the map's texels per light texel.
    """
    from probeless.color import REC709_Y
    from probeless.geom.cube import cube_directions, cube_solid_angles

    f = np.asarray(faces, np.float32)[..., :3]
    size = f.shape[1]
    k = size // face if size >= face and size % face == 0 else 0
    empty = np.zeros((0, 3), np.float32)
    if count <= 0 or k == 0:
        return f, empty, empty, np.zeros((0, split * split, 3), np.float32), np.zeros((0, split * split, 3), np.float32)
    split = split if k % split == 0 else 1
    dw = cube_solid_angles(size).astype(np.float32)
    small = (f * dw[..., None]).reshape(6, face, k, face, k, 3).sum(axis=(2, 4))
    small /= dw.reshape(6, face, k, face, k).sum(axis=(2, 4))[..., None]
    y = small @ REC709_Y
    flat = np.sort(y.ravel())
    if len(flat) <= count:
        return f, empty, empty, np.zeros((0, split * split, 3), np.float32), np.zeros((0, split * split, 3), np.float32)
    level = float(flat[-count - 1])
    keep = np.where(y > level, level / np.maximum(y, 1e-30), 1.0).astype(np.float32)  # residual / map per texel
    keep_full = np.repeat(np.repeat(keep, k, axis=1), k, axis=2)[..., None]
    residual = f * keep_full
    excess = (f - residual) * dw[..., None]  # radiance x sr per texel
    weight = excess @ REC709_Y
    lit = np.argwhere(y > level)
    dirs = cube_directions(size)
    dirs = dirs / np.linalg.norm(dirs, axis=-1, keepdims=True)
    q = k // split

    def centroid(d, w, p):
        c = (d * w[..., None]).reshape(-1, 3).sum(axis=0)
        if np.linalg.norm(c) < 1e-30:
            c = d.reshape(-1, 3).sum(axis=0)
        return c / np.linalg.norm(c), p.reshape(-1, 3).sum(axis=0)

    out_d, out_p, part_d, part_p = [], [], [], []
    for fc, r, c in lit:
        sl = (fc, slice(r * k, (r + 1) * k), slice(c * k, (c + 1) * k))
        d, p = centroid(dirs[sl], weight[sl], excess[sl])
        out_d.append(d)
        out_p.append(p)
        cells = [(slice(i * q, (i + 1) * q), slice(j * q, (j + 1) * q)) for i in range(split) for j in range(split)]
        parts = [centroid(dirs[sl][c], weight[sl][c], excess[sl][c]) for c in cells]
        part_d.append([x[0] for x in parts])
        part_p.append([x[1] for x in parts])
    return (residual, np.asarray(out_d, np.float32), np.asarray(out_p, np.float32), np.asarray(part_d, np.float32),
            np.asarray(part_p, np.float32))
