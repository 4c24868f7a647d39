"""Lighting maps for paper 002's Figure 7 made quantitative (:mod:`probeless.pano.itmo_eval`).

For a true-HDR panorama, an auto-exposed 8-bit camera is simulated (:func:`camera_exposure`,
:func:`make_ldr`): the exposure maps the luminance exceeded by 10% of the sphere (solid-angle
weighted 90th percentile, Rec. 709 luminance) to linear 0.5 (sRGB code 188), i.e. the camera meters
for the bright part of the scene and clips only the light sources (3-4% of the sphere on the
shipped panoramas); values are clipped to 0..1 and sRGB-encoded to uint8 (IEC 61966-2-1). The
lighting maps (:func:`lighting_maps`), all in the same camera units:

* ``ldr``: the 8-bit map decoded to linear, no expansion;
* ``paper``: Eq. 1-3 on the display (sRGB-coded) values, as the paper does; ``paper_linear``: the
  same operator on gamma-decoded values (shows what skipping linearisation costs);
* ``landis``, ``akyuz``, ``banterle``: :mod:`probeless.pano.itmo` on gamma-decoded values (2.2);
* ``hdr``: the true panorama times the exposure (the reference).

Every map lights a diffuse, a glossy and a mirror sphere (:mod:`probeless.pano.spheres`) seen from
four horizontal directions (:class:`SphereLighting`, :func:`render_spheres`); the errors are in :mod:`itmo_metrics`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from probeless.color import REC709_Y, from_srgb8
from probeless.errors import DatasetError
from probeless.pano import glossy
from probeless.pano.diffuse import diffuse_map
from probeless.pano.equirect import check_equirect, solid_angles
from probeless.pano.itmo import EXPOSURE_PERCENTILE, EXPOSURE_TARGET, apply_itmo, gamma_decode, paper_itmo
from probeless.pano.sources import read_panorama
from probeless.pano.spheres import OBJECTS, shade, sphere_view
from probeless.scene.rig import expose

MAPS = ("ldr", "paper", "paper_linear", "landis", "akyuz", "banterle", "hdr")
VIEWS = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (-1.0, 0.0, 0.0), (0.0, -1.0, 0.0))
DIFFUSE_SIZE = (32, 16)
ROUGHNESS = 0.1


def weighted_percentile(values: np.ndarray, q: float) -> float:
    """The ``q`` quantile (0..1) of an equirect (H, 2H) map, each texel weighted by its solid angle."""
    h, w = values.shape
    order = np.argsort(values, axis=None)
    cum = np.cumsum(solid_angles(w, h).reshape(-1)[order])
    return float(values.reshape(-1)[order][min(np.searchsorted(cum, q * cum[-1]), len(order) - 1)])


def camera_exposure(hdr: np.ndarray, percentile: float = EXPOSURE_PERCENTILE,
                    target: float = EXPOSURE_TARGET) -> float:
    """Exposure ``k`` mapping the weighted ``percentile`` of the luminance of ``hdr`` to ``target``."""
    lum = check_equirect(hdr, "camera_exposure").astype(np.float64) @ REC709_Y
    ref = weighted_percentile(lum, percentile)
    if not ref > 0:
        raise DatasetError(f"camera_exposure: the {percentile:.0%} luminance percentile is {ref}, not positive")
    return target / ref


def make_ldr(hdr: np.ndarray, exposure: float) -> np.ndarray:
    """uint8 sRGB (H, W, 3) camera image of ``hdr * exposure``: clipped to 0..1, then sRGB-encoded."""
    return expose(np.asarray(hdr, np.float32), exposure)


def lighting_maps(hdr: np.ndarray, exposure: float) -> dict[str, np.ndarray]:
    """Every map of :data:`MAPS` (linear float32, camera units) made from ``hdr`` at ``exposure``."""
    ldr8 = make_ldr(hdr, exposure)
    display = ldr8.astype(np.float32) / 255.0
    decoded = gamma_decode(display)
    maps = {"ldr": from_srgb8(ldr8), "paper": paper_itmo(display), "paper_linear": paper_itmo(decoded)}
    for name in ("landis", "akyuz", "banterle"):
        maps[name] = apply_itmo(name, decoded)
    maps["hdr"] = (np.asarray(hdr, np.float32) * np.float32(exposure)).astype(np.float32)
    return maps


def ldr_stats(hdr: np.ndarray, exposure: float) -> dict[str, float]:
    """Solid-angle fraction of the sphere clipped by the camera and share of the light it keeps."""
    lin = np.asarray(hdr, np.float64) * exposure
    h, w = lin.shape[:2]
    sa = solid_angles(w, h)
    clipped = float((sa * (lin.max(axis=-1) >= 1.0)).sum() / sa.sum())
    kept = float((np.minimum(lin, 1.0) * sa[..., None]).sum() / max((lin * sa[..., None]).sum(), 1e-30))
    return {"clipped_fraction": clipped, "ldr_energy_fraction": kept}


@dataclass(frozen=True)
class SphereSetup:
    """What the spheres are rendered with: views, image size, materials."""

    views: tuple = VIEWS
    size: int = 64
    roughness: float = ROUGHNESS
    albedo: float = 0.8
    specular: float = 1.0
    diffuse_size: tuple = DIFFUSE_SIZE


@dataclass(frozen=True)
class SphereLighting:
    """A lighting map with what the spheres sample: its mip chain and its diffuse map."""

    env: np.ndarray
    levels: list
    diffuse: np.ndarray

    @classmethod
    def of(cls, env: np.ndarray, diffuse_size: tuple = DIFFUSE_SIZE) -> "SphereLighting":
        """Mip chain (:func:`glossy.mip_levels`) and diffuse map (:func:`diffuse_map`) of ``env``."""
        return cls(env, glossy.mip_levels(env), diffuse_map(env, diffuse_size))


def render_spheres(lit: SphereLighting, setup: SphereSetup = SphereSetup(), views: tuple | None = None,
                   size: int | None = None) -> dict[str, np.ndarray]:
    """Per object of :data:`OBJECTS`, the (N, 3) radiance of the sphere pixels of every view (default
    ``setup.views`` at ``setup.size``), the views one after the other, lit by ``lit``."""
    vs = [sphere_view(size or setup.size, f) for f in (views or setup.views)]
    normals, reflect = np.concatenate([v.normals for v in vs]), np.concatenate([v.reflect for v in vs])
    return {o: shade(o, normals, reflect, lit.env, lit.diffuse, lit.levels, setup.roughness, setup.albedo,
                     setup.specular) for o in OBJECTS}


def load_case(path: str) -> tuple[str, np.ndarray]:
    """(name, linear HDR float32) of an HDR panorama file; DatasetError for an LDR file."""
    img = read_panorama(path)
    if img.dtype != np.float32:
        raise DatasetError(f"{path}: not an HDR panorama (need .hdr/.pic/.exr with true HDR)")
    return os.path.splitext(os.path.basename(path))[0], img
