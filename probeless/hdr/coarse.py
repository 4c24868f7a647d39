"""HDR expansion of the coarse room model's atlas and of the dense model (paper 003's future work, paper 001 §4).

The coarse model's atlas (:mod:`probeless.coarse.gpu`, the texturer's published ``rgba8`` image) holds camera
LDR values: the fisheye's sRGB-encoded output / 255, alpha > 0 where the texel was observed directly. Every
observed texel is a point of a cloud: its centre (:class:`probeless.coarse.texels.TexelMap` ``position``,
the atlas layout's mapping), its inward surface normal and its colour decoded to linear 0..1
(:func:`probeless.color.srgb_to_linear`). :func:`expand_atlas` runs :func:`probeless.hdr.expand.expand_cloud`
on that cloud with the HDR photo and writes the radiance back into an atlas of the same layout:

* only **core** texels (centre on the surface itself) go into the cloud: the padding ring of a wall repeats
  the positions of the wall's edge texels (clamped onto it), and duplicate points would give the kNN graph of
  the Poisson fill zero-length edges. An observed ring texel keeps its linear LDR value, or, where it is
  over-exposed (:func:`probeless.hdr.transfer.overexposed`), takes the HDR value of the nearest observed core
  texel of its own surface (atlas distance), so bilinear lookups at an edge read the expanded value;
* inpainted and never-observed texels keep their linear LDR value (inpainting is LDR; known limit).

Radiance is in cloud units: the camera's linear scale (1 = the fisheye's LDR white), unbounded above. The
cubemap renderer draws such an atlas with ``set_atlas(..., linear=True)``
(:class:`probeless.envmap.cubemap.EnvmapRenderer`). :func:`expand_dense` does the same for the dense model's
coloured points (already a cloud), with the brightness change Δ applied first as the renderer applies it.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.ndimage import distance_transform_edt

from probeless.coarse.texels import TexelMap
from probeless.color import from_srgb8, srgb_to_linear
from probeless.errors import HdrError
from probeless.hdr.expand import ExpansionResult, expand_cloud
from probeless.hdr.transfer import overexposed


@dataclasses.dataclass(frozen=True, eq=False)
class TexelCloud:
    """The observed core texels of an atlas as a point cloud: texel ``rows``, ``cols`` (N,) int64 (atlas row
    0 = top); ``points`` (N, 3) float32 texel centres [m, world]; ``normals`` (N, 3) float32 inward unit
    normals; ``colors`` (N, 3) float32 linear LDR 0..1."""

    rows: np.ndarray
    cols: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    colors: np.ndarray


@dataclasses.dataclass(frozen=True, eq=False)
class HdrAtlas:
    """``radiance`` (H, W, 3) float32 linear >= 0 [cloud units], the atlas layout's shape; ``ldr_linear``
    (H, W, 3) float32 the input atlas decoded to linear; ``cloud`` the :class:`TexelCloud` expanded;
    ``result`` :func:`~probeless.hdr.expand.expand_cloud`'s :class:`~probeless.hdr.expand.ExpansionResult`;
    ``report``: its report plus the texel counts (``texels_observed``, ``texels_cloud``, ``texels_ring``,
    ``texels_ring_expanded``, ``texels_inpainted_or_unseen``)."""

    radiance: np.ndarray
    ldr_linear: np.ndarray
    cloud: TexelCloud
    result: ExpansionResult
    report: dict


def atlas_linear(atlas: np.ndarray, what: str = "atlas") -> np.ndarray:
    """(H, W, 3) float32 linear 0..1 of a camera-LDR atlas (H, W, 3|4): uint8 sRGB codes, or floats 0..1
    sRGB-encoded (the texturer's float atlas; clipped to 0..1 first). Alpha is ignored."""
    a = np.asarray(atlas)
    if a.ndim != 3 or a.shape[2] not in (3, 4) or 0 in a.shape:
        raise HdrError(f"{what}: expected an (H, W, 3|4) camera-LDR image, got shape {a.shape}")
    rgb = a[..., :3]
    if rgb.dtype == np.uint8:
        return from_srgb8(rgb)
    if not np.issubdtype(rgb.dtype, np.floating) or not np.isfinite(rgb).all():
        raise HdrError(f"{what}: expected uint8 codes or finite floats 0..1, got dtype {rgb.dtype}")
    return srgb_to_linear(np.clip(rgb.astype(np.float32), 0.0, 1.0)).astype(np.float32)


def observed_mask(atlas: np.ndarray, observed: np.ndarray | None = None, what: str = "atlas") -> np.ndarray:
    """(H, W) bool: ``observed`` when given, else the atlas's alpha > 0 (the texturer's ``rgba8`` convention)."""
    a = np.asarray(atlas)
    if observed is None:
        if a.ndim != 3 or a.shape[2] != 4:
            raise HdrError(f"{what}: without an observed mask the atlas needs an alpha channel (H, W, 4), "
                           f"got shape {a.shape}")
        return a[..., 3] > 0
    m = np.asarray(observed)
    if m.shape != a.shape[:2]:
        raise HdrError(f"{what}: observed mask is {m.shape}, the atlas {a.shape[:2]}")
    return m.astype(bool)


def _check_texmap(texmap: TexelMap, shape: tuple[int, ...], what: str) -> None:
    if texmap.surface.shape != tuple(shape[:2]):
        raise HdrError(f"{what}: atlas is {tuple(shape[:2])} texels, the texel map (layout) "
                       f"{texmap.surface.shape}")


def texel_cloud(atlas: np.ndarray, texmap: TexelMap, observed: np.ndarray | None = None) -> TexelCloud:
    """The observed core texels of ``atlas`` as a :class:`TexelCloud` (module docstring), in row-major order.

    ``atlas``: (H, W, 3|4) camera LDR (:func:`atlas_linear`); ``observed``: (H, W) bool, default alpha > 0;
    ``texmap``: the atlas layout's :func:`~probeless.coarse.texels.texel_map`.
    """
    _check_texmap(texmap, np.shape(atlas), "texel_cloud")
    seen = observed_mask(atlas, observed, "texel_cloud")
    rows, cols = np.nonzero(seen & texmap.core & texmap.valid)
    lin = atlas_linear(atlas, "texel_cloud")
    return TexelCloud(rows.astype(np.int64), cols.astype(np.int64), texmap.position[rows, cols].astype(np.float32),
                      texmap.normal[rows, cols].astype(np.float32), lin[rows, cols])


def fill_ring(radiance: np.ndarray, ldr_linear: np.ndarray, texmap: TexelMap, seen: np.ndarray) -> np.ndarray:
    """(H, W) bool of the observed non-core texels given the radiance of the nearest observed core texel of
    their surface (where they are over-exposed); ``radiance`` is updated in place (module docstring)."""
    core = seen & texmap.core & texmap.valid
    ring = seen & ~texmap.core & texmap.valid & overexposed(ldr_linear)
    if not ring.any() or not core.any():
        return np.zeros(seen.shape, bool)
    _, (nr, nc) = distance_transform_edt(~core, return_indices=True)
    rr, cc = np.nonzero(ring)
    same = texmap.surface[nr[rr, cc], nc[rr, cc]] == texmap.surface[rr, cc]
    rr, cc = rr[same], cc[same]
    radiance[rr, cc] = radiance[nr[rr, cc], nc[rr, cc]]
    done = np.zeros(seen.shape, bool)
    done[rr, cc] = True
    return done


def expand_atlas(atlas: np.ndarray, texmap: TexelMap, photo_hdr, *, observed: np.ndarray | None = None,
                 method: str = "pmatch-rgb", views=None, transfer: str = "rgb", size: int = 256,
                 ssd_threshold: float = 1.0, progress=None, **options) -> HdrAtlas:
    """The HDR atlas of a coarse model's camera-LDR ``atlas`` from one HDR photo (module docstring).

    ``atlas``, ``observed``, ``texmap``: as :func:`texel_cloud`; ``photo_hdr`` and the keyword arguments are
    :func:`~probeless.hdr.expand.expand_cloud`'s (the texel normals are passed along for view placement;
    ``options``: its ``exposure``, ``max_lum``, ``photo_pose``, ``robust``). HdrError when no texel was observed.
    """
    cloud = texel_cloud(atlas, texmap, observed)
    if len(cloud.points) == 0:
        raise HdrError("expand_atlas: no observed texel on the coarse model's surfaces (atlas alpha all 0?)")
    seen = observed_mask(atlas, observed, "expand_atlas")
    result = expand_cloud(cloud.points, cloud.colors, photo_hdr, method=method, views=views, transfer=transfer,
                          normals=cloud.normals, size=size, ssd_threshold=ssd_threshold, progress=progress,
                          **options)
    ldr = atlas_linear(atlas, "expand_atlas")
    radiance = ldr.copy()
    radiance[cloud.rows, cloud.cols] = result.radiance
    ring = fill_ring(radiance, ldr, texmap, seen)
    n_ring = int((seen & ~texmap.core & texmap.valid).sum())
    report = {**result.report, "texels_observed": int(seen.sum()), "texels_cloud": int(len(cloud.points)),
              "texels_ring": n_ring, "texels_ring_expanded": int(ring.sum()),
              "texels_inpainted_or_unseen": int((texmap.valid & ~seen).sum())}
    return HdrAtlas(radiance.astype(np.float32), ldr, cloud, result, report)


def dense_linear(colors: np.ndarray, delta=(0.0, 0.0, 0.0)) -> np.ndarray:
    """(N, 3) float32 linear 0..1 of dense-model colours as the cubemap renderer shows them: camera LDR
    (uint8 0..255 or float 0..1, sRGB-encoded) plus the brightness change ``delta`` [camera LDR units],
    clipped to 0..1, then decoded."""
    c = np.asarray(colors)
    if c.ndim != 2 or c.shape[1] != 3:
        raise HdrError(f"dense colours: expected (N, 3), got shape {c.shape}")
    d = np.asarray(delta, np.float32).reshape(-1)
    if d.shape != (3,) or not np.isfinite(d).all():
        raise HdrError(f"dense delta: expected 3 finite numbers, got {delta!r}")
    ldr = c.astype(np.float32) / 255.0 if c.dtype == np.uint8 else c.astype(np.float32)
    if not np.isfinite(ldr).all():
        raise HdrError("dense colours: NaN or infinite values")
    return srgb_to_linear(np.clip(ldr + d, 0.0, 1.0)).astype(np.float32)


def expand_dense(points: np.ndarray, colors: np.ndarray, photo_hdr, *, delta=(0.0, 0.0, 0.0),
                 method: str = "pmatch-rgb", views=None, transfer: str = "rgb", size: int = 256,
                 ssd_threshold: float = 1.0, progress=None, **options) -> ExpansionResult:
    """HDR radiance of the dense model's points (:func:`~probeless.hdr.expand.expand_cloud` on
    :func:`dense_linear` colours): draw ``result.radiance`` with ``set_dense(..., linear=True)`` and no Δ."""
    ldr = dense_linear(colors, delta)
    return expand_cloud(points, ldr, photo_hdr, method=method, views=views, transfer=transfer, size=size,
                        ssd_threshold=ssd_threshold, progress=progress, **options)
