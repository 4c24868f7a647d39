"""Fast diffuse radiance maps: Algorithm 1 on an area average, by FFT along longitude, plus the brightest
texels from the full-resolution frame.

The operator is that of :func:`probeless.pano.diffuse.diffuse_map` (each input texel of an ``in_size`` area
average integrated with ``sub x sub`` exact-solid-angle sub-texels), evaluated two ways cheaper, and made
right where the area average is wrong:

* **Longitude is a shift.** The weights of output column ``j`` are those of column 0 moved by
  ``j * in_w / out_w`` input columns, so each output row is a circular cross-correlation along the input
  rows: one real FFT of the input, a batched product with the cached spectra of the ``out_h`` kernels
  (one per output row, ``out_h * in_h * (in_w / 2 + 1)`` complex values: 4 MiB at 64x32 from 256x128,
  where the dense weight matrix of ``diffuse_map`` is 64 MiB at 64x32 from 128x64), and an inverse FFT.
* **Bright texels exactly.** An area average spreads a small bright source over its texel, so a normal
  whose horizon cuts that texel sees too much or too little of it: on a studio panorama the relative error
  of dark texels reaches 9.6 % with a 128x64 average. Here the ``hot`` input texels with the largest
  ``luminance x solid angle`` leave the average, and their full-resolution pixels are summed exactly
  (``solid angle * max(0, n . w)``, as the exact convolution). The split is exact (the map is linear in
  the frame); only the rest goes through the average, and the rest has no bright source left.

The frame must be a whole multiple of ``in_size`` for the hot texels' pixels to be theirs; another size
is first area-averaged to the largest multiple it holds (said in :func:`plan`). Normalisation as
``diffuse_map``: by the weight sum (the paper's, ``"weights"``) or by pi.
"""

from __future__ import annotations

import functools
import logging

import cv2
import numpy as np

from probeless.errors import ProbelessError
from probeless.pano.diffuse import _check
from probeless.pano.diffuse_kernels import cosine_sums
from probeless.pano.equirect import check_equirect, pixel_directions, solid_angles

IN_SIZE = (256, 128)  # the area average [W, H]
HOT_TEXELS = 64       # input texels summed from the full-resolution frame
SUB = 4               # sub-texels per input texel side for the averaged part's weights
LUMA = np.array([0.2126, 0.7152, 0.0722], np.float32)
WARN_ERROR = 0.01     # warn when the error estimate of the averaged part exceeds this (relative)

log = logging.getLogger(__name__)


@functools.lru_cache(maxsize=8)
def kernels(out_size: tuple[int, int], in_size: tuple[int, int], sub: int = SUB) -> tuple[np.ndarray, np.ndarray]:
    """(spectra (F, out_h, in_h) complex64: conj(rfft) of each output row's column-0 weights along the input
    columns, F = in_w / 2 + 1; weight sums (out_h,) float64) of the averaged part (module doc)."""
    (ow, oh), (iw, ih) = out_size, in_size
    normals = pixel_directions(ow, oh)[:, 0]  # (oh, 3): column 0 of each output row
    fine = pixel_directions(iw * sub, ih * sub) * solid_angles(iw * sub, ih * sub)[..., None]
    fine = fine.reshape(ih, sub, iw, sub, 3).transpose(0, 2, 1, 3, 4).reshape(ih, iw, sub * sub, 3)
    area = np.linalg.norm(fine, axis=-1)
    unit = fine / area[..., None]
    kern = np.zeros((oh, ih, iw))
    for k in range(sub * sub):
        kern += np.maximum(np.einsum("tc,hwc->thw", normals, unit[:, :, k]), 0.0) * area[:, :, k]
    spectra = np.conj(np.fft.rfft(kern, axis=2)).transpose(2, 0, 1)
    return np.ascontiguousarray(spectra.astype(np.complex64)), kern.sum(axis=(1, 2))


@functools.lru_cache(maxsize=8)
def frame_geometry(width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """(directions (H, W, 3) float32, solid angles (H, W) float32) of a full-resolution frame's pixels."""
    return pixel_directions(width, height).astype(np.float32), solid_angles(width, height).astype(np.float32)


@functools.lru_cache(maxsize=8)
def output_normals(out_size: tuple[int, int]) -> np.ndarray:
    """(3, out_h * out_w) float32 directions of the output texels, one row per axis."""
    return np.ascontiguousarray(pixel_directions(*out_size).reshape(-1, 3).T.astype(np.float32))


def plan(frame_size: tuple[int, int], in_size: tuple[int, int]) -> tuple[tuple[int, int], int]:
    """(the frame size the method works on, its pixels per input texel side) for a ``frame_size`` frame."""
    (w, h), (iw, ih) = frame_size, in_size
    f = max(1, min(w // iw, h // ih))
    return (iw * f, ih * f), f


def averaged_part(small: np.ndarray, out_size: tuple[int, int]) -> np.ndarray:
    """(out_h, out_w, C) float64 un-normalised cosine sums of the area average ``small`` (FFT along rows)."""
    ih, iw, c = small.shape
    ow = out_size[0]
    spectra, _ = kernels(tuple(out_size), (iw, ih))
    spec = np.fft.rfft(small, axis=1).transpose(1, 0, 2).astype(np.complex64)  # (F, ih, C)
    corr = np.fft.irfft(np.matmul(spectra, spec), n=iw, axis=0)  # (iw, oh, C)
    return corr[::iw // ow].transpose(1, 0, 2).astype(np.float64)


def hot_part(img: np.ndarray, hot: np.ndarray, f: int, out_size: tuple[int, int]) -> np.ndarray:
    """(out_h, out_w, C) float64 exact cosine sums of the full-resolution pixels of the input texels ``hot``
    (flat indices into the in_size grid, each ``f x f`` pixels of ``img``)."""
    h, w, c = img.shape
    iw = w // f
    rows, cols = np.divmod(hot, iw)
    r = (rows[:, None, None] * f + np.arange(f)[None, :, None]).repeat(f, axis=2).reshape(-1)
    q = (cols[:, None, None] * f + np.arange(f)[None, None, :]).repeat(f, axis=1).reshape(-1)
    dirs, omega = frame_geometry(w, h)
    ow, oh = out_size
    sums = cosine_sums(output_normals(tuple(out_size)), np.ascontiguousarray(dirs[r, q]),
                       np.ascontiguousarray(omega[r, q]), np.ascontiguousarray(img[r, q], np.float32))
    return sums.reshape(oh, ow, c)


def diffuse_map_fast(hdr: np.ndarray, out_size: tuple[int, int] = (32, 16), in_size: tuple[int, int] = IN_SIZE,
                     hot_texels: int = HOT_TEXELS, normalize: str = "weights") -> np.ndarray:
    """(H_out, W_out, C) float32 diffuse radiance map of the equirect ``hdr`` (H, 2H, C) (module doc)."""
    ow, oh = _check(out_size, normalize)
    iw, ih = (int(s) for s in in_size)
    if iw != 2 * ih or iw % ow:
        raise ProbelessError(f"diffuse_map_fast: in_size must be (2H, H) and a multiple of out_size, got "
                             f"{in_size} for {out_size}")
    img = check_equirect(hdr, "diffuse_map_fast").astype(np.float32, copy=False)
    while iw > img.shape[1] and (iw // 2) % ow == 0:  # a frame smaller than in_size: average less
        iw, ih = iw // 2, ih // 2
    size, f = plan((img.shape[1], img.shape[0]), (iw, ih))
    if size != (img.shape[1], img.shape[0]):
        img = cv2.resize(img, size, interpolation=cv2.INTER_AREA)
    small = cv2.resize(img, (iw, ih), interpolation=cv2.INTER_AREA) if f > 1 else img.copy()
    if small.ndim == 2:
        small = small[..., None]
        img = img[..., None]
    acc = np.zeros((oh, ow, small.shape[2]))
    luminance = small @ LUMA if small.shape[2] == 3 else small.mean(axis=2)
    energy = (luminance * frame_geometry(iw, ih)[1]).reshape(-1)
    n_hot = min(max(int(hot_texels), 0), iw * ih)
    if n_hot > 0:
        hot = np.argpartition(energy, -n_hot)[-n_hot:]
        small.reshape(-1, small.shape[2])[hot] = 0.0
        energy[hot] = 0.0
        acc += hot_part(img, hot, f, (ow, oh))
    acc += averaged_part(small, (ow, oh))
    _check_rest(acc, energy, ih, n_hot)
    wsum = kernels((ow, oh), (iw, ih))[1][:, None, None]
    return (acc / (wsum if normalize == "weights" else np.pi)).astype(np.float32)


def _check_rest(acc: np.ndarray, energy: np.ndarray, in_h: int, n_hot: int) -> None:
    """Warn when the brightest texel left in the average could move the darkest output by more than
    :data:`WARN_ERROR`: a horizon through it weighs its parts by up to its angular size (pi / in_h) apart."""
    darkest = float((acc @ LUMA if acc.shape[2] == 3 else acc.mean(axis=2)).min())
    estimate = float(energy.max()) * np.pi / in_h / darkest if darkest > 0 else 0.0
    if estimate > WARN_ERROR:
        log.warning("diffuse_map_fast: %d hot texels summed exactly, but the brightest texel left in the %d-row "
                    "average may still move the darkest output texel by about %.1f %% (> %.0f %%): raise "
                    "hot_texels or in_size", n_hot, in_h, 100 * estimate, 100 * WARN_ERROR)
