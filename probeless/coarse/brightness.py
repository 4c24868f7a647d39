"""Global brightness change Δ between the coarse model and a new fisheye frame (paper §4.6).

``Δ = Σ_t v(t) (F(f(t)) - T(t)) / Σ_t v(t)``: T the atlas (camera LDR units 0..1), F the fisheye
frame, f the texel -> pixel projection (:mod:`probeless.coarse.project`). v(t) = 1 for texels that
were directly observed before, are visible in this frame (in view, not occluded by the room:
:mod:`probeless.coarse.occlusion`) and whose old and new values are neither saturated (any channel
>= ``saturated``) nor black (all channels <= ``dark``).

:func:`estimate_delta` is fully vectorised over a fixed random sample of core texels
(:func:`draw_sample`, or all of them); :func:`estimate_delta_serial` is the paper's straightforward
per-texel loop, same result, kept as the benchmark reference.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from probeless.cameras.omnidir import OmnidirModel
from probeless.coarse.occlusion import inside, polygon_contains
from probeless.coarse.project import project_columns, sample_columns
from probeless.coarse.texels import TexelMap
from probeless.coarse.visibility import is_convex, visibility_polygon
from probeless.errors import SchemaError
from probeless.geom.rotation import invert_transform

DARK = 0.01           # a value is black when all channels are <= this [0..1]
SATURATED = 0.98      # a value is saturated when any channel is >= this [0..1]
OFFSET_M = 0.01       # wall texels are tested this far inside the room for occlusion [m]
DEADBAND = 0.5 / 255  # Δ smaller than this (every channel) counts as no change [0..1]


def apply_deadband(delta: np.ndarray, threshold: float = DEADBAND) -> np.ndarray:
    """Δ, or zeros when every channel is below ``threshold`` in magnitude.

    In a static room the per-frame estimate is not exactly 0 (resampling at other fisheye
    resolutions and angles: about ±0.1 codes a frame on the shipped scenes), and Δ is added to every
    out-of-view texel each frame, so that noise would accumulate into a drift of several codes.
    """
    d = np.asarray(delta, np.float32)
    return np.zeros(3, np.float32) if np.all(np.abs(d) < threshold) else d


@dataclass(frozen=True)
class BrightnessSample:
    """A fixed subset of an atlas's core texels and their geometry, drawn once per layout."""

    index: np.ndarray     # (K,) int64 flat atlas indices (row * W + col), increasing
    position: np.ndarray  # (K, 3) float32 texel centres [m, world]
    normal: np.ndarray    # (K, 3) float32 inward unit normals [world]
    shape: tuple[int, int]  # (H, W) of the atlas it indexes


def draw_sample(texmap: TexelMap, samples: int = 0, seed: int = 0) -> BrightnessSample:
    """``samples`` core texels drawn without replacement with ``seed`` (0 or more than there are = all)."""
    core = np.flatnonzero(texmap.core.ravel())
    if 0 < samples < len(core):
        core = np.sort(np.random.default_rng(seed).choice(core, samples, replace=False))
    pos = texmap.position.reshape(-1, 3)[core]
    nrm = texmap.normal.reshape(-1, 3)[core]
    return BrightnessSample(core.astype(np.int64), pos, nrm, texmap.core.shape)


def _sample(sample_idx, texmap: TexelMap) -> BrightnessSample:
    if sample_idx is None:
        return draw_sample(texmap)
    if isinstance(sample_idx, BrightnessSample):
        if sample_idx.shape != texmap.core.shape:
            raise SchemaError(f"brightness sample drawn for a {sample_idx.shape} atlas, "
                              f"texel map is {texmap.core.shape}")
        return sample_idx
    idx = np.asarray(sample_idx, np.int64)
    return BrightnessSample(idx, texmap.position.reshape(-1, 3)[idx], texmap.normal.reshape(-1, 3)[idx],
                            texmap.core.shape)


def _check_shapes(atlas_rgb: np.ndarray, observed: np.ndarray, texmap: TexelMap) -> None:
    shape = texmap.core.shape
    if atlas_rgb.shape != shape + (3,) or observed.shape != shape:
        raise SchemaError(f"atlas {atlas_rgb.shape} / observed {observed.shape} do not match the texel map's "
                          f"layout {shape}: atlas_size / texels_per_m differ from the texturer's")


def _unit(values: np.ndarray) -> np.ndarray:
    """float32 0..1 of uint8 codes or float values."""
    return values.astype(np.float32) / 255.0 if values.dtype == np.uint8 else values.astype(np.float32)


def _gather(a: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """``a[idx]`` along axis 0. np.take is the fastest gather but first copies a non-contiguous ``a`` (a view
    of an RGBA atlas) whole: worth it only when ``idx`` covers much of ``a``."""
    return np.take(a, idx, axis=0) if a.flags.c_contiguous or 16 * len(idx) > len(a) else a[idx]


def usable(rgb: np.ndarray, dark: float, saturated: float) -> np.ndarray:
    """(N,) bool: neither saturated (any channel >= saturated) nor black (all <= dark); NaN is unusable."""
    top = np.maximum(np.maximum(rgb[:, 0], rgb[:, 1]), rgb[:, 2])
    return (top < saturated) & (top > dark)


def estimate_delta(atlas_rgb: np.ndarray, observed: np.ndarray, texmap: TexelMap, image: np.ndarray, model,
                   world_from_fisheye: np.ndarray, fov_deg: float, floorplan: np.ndarray, *,
                   sample_idx: BrightnessSample | np.ndarray | None = None, dark: float = DARK,
                   saturated: float = SATURATED, offset_m: float = OFFSET_M) -> tuple[np.ndarray, int]:
    """(Δ (3,) float32 in 0..1 units, texels used) of a fisheye ``image`` against the atlas (module doc).

    ``atlas_rgb`` (H, W, 3) float32 0..1 or uint8 (a view of an RGBA atlas is fine), ``observed``
    (H, W) bool or uint8, nonzero = observed directly (e.g. the RGBA atlas's alpha); ``sample_idx``
    restricts the mean to a :class:`BrightnessSample` or flat texel indices (None: all core texels).
    Δ is 0 and texels used 0 when no texel qualifies.
    GeometryError when the camera is outside a non-convex floorplan.
    """
    _check_shapes(atlas_rgb, observed, texmap)
    s = _sample(sample_idx, texmap)
    old = _unit(_gather(atlas_rgb.reshape(-1, 3), s.index))
    u, v, ok = project_columns(s.position, model, world_from_fisheye, fov_deg)
    ok &= _gather(observed.reshape(-1), s.index).astype(bool) & usable(old, dark, saturated)
    j = np.flatnonzero(ok)
    if not is_convex(floorplan):
        poly = visibility_polygon(floorplan, np.asarray(world_from_fisheye, np.float64)[:2, 3])
        j = j[inside(poly, np.take(s.position, j, axis=0), np.take(s.normal, j, axis=0), offset_m)]
    new, old = sample_columns(image, u[j], v[j]), np.take(old, j, axis=0)
    j = np.flatnonzero(usable(new, dark, saturated))
    n = len(j)
    if n == 0:
        return np.zeros(3, np.float32), 0
    diff = np.take(new, j, axis=0) - np.take(old, j, axis=0)
    return np.array([diff[:, c].sum(dtype=np.float64) / n for c in range(3)], np.float32), n


def _bilinear(flat: np.ndarray, w: int, h: int, u: float, v: float) -> tuple[float, float, float]:
    """One bilinear sample of a flat (h * w, 3) uint8 image, edges replicated, in 0..1 (plain Python)."""
    u0, v0 = math.floor(u), math.floor(v)
    fu, fv = u - u0, v - v0
    c0, c1 = min(max(u0, 0), w - 1), min(max(u0 + 1, 0), w - 1)
    r0, r1 = min(max(v0, 0), h - 1) * w, min(max(v0 + 1, 0), h - 1) * w
    a, b, c, d = flat[r0 + c0].tolist(), flat[r0 + c1].tolist(), flat[r1 + c0].tolist(), flat[r1 + c1].tolist()
    return tuple(((a[k] * (1 - fu) + b[k] * fu) * (1 - fv) + (c[k] * (1 - fu) + d[k] * fu) * fv) / 255.0
                 for k in range(3))


def _ok(rgb, dark: float, saturated: float) -> bool:
    return max(rgb) < saturated and max(rgb) > dark


def estimate_delta_serial(atlas_rgb: np.ndarray, observed: np.ndarray, texmap: TexelMap, image: np.ndarray, model,
                          world_from_fisheye: np.ndarray, fov_deg: float, floorplan: np.ndarray, *,
                          sample_idx: BrightnessSample | np.ndarray | None = None, dark: float = DARK,
                          saturated: float = SATURATED, offset_m: float = OFFSET_M,
                          limit: int | None = None) -> tuple[np.ndarray, int]:
    """:func:`estimate_delta` as a plain per-texel Python loop (the paper's serial version).

    Per texel: observed? old value usable? transform, field of view, unified-sphere projection,
    image bounds, point-in-visibility-polygon, bilinear sample, new value usable? accumulate.
    ``limit`` runs only the first ``limit`` texels of the sample (for timing).
    """
    _check_shapes(atlas_rgb, observed, texmap)
    s = _sample(sample_idx, texmap)
    T = invert_transform(np.asarray(world_from_fisheye, np.float64)).tolist()
    cos_half = math.cos(math.radians(fov_deg) / 2)
    poly = None if is_convex(floorplan) else visibility_polygon(
        np.asarray(floorplan, np.float64), np.asarray(world_from_fisheye, np.float64)[:2, 3]).tolist()
    ideal = isinstance(model, OmnidirModel) and len(model.D) == 0
    if ideal:
        (fx, skew, cx), (_, fy, cy), xi = model.K[0].tolist(), model.K[1].tolist(), model.xi
    w, h = image.shape[1], image.shape[0]
    flat_img, flat_atlas, flat_obs = image.reshape(-1, 3), atlas_rgb.reshape(-1, 3), observed.reshape(-1)
    scale = 1 / 255.0 if atlas_rgb.dtype == np.uint8 else 1.0
    total, n = [0.0, 0.0, 0.0], 0
    count = len(s.index) if limit is None else min(limit, len(s.index))
    for k in range(count):
        i = int(s.index[k])
        if not flat_obs[i]:
            continue
        old = [c * scale for c in flat_atlas[i].tolist()]
        if not _ok(old, dark, saturated):
            continue
        px, py, pz = s.position[k].tolist()
        x = T[0][0] * px + T[0][1] * py + T[0][2] * pz + T[0][3]
        y = T[1][0] * px + T[1][1] * py + T[1][2] * pz + T[1][3]
        z = T[2][0] * px + T[2][1] * py + T[2][2] * pz + T[2][3]
        r = math.sqrt(x * x + y * y + z * z)
        if r == 0 or z / r < cos_half:
            continue
        if ideal:
            zs = z / r
            if zs + xi <= 0 or 1 + xi * zs <= 0:
                continue
            mx, my = x / r / (zs + xi), y / r / (zs + xi)
            u, v = fx * mx + skew * my + cx, fy * my + cy
        else:
            uv, valid = model.project(np.array([[x, y, z]]))
            if not valid[0]:
                continue
            u, v = uv[0].tolist()
        if not (-0.5 <= u <= w - 0.5 and -0.5 <= v <= h - 0.5):
            continue
        if poly is not None:
            nx, ny, _ = s.normal[k].tolist()
            if not polygon_contains(poly, px + offset_m * nx, py + offset_m * ny):
                continue
        new = _bilinear(flat_img, w, h, u, v)
        if not _ok(new, dark, saturated):
            continue
        for c in range(3):
            total[c] += new[c] - old[c]
        n += 1
    if n == 0:
        return np.zeros(3, np.float32), 0
    return np.array([t / n for t in total], np.float32), n


def sampling_error(sample: BrightnessSample, *args, **kwargs) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(|Δ_sample - Δ_all| (3,) in 0..255 units, Δ_sample, Δ_all): the sampled estimate against all core texels.

    ``args`` / ``kwargs`` are those of :func:`estimate_delta` (without ``sample_idx``).
    """
    d_sample, _ = estimate_delta(*args, sample_idx=sample, **kwargs)
    d_all, _ = estimate_delta(*args, sample_idx=None, **kwargs)
    return np.abs(d_sample.astype(np.float64) - d_all) * 255.0, d_sample, d_all
