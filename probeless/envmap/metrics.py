"""Environment-map accuracy against ground truth (issue 7): PSNR, SSIM, coverage, sphere renders, SH error.

Maps are (6, S, S, 3) cubemaps in the convention of :mod:`probeless.messages.lighting` / :mod:`probeless.geom.cube`.
PSNR and SSIM work in the camera LDR domain: floats 0..1 (sRGB-encoded camera output / 255; uint8
input is divided by 255), peak 1. Every texel counts the same in PSNR/SSIM (like an image metric
over the six faces); pass ``weights=cube_solid_angles(S)`` (:mod:`probeless.geom.cube`) to :func:`envmap_psnr` for a
per-steradian error instead.

Spheres are drawn orthographically from +X looking at the origin (towards -X), +Z up, so image
right is +Y: pixel (row r, col c) of a ``size`` image lies at ``y = 2 (c + 0.5) / size - 1`` (right),
``z = 1 - 2 (r + 0.5) / size`` (up) on the image plane; pixels outside the unit disc are 0 and
excluded from the sphere PSNRs. The mirror sphere shows the environment along the reflected ray
(its centre pixel: along +X, back towards the viewer).
"""

from __future__ import annotations

import cv2
import numpy as np

from probeless.color import linear_to_srgb, srgb_to_linear
from probeless.errors import ProbelessError
from probeless.geom.cube import cube_directions, cube_solid_angles, sample_cubemap

SSIM_SIGMA, SSIM_RADIUS, SSIM_K1, SSIM_K2 = 1.5, 5, 0.01, 0.03  # Wang et al. 2004: 11x11 Gaussian window
VIEW, RIGHT, UP = np.array([-1.0, 0, 0]), np.array([0, 1.0, 0]), np.array([0, 0, 1.0])
# Ramamoorthi & Hanrahan 2001: irradiance = SH radiance convolved with the clamped cosine, A_l per band
COSINE_LOBE = np.array([np.pi, 2 * np.pi / 3, np.pi / 4, 0.0, -np.pi / 24])


def _ldr(faces: np.ndarray) -> np.ndarray:
    f = np.asarray(faces)
    if f.ndim != 4 or f.shape[0] != 6 or f.shape[1] != f.shape[2] or f.shape[3] < 3:
        raise ProbelessError(f"envmap metrics: expected (6, S, S, 3) faces, got shape {f.shape}")
    return f[..., :3].astype(np.float64) / (255.0 if f.dtype == np.uint8 else 1.0)


def _pair(est: np.ndarray, ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a, b = _ldr(est), _ldr(ref)
    if a.shape != b.shape:
        raise ProbelessError(f"envmap metrics: estimate {a.shape} and reference {b.shape} differ in shape")
    return a, b


def psnr(est: np.ndarray, ref: np.ndarray, weights: np.ndarray | None = None) -> float:
    """10 log10(1 / MSE) [dB] of (..., C) arrays with peak 1, MSE weighted per element of ``weights`` (...)."""
    err = np.mean((np.asarray(est, np.float64) - np.asarray(ref, np.float64)) ** 2, axis=-1)
    w = np.ones_like(err) if weights is None else np.broadcast_to(weights, err.shape).astype(np.float64)
    if w.sum() <= 0:
        raise ProbelessError("envmap metrics: PSNR over an empty mask")
    mse = float((err * w).sum() / w.sum())
    return float("inf") if mse == 0 else 10.0 * np.log10(1.0 / mse)


def envmap_psnr(est: np.ndarray, ref: np.ndarray, mask: np.ndarray | None = None,
                weights: np.ndarray | None = None) -> float:
    """PSNR [dB] of two LDR cubemaps over the texels in ``mask`` (6, S, S) (all when None)."""
    a, b = _pair(est, ref)
    w = np.ones(a.shape[:3]) if weights is None else np.broadcast_to(weights, a.shape[:3])
    return psnr(a, b, w * (1.0 if mask is None else np.asarray(mask, bool)))


def ssim_map(x: np.ndarray, y: np.ndarray, data_range: float = 1.0) -> np.ndarray:
    """(H, W) SSIM map of two (H, W) or (H, W, C) images (channels averaged), Wang et al. 2004.

    Gaussian window sigma 1.5 truncated to 11x11, K1 = 0.01, K2 = 0.03, population (co)variances, borders
    reflected (as scikit-image's ``structural_similarity(..., full=True)``).
    """
    x, y = np.atleast_3d(np.asarray(x, np.float64)), np.atleast_3d(np.asarray(y, np.float64))
    if x.shape != y.shape or min(x.shape[:2]) <= 2 * SSIM_RADIUS:
        raise ProbelessError(f"SSIM: images must match and exceed {2 * SSIM_RADIUS + 1} px, got {x.shape}, {y.shape}")
    k = 2 * SSIM_RADIUS + 1

    def blur(img: np.ndarray) -> np.ndarray:
        return np.atleast_3d(cv2.GaussianBlur(img, (k, k), SSIM_SIGMA, borderType=cv2.BORDER_REFLECT))

    c1, c2 = (SSIM_K1 * data_range) ** 2, (SSIM_K2 * data_range) ** 2
    mx, my = blur(x), blur(y)
    vx, vy, cxy = blur(x * x) - mx * mx, blur(y * y) - my * my, blur(x * y) - mx * my
    s = (2 * mx * my + c1) * (2 * cxy + c2) / ((mx * mx + my * my + c1) * (vx + vy + c2))
    return s.mean(axis=2)


def ssim_image(x: np.ndarray, y: np.ndarray, data_range: float = 1.0) -> float:
    """Mean SSIM of two (H, W) or (H, W, C) images (:func:`ssim_map`), leaving out the 5-pixel border where the
    window leaves the image (as scikit-image does)."""
    r = SSIM_RADIUS
    return float(ssim_map(x, y, data_range)[r:-r, r:-r].mean())


def envmap_ssim(est: np.ndarray, ref: np.ndarray) -> float:
    """Mean over the six faces of :func:`ssim_image` in the LDR domain (faces compared separately)."""
    a, b = _pair(est, ref)
    return float(np.mean([ssim_image(a[f], b[f]) for f in range(6)]))


def coverage(observed: np.ndarray, solid_angles: np.ndarray | None = None) -> float:
    """Fraction of the sphere of directions covered by ``observed`` (6, S, S) texels, solid-angle weighted."""
    obs = np.asarray(observed, bool)
    omega = cube_solid_angles(obs.shape[1]) if solid_angles is None else np.asarray(solid_angles, np.float64)
    return float((omega * obs).sum() / omega.sum())


def sphere_normals(size: int) -> tuple[np.ndarray, np.ndarray]:
    """(normals (size, size, 3) of the unit sphere seen from +X, 0 off it; on-sphere mask (size, size))."""
    t = 2.0 * (np.arange(size) + 0.5) / size - 1.0
    z, y = -t[:, None] * np.ones(size), t[None, :] * np.ones((size, 1))
    r2 = y * y + z * z
    inside = r2 <= 1.0
    n = np.stack([np.sqrt(np.clip(1.0 - r2, 0, None)), y, z], axis=-1)
    return np.where(inside[..., None], n, 0.0), inside


def render_mirror_sphere(faces: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
    """(image (size, size, C) of a mirror sphere lit by ``faces``, on-sphere mask); reflection r = v - 2 (v.n) n."""
    n, inside = sphere_normals(size)
    r = VIEW - 2.0 * (n @ VIEW)[..., None] * n
    img = sample_cubemap(np.asarray(faces), r[inside])
    out = np.zeros((size, size, img.shape[-1]), img.dtype)
    out[inside] = img
    return out, inside


def downsample_faces(faces: np.ndarray, max_size: int) -> np.ndarray:
    """Faces box-averaged by 2x2 blocks until at most ``max_size`` texels wide
    (each block weighted by its solid angle)."""
    f = np.asarray(faces, np.float64)
    while f.shape[1] > max_size and f.shape[1] % 2 == 0:
        s = f.shape[1]
        w = cube_solid_angles(s)[..., None]
        blocks = (f * w).reshape(6, s // 2, 2, s // 2, 2, -1).sum(axis=(2, 4))
        f = blocks / w.reshape(6, s // 2, 2, s // 2, 2, 1).sum(axis=(2, 4))
    return f


def render_diffuse_sphere(faces_linear: np.ndarray, size: int, albedo: float = 1.0,
                          max_face: int = 32) -> tuple[np.ndarray, np.ndarray]:
    """(outgoing radiance (size, size, C) of a Lambertian sphere, on-sphere mask), no self-shadowing.

    Per pixel ``albedo / pi * E(n)`` with irradiance ``E(n) = sum L(w) max(0, n.w) dOmega(w)`` over the
    cube texels (exact texel solid angles, cosine at texel centres; faces first averaged down to <=
    ``max_face``). The 1/pi makes a constant environment L give ``albedo * L`` (within 0.1 % at 32^2 faces:
    the quadrature of the clamped cosine). Linear radiance in, linear radiance out.
    """
    f = downsample_faces(faces_linear, max_face)
    s = f.shape[1]
    dirs = cube_directions(s).reshape(-1, 3)
    weighted = f.reshape(-1, f.shape[-1]) * cube_solid_angles(s).reshape(-1, 1)
    n, inside = sphere_normals(size)
    normals = n[inside]
    irr = np.concatenate([np.clip(normals[i:i + 2048] @ dirs.T, 0, None) @ weighted
                          for i in range(0, len(normals), 2048)]) if len(normals) else np.zeros((0, f.shape[-1]))
    out = np.zeros((size, size, f.shape[-1]))
    out[inside] = albedo / np.pi * irr
    return out, inside


def mirror_psnr(est: np.ndarray, ref: np.ndarray, size: int = 128) -> float:
    """PSNR [dB] of mirror spheres drawn with two LDR cubemaps, over the sphere's pixels."""
    a, b = _pair(est, ref)
    (ia, inside), (ib, _) = render_mirror_sphere(a, size), render_mirror_sphere(b, size)
    return psnr(ia[inside], ib[inside])


def diffuse_psnr(est: np.ndarray, ref: np.ndarray, size: int = 64, albedo: float = 0.8) -> float:
    """PSNR [dB] of diffuse spheres lit by two LDR cubemaps, compared in LDR.

    The maps are linearised (inverse sRGB: camera-exposure-relative linear units, clipped where the camera
    clipped), the spheres shaded with ``albedo`` and re-encoded to sRGB (clipped at 1) before the PSNR.
    """
    a, b = _pair(est, ref)
    (ia, inside), (ib, _) = (render_diffuse_sphere(srgb_to_linear(m), size, albedo) for m in (a, b))
    return psnr(linear_to_srgb(ia[inside]), linear_to_srgb(ib[inside]))


def sh_rel_error(est: np.ndarray, ref: np.ndarray, irradiance: bool = True) -> float:
    """Relative L2 error ``|est - ref| / |ref|`` of (bands^2, 3) SH radiance coefficients (Frobenius norms).

    With ``irradiance`` (default) each band l is first scaled by the clamped-cosine factor A_l (pi, 2pi/3,
    pi/4, 0, -pi/24, ...): the SH coefficients of irradiance, so by Parseval the result is the relative
    L2 error of the irradiance function over the sphere. Without it: of the raw coefficients.
    """
    e, r = np.asarray(est, np.float64), np.asarray(ref, np.float64)
    bands = round(np.sqrt(len(r)))
    if e.shape != r.shape or bands * bands != len(r) or bands > len(COSINE_LOBE):
        raise ProbelessError(f"sh_rel_error: need equal (bands^2, C) arrays with bands <= {len(COSINE_LOBE)}, "
                             f"got {e.shape} and {r.shape}")
    if irradiance:
        scale = np.repeat(COSINE_LOBE[:bands], 2 * np.arange(bands) + 1)[:, None]
        e, r = e * scale, r * scale
    norm = np.linalg.norm(r)
    if norm == 0:
        raise ProbelessError("sh_rel_error: the reference coefficients are all zero")
    return float(np.linalg.norm(e - r) / norm)
