"""Diffuse radiance maps of equirectangular HDR frames (paper 002, Algorithm 1).

A diffuse map texel with direction ``n`` holds the outgoing radiance of a white Lambertian
surface with normal ``n``: ``D(n) = sum_w L(w) max(0, n . w) dOmega(w) / norm``. The paper
normalises by the weight sum (``accumulator / weight``, ``normalize="weights"``), which equals
``pi`` in the continuum; ``normalize="pi"`` divides by ``pi`` instead. The paper weights input
texels by ``cos(latitude)``, the midpoint rule for a pixel's solid angle; we use the exact
solid angle (:func:`probeless.pano.equirect.solid_angles`). Conventions: see ``equirect``.
"""

from __future__ import annotations

import functools

import cv2
import numpy as np

from probeless.envmap.sh import irradiance_from_sh, sh_basis
from probeless.errors import ProbelessError
from probeless.pano.equirect import check_equirect, pixel_directions, pixel_to_direction, solid_angles

NORMALIZE = ("weights", "pi")
IN_SIZES = ((128, 64), (64, 32))  # default input sizes, largest first
MAX_WEIGHTS = 1 << 24  # entries (64 MiB float32) allowed in a default-sized weight matrix


def _check(out_size: tuple[int, int], normalize: str) -> tuple[int, int]:
    w, h = (int(s) for s in out_size)
    if w < 1 or w != 2 * h:
        raise ProbelessError(f"diffuse map: out_size must be (2H, H), got {out_size}")
    if normalize not in NORMALIZE:
        raise ProbelessError(f"diffuse map: unknown normalize {normalize!r}; choices: {', '.join(NORMALIZE)}")
    return w, h


def _finish(acc: np.ndarray, wsum: np.ndarray, normalize: str) -> np.ndarray:
    return acc / (wsum if normalize == "weights" else np.pi)


@functools.lru_cache(maxsize=8)
def diffuse_weights(out_size: tuple[int, int], in_size: tuple[int, int], sub: int = 4) -> np.ndarray:
    """(out_texels, in_texels) float32 integral of ``max(0, n . w)`` over each input texel.

    Each input texel is integrated with ``sub x sub`` exact-solid-angle sub-texels, so the weight
    is right for an input that is constant over the texel (what area averaging produces).
    """
    (ow, oh), (iw, ih) = out_size, in_size
    normals = pixel_directions(ow, oh).reshape(-1, 3)
    fine = pixel_directions(iw * sub, ih * sub) * solid_angles(iw * sub, ih * sub)[..., None]
    # (ih, sub, iw, sub, 3) -> per input texel, its sub-samples; cosine clamp needs them apart
    fine = fine.reshape(ih, sub, iw, sub, 3).transpose(0, 2, 1, 3, 4).reshape(ih * iw, sub * sub, 3)
    area = np.linalg.norm(fine, axis=-1)
    unit = fine / area[..., None]
    out = np.zeros((len(normals), ih * iw), dtype=np.float64)
    for k in range(sub * sub):
        out += np.maximum(normals @ unit[:, k].T, 0.0) * area[:, k]
    return out.astype(np.float32)


def diffuse_map(hdr: np.ndarray, out_size: tuple[int, int] = (32, 16),
                in_size: tuple[int, int] | None = None, normalize: str = "weights") -> np.ndarray:
    """(H_out, W_out, C) float32 diffuse radiance map of the equirect ``hdr`` (H, 2H, C).

    ``hdr`` is area-averaged to ``in_size`` (W, H) (cv2.INTER_AREA, the mipmap stand-in), then
    every output texel is one row of a cached weight matrix times the input: one matmul.
    ``in_size=None`` takes the first of :data:`IN_SIZES` whose matrix has at most
    :data:`MAX_WEIGHTS` entries: 128x64 for outputs up to 64x32, 64x32 for 128x64.
    """
    ow, oh = _check(out_size, normalize)
    img = check_equirect(hdr, "diffuse_map").astype(np.float32)
    if in_size is None:
        in_size = next((s for s in IN_SIZES if s[0] * s[1] * ow * oh <= MAX_WEIGHTS), IN_SIZES[-1])
    iw, ih = int(in_size[0]), int(in_size[1])
    if iw != 2 * ih or ih < 1:
        raise ProbelessError(f"diffuse_map: in_size must be (2H, H), got {in_size}")
    small = img if img.shape[:2] == (ih, iw) else cv2.resize(img, (iw, ih), interpolation=cv2.INTER_AREA)
    small = small.reshape(ih * iw, -1)
    wts = diffuse_weights((ow, oh), (iw, ih))
    acc = wts @ small
    return _finish(acc, wts.sum(axis=1, keepdims=True), normalize).reshape(oh, ow, -1).astype(np.float32)


def bruteforce_inputs(hdr: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The brute force's per-frame setup: (N, 3) pixel directions, (N,) solid angles [sr] and
    (N, C) float64 radiance of every full-resolution pixel of the equirect ``hdr``."""
    img = check_equirect(hdr, "diffuse_map_bruteforce").astype(np.float64)
    h, w, c = img.shape
    return pixel_directions(w, h).reshape(-1, 3), solid_angles(w, h).reshape(-1), img.reshape(-1, c)


def bruteforce_texels(inputs: tuple[np.ndarray, np.ndarray, np.ndarray], out_size: tuple[int, int],
                      texels: np.ndarray, normalize: str = "weights") -> np.ndarray:
    """(len(texels), C) float32 brute-force values of the flat output ``texels`` from
    :func:`bruteforce_inputs`: every input pixel weighted ``solid angle * max(0, n . w)``."""
    ow, oh = _check(out_size, normalize)
    dirs, omega, flat = inputs
    idx = np.asarray(texels).reshape(-1)
    v, u = np.divmod(idx, ow)
    normals = pixel_to_direction(u + 0.5, v + 0.5, ow, oh)
    out = np.empty((len(idx), flat.shape[1]), dtype=np.float64)
    for k, n in enumerate(normals):
        wgt = omega * np.maximum(dirs @ n, 0.0)
        out[k] = _finish(wgt @ flat, wgt.sum(), normalize)
    return out.astype(np.float32)


def diffuse_map_bruteforce(hdr: np.ndarray, out_size: tuple[int, int] = (32, 16),
                           normalize: str = "weights", texels: np.ndarray | None = None) -> np.ndarray:
    """The paper's straightforward construction on the FULL-resolution frame, one texel at a time.

    For each output texel: loop over every input pixel (numpy over the frame), weight
    ``solid angle * max(0, n . w)``, accumulate. ``texels`` (flat output indices) restricts the
    work to a subset (for tests and timing); returns (len(texels), C) then, else (H_out, W_out, C).
    """
    ow, oh = _check(out_size, normalize)
    idx = np.arange(ow * oh) if texels is None else texels
    out = bruteforce_texels(bruteforce_inputs(hdr), (ow, oh), idx, normalize)
    return out.reshape(oh, ow, -1) if texels is None else out


def sh9_coefficients(hdr: np.ndarray) -> np.ndarray:
    """(9, C) float64 SH coefficients ``sum L Y dOmega`` of an equirect frame (basis: envmap.sh)."""
    img = check_equirect(hdr, "sh9_coefficients").astype(np.float64)
    h, w, c = img.shape
    basis = sh_basis(pixel_directions(w, h), 3) * solid_angles(w, h)[..., None]
    return basis.reshape(-1, 9).T @ img.reshape(-1, c)


def sh9_irradiance_map(hdr: np.ndarray, out_size: tuple[int, int] = (32, 16)) -> np.ndarray:
    """(H_out, W_out, C) float32 diffuse map ``E(n) / pi`` from 9 SH coefficients (Ramamoorthi-Hanrahan)."""
    ow, oh = _check(out_size, "pi")
    coeffs = sh9_coefficients(hdr)
    return (irradiance_from_sh(coeffs, pixel_directions(ow, oh)) / np.pi).astype(np.float32)
