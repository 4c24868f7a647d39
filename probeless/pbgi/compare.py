"""PBGI and environment-map renderings of an object against a Mitsuba 3 one-bounce reference (paper 001, Figure 14).

:class:`Comparison` holds one :class:`~probeless.pbgi.room.ReferenceRoom`: its cloud (:func:`sample_cloud`: the
emitters' exact radiance at 1 cm spacing) and BSH, the room's sphere seen by :func:`object_camera`, and a far-field
cubemap of the cloud splatted at the sphere's centre. :meth:`Comparison.render` draws the sphere with one material by

* ``reference`` -- Mitsuba 3 (``scalar_rgb``, ``direct`` integrator; :func:`render_reference`), the truth;
* ``pbgi`` -- our micro-buffer PBGI (the importance-sampled lookup below roughness 0.2, as shipped);
* ``pbgi_no_is`` -- the same without that lookup (only for roughness < 0.2: §6.3's artefact);
* ``envmap`` -- the same shading (Eq. 9 over a micro-buffer) with every direction read from the cubemap at the
  centre: the environment map "taken from the position of the relighted object, the optimal situation for this
  algorithm" (§6.3), so the difference to ``pbgi`` is the lighting representation alone;
* ``ibl`` -- the IBL compositor's shading of the same cubemap (:class:`~probeless.ibl.probes.ProbeRenderer`: SH
  irradiance for Lambert, the split-sum GGX prefilter without Fresnel or masking for GGX): what ships in the
  cubemap pipeline.

:func:`relative_rms` is the error of Figure 14: RMS of the luminance difference over the object's fully covered
pixels, divided by the RMS of the reference's luminance there. The reference is the mean of two Mitsuba renders
with different seeds (``spp / 2`` each); their difference estimates its Monte Carlo noise (``noise``: the RMS
noise of the mean, relative like the errors), and ``corrected`` errors remove it in quadrature
(sqrt(error^2 - noise^2): the noise is independent of every method's image), so methods are not judged on the
reference's grain.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from probeless.color import luminance
from probeless.errors import PbgiError

METHODS = ("pbgi", "pbgi_no_is", "envmap", "ibl")


def relative_rms(est: np.ndarray, ref: np.ndarray, mask: np.ndarray, rgb: bool = False) -> float:
    """RMS of luminance(est) - luminance(ref) over ``mask``, over the RMS of luminance(ref) there; with ``rgb`` over
    the R, G and B values instead of the luminance (colour errors such as bleeding count in full)."""
    if not mask.any():
        raise PbgiError("relative_rms: empty mask")
    pick = (lambda a: a[mask].astype(np.float64)) if rgb else (lambda a: luminance(a[mask]).astype(np.float64))
    y, y0 = pick(est), pick(ref)
    return float(np.sqrt(np.mean((y - y0) ** 2)) / np.sqrt(np.mean(y0 ** 2)))


def material_key(brdf) -> str:
    """``lambert`` or ``ggx-0.30`` style names of the compared materials."""
    return brdf.model if brdf.model == "lambert" else f"{brdf.model}-{brdf.roughness:.2f}"


@dataclass
class Rendered:
    """One material's images (H, W, 3) float32 linear radiance by method, and the compared pixels."""

    images: dict
    mask: np.ndarray
    errors: dict     # method -> relative_rms against the reference
    corrected: dict  # method -> the error with the reference's noise removed in quadrature
    noise: float     # relative RMS Monte Carlo noise of the reference (mean of two seeds)
    seconds: dict    # method -> render seconds (the reference's: small when it came from the cache)


class Comparison:
    """One room's cloud, hierarchy, camera and far field, rendering the room's sphere (see the module docstring)."""

    def __init__(self, room_name: str, *, size: int = 128, view: str = "front", micro: int = 24,
                 variant: str = "hybrid", spacing: float = 0.01, far_face: int = 128, spp: int = 1024,
                 supersample: int = 1, cache=True):
        from probeless.gl.context import create_context
        from probeless.hdr.splat import SplatRenderer, cloud_cubemap, point_spacing
        from probeless.ibl.mesh_io import place, uv_sphere
        from probeless.pbgi.bsh import build_bsh
        from probeless.pbgi.render import PbgiRenderer
        from probeless.pbgi.room import object_camera, reference_room, sample_cloud

        self.room = reference_room(room_name)
        self.size, self.spp, self.cache, self.micro, self.variant = int(size), int(spp), cache, micro, variant
        self.K, self.pose = object_camera(self.room, self.size, view)
        points, colors, normals = sample_cloud(self.room, spacing)
        self.n_points = len(points)
        self.bsh = build_bsh(points, colors, normals)
        self.mesh = place(*uv_sphere(), np.asarray(self.room.object_centre, float), radius=self.room.object_radius)
        self.ctx = create_context()
        splat = SplatRenderer(self.ctx)
        try:
            self.faces, covered = cloud_cubemap(splat, points, colors, point_spacing(points),
                                                self.room.object_centre, far_face)
        finally:
            splat.release()
        self.far_holes = float(1.0 - covered.mean())
        self.renderers = {is_r: PbgiRenderer([], variant=variant, micro=micro, is_roughness=is_r, ctx=self.ctx,
                                             supersample=supersample) for is_r in (0.2, 0.0)}
        for r in self.renderers.values():
            r.set_cloud(self.bsh)
            r.set_far_field(self.faces)

    def render(self, brdf) -> Rendered:
        """The sphere in material ``brdf`` (a :class:`~probeless.pbgi.materials.Brdf`) by every method."""
        import time

        from probeless.pbgi.render import PbgiObject

        t0 = time.perf_counter()
        (ref_a, ref_mask), (ref_b, _) = self._references(brdf)
        ref = 0.5 * (ref_a + ref_b)
        images, seconds = {"reference": ref}, {"reference": time.perf_counter() - t0}
        runs = [("pbgi", 0.2, None), ("envmap", 0.2, "envmap")]
        if brdf.model != "lambert" and brdf.roughness < 0.2:
            runs.append(("pbgi_no_is", 0.0, None))
        mask = ref_mask
        for name, is_r, variant in runs:
            r = self.renderers[is_r]
            r.set_objects([PbgiObject("sphere", self.mesh, brdf)])
            t0 = time.perf_counter()
            res = r.render(self.K, self.pose, self.size, self.size, variant=variant)
            seconds[name] = time.perf_counter() - t0
            images[name] = res.color
            mask = mask & res.mask
        images["ibl"], ibl_mask = self._ibl(brdf)
        mask = mask & ibl_mask
        errors = {m: relative_rms(images[m], ref, mask) for m in METHODS if m in images}
        noise = 0.5 * relative_rms(ref_a, ref_b, mask) * float(np.sqrt(np.mean(luminance(ref_b[mask]) ** 2)) /
                                                              np.sqrt(np.mean(luminance(ref[mask]) ** 2)))
        corrected = {m: float(np.sqrt(max(0.0, e * e - noise * noise))) for m, e in errors.items()}
        return Rendered(images, mask, errors, corrected, float(noise), seconds)

    def _references(self, brdf) -> list:
        from probeless.pbgi.reference import render_reference

        return [render_reference(self.room, brdf, self.K, self.pose, self.size, self.size, spp=max(1, self.spp // 2),
                                 seed=seed, cache=self.cache) for seed in (0, 1)]

    def reference(self, brdf) -> tuple[np.ndarray, np.ndarray]:
        """(Mitsuba image, mask) of the sphere in ``brdf``: the mean of the two seeds :meth:`render` compares with."""
        (a, mask), (b, _) = self._references(brdf)
        return 0.5 * (a + b), mask

    def pbgi(self, brdf) -> tuple[np.ndarray, np.ndarray]:
        """(image, mask) of the sphere in ``brdf`` by our PBGI alone, as :meth:`render`'s ``pbgi`` (no reference)."""
        from probeless.pbgi.render import PbgiObject

        r = self.renderers[0.2]
        r.set_objects([PbgiObject("sphere", self.mesh, brdf)])
        res = r.render(self.K, self.pose, self.size, self.size)
        return res.color, res.mask

    def panel_target(self) -> np.ndarray | None:
        """The area-weighted centre of the room's panels [m, world] (a cut-up panel: its whole), None without."""
        panels = [p for p in self.room.panels if p.in_cloud]
        if not panels:
            return None
        w = np.array([p.area for p in panels])
        centres = np.array([p.origin + 0.5 * (p.edge_u + p.edge_v) for p in panels])
        return (w[:, None] * centres).sum(0) / w.sum()

    def facing(self, mask: np.ndarray, target, cos_min: float = 0.5) -> np.ndarray:
        """``mask`` pixels of the sphere whose normal points within acos(cos_min) of the direction to ``target``."""
        from probeless.pbgi.reference import pixel_rays

        h, w = mask.shape
        v, u = np.mgrid[0:h, 0:w]
        o, d = pixel_rays(self.K, self.pose, u.ravel().astype(float), v.ravel().astype(float))
        c, r = np.asarray(self.room.object_centre, float), float(self.room.object_radius)
        oc = o - c
        b = (d * oc).sum(-1)
        disc = b * b - ((oc * oc).sum(-1) - r * r)
        t = -b - np.sqrt(np.maximum(disc, 0))
        n = (o + t[:, None] * d - c) / r
        to = np.asarray(target, float) - c
        return mask & ((n @ (to / np.linalg.norm(to))) >= cos_min).reshape(h, w)

    def _ibl(self, brdf) -> tuple[np.ndarray, np.ndarray]:
        from probeless.ibl.probes import ProbeRenderer

        if brdf.model not in ("lambert", "ggx") or (brdf.model == "ggx" and not np.allclose(brdf.base_color, 1)):
            raise PbgiError(f"the IBL comparison takes Lambert or GGX with f0 = 1, got {brdf}")
        probe = ProbeRenderer(self.ctx, self.room.object_centre, self.room.object_radius, brdf.roughness,
                              [(self.K, self.pose)], self.size)
        try:
            out = probe.render(self.faces)
        finally:
            probe.release()
        if brdf.model == "lambert":
            color, mask = out["diffuse"][0]
            return (color * np.asarray(brdf.base_color)).astype(np.float32), mask
        color, mask = out["ggx"][0]
        return color.astype(np.float32), mask

    def release(self) -> None:
        for r in self.renderers.values():
            r.release()
        self.ctx.release()
