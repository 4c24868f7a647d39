"""Exposure matching of an uncalibrated HDR photo to an LDR point cloud (paper 001, §4.1, Eq. 1).

The photo ``I_HDR`` is radiance in unknown units; the cloud's colours are linear LDR values 0..1. We
look for the exposure ``alpha`` such that ``I_LDR = clamp(alpha * I_HDR, 0, 1)`` has the CIE-Y
histogram (128 bins on [0, 1]) closest, by the 1-D Wasserstein distance, to the whole cloud's:

1. a fixed set of exposures one stop apart (see :func:`fixed_exposures`),
2. the one whose histogram is closest to the cloud's,
3. a binary search of ``alpha`` between that exposure's two neighbours (see :func:`match_exposure`).

Everything is linear (Rec.709 / sRGB primaries): decode the cloud's 8-bit sRGB codes first
(:func:`probeless.color.from_srgb8`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import wasserstein_distance

from probeless.color import REC709_Y, luminance  # noqa: F401 (luminance: re-exported)
from probeless.errors import HdrError

BINS = 128
"""Histogram bins of the paper (§4.1)."""


def _rgb(a, what: str, *, image: bool = False) -> np.ndarray:
    """float32 copy-free view of ``a`` checked: (..., 3) ((H, W, 3) if ``image``), non-empty, finite, >= 0."""
    a = np.asarray(a)
    if a.ndim < 2 or a.shape[-1] != 3 or (image and a.ndim != 3):
        want = "(H, W, 3)" if image else "(N, 3)"
        raise HdrError(f"{what}: expected an {want} RGB array, got shape {a.shape}")
    if a.size == 0:
        raise HdrError(f"{what}: is empty (shape {a.shape})")
    if not np.issubdtype(a.dtype, np.number) or np.iscomplexobj(a):
        raise HdrError(f"{what}: expected real numbers, got dtype {a.dtype}")
    a = a.astype(np.float32, copy=False)
    if not np.isfinite(a).all():
        raise HdrError(f"{what}: has {int((~np.isfinite(a)).sum())} NaN or infinite values")
    if (a < 0).any():
        raise HdrError(f"{what}: has {int((a < 0).sum())} negative values (min {float(a.min()):g})")
    return a


def bin_centres(bins: int = BINS) -> np.ndarray:
    """(bins,) float64 centres of ``bins`` equal bins on [0, 1]."""
    return (np.arange(bins, dtype=np.float64) + 0.5) / bins


def luminance_histogram(y: np.ndarray, bins: int = BINS) -> np.ndarray:
    """(bins,) float64 histogram of luminances ``y`` (any shape) on [0, 1], normalised to sum 1.

    Values are clipped to [0, 1] first (1.0 falls in the last bin). An empty ``y`` raises HdrError.
    """
    y = np.asarray(y, dtype=np.float64).ravel()
    if y.size == 0:
        raise HdrError("luminance_histogram: no values")
    if bins < 1:
        raise HdrError(f"luminance_histogram: bins must be >= 1, got {bins}")
    idx = np.minimum((np.clip(y, 0.0, 1.0) * bins).astype(np.int64), bins - 1)
    h = np.bincount(idx, minlength=bins).astype(np.float64)
    return h / h.sum()


def histogram_distance(h1: np.ndarray, h2: np.ndarray) -> float:
    """Wasserstein-1 distance (luminance units) between two histograms on the same [0, 1] bins."""
    c = bin_centres(len(h1))
    return float(wasserstein_distance(c, c, h1, h2))


def expose(hdr_image: np.ndarray, alpha: float) -> np.ndarray:
    """Eq. 1: ``clamp(alpha * I_HDR, 0, 1)`` as float32, same shape."""
    return np.clip(np.asarray(hdr_image, np.float32) * np.float32(alpha), 0.0, 1.0)


def fixed_exposures(hdr_image: np.ndarray, bins: int = BINS) -> np.ndarray:
    """Exposures ``2^k`` (one stop apart, increasing) that span every histogram the photo can give.

    Exposure fusion [MKR07] works on a bracketed stack one stop apart; our stack is
    ``k = floor(log2(1 / (bins * Ymax))) .. ceil(log2(1 / Ymin))`` with ``Ymax`` / ``Ymin`` the
    largest / smallest positive luminance of the photo. Below the first, the whole image falls in
    the histogram's first bin; above the last, every non-black pixel clips to 1: further exposures
    could only repeat a histogram. (A black photo raises HdrError.)
    """
    y = luminance(hdr_image)
    pos = y[y > 0]
    if pos.size == 0:
        raise HdrError("fixed_exposures: the HDR photo is black (no positive luminance)")
    k_lo = math.floor(math.log2(1.0 / (bins * float(pos.max()))))
    k_hi = max(math.ceil(math.log2(1.0 / float(pos.min()))), k_lo + 1)
    return np.exp2(np.arange(k_lo, k_hi + 1, dtype=np.float64))


@dataclass(frozen=True)
class ExposureMatch:
    """Result of :func:`match_exposure`.

    ``alpha``: the exposure (``I_LDR = clamp(alpha * I_HDR, 0, 1)``); ``ldr_image``: that
    ``I_LDR``, (H, W, 3) float32; ``distance``: its histogram's Wasserstein distance to the cloud's
    (luminance units); ``steps``: binary-search steps taken; ``candidates``: (K, 2) float64 rows
    ``(alpha, distance)`` of the fixed exposures.
    """

    alpha: float
    ldr_image: np.ndarray
    distance: float
    steps: int
    candidates: np.ndarray

    def as_dict(self) -> dict:
        """JSON-ready summary (no image)."""
        return {"alpha": self.alpha, "distance": self.distance, "steps": self.steps,
                "candidates": self.candidates.tolist()}


def match_exposure(hdr_image: np.ndarray, cloud_rgb_linear: np.ndarray, exposures=None, max_steps: int = 50,
                   *, bins: int = BINS, rtol: float = 1e-9, xtol: float = 1e-4) -> ExposureMatch:
    """Exposure of the HDR photo whose clamped CIE-Y histogram best matches the cloud's (§4.1).

    ``hdr_image``: (H, W, 3) linear radiance >= 0, any units; ``cloud_rgb_linear``: (N, 3) linear
    LDR colours of the whole cloud, 0..1. ``exposures``: the fixed set to try (default
    :func:`fixed_exposures`). The best fixed exposure ``a_k`` is refined in ``[a_{k-1}, a_{k+1}]``
    (the end exposure itself where ``a_k`` is first or last) by a binary search in ``log(alpha)``:
    each step tries the two midpoints between the best so far and the ends of its bracket, moves to
    the better one if it lowers the distance, and halves the bracket around the best. The paper stops
    "when the error stops decreasing" or after 50 steps. A step without a decrease is no sign of
    convergence (the distance is V-shaped around its minimum, so both midpoints overshoot until the
    bracket is narrower than twice the offset of the minimum), so "stops decreasing" is read as "stops
    changing": we stop when both midpoints give the best distance again (relative ``rtol``: the
    histograms no longer see the change), when the distance is 0, when the bracket is narrower than
    ``xtol`` stops, or after ``max_steps`` steps. The distance returned is never above the best fixed
    exposure's.
    """
    img = _rgb(hdr_image, "hdr_image", image=True)
    cloud = _rgb(cloud_rgb_linear, "cloud_rgb_linear")
    if float(cloud.max()) > 1.0 + 1e-6:
        raise HdrError(f"cloud_rgb_linear: LDR colours must be in 0..1, max is {float(cloud.max()):g}")
    if max_steps < 0:
        raise HdrError(f"match_exposure: max_steps must be >= 0, got {max_steps}")
    alphas = fixed_exposures(img, bins) if exposures is None else np.sort(np.asarray(exposures, np.float64).ravel())
    if alphas.size == 0 or not np.isfinite(alphas).all() or (alphas <= 0).any():
        raise HdrError(f"exposures: expected positive finite values, got {alphas.tolist()}")

    target = luminance_histogram(luminance(cloud), bins)

    def dist(a: float) -> float:
        return histogram_distance(luminance_histogram(luminance(expose(img, a)), bins), target)

    d_fixed = np.array([dist(a) for a in alphas])
    k = int(np.argmin(d_fixed))
    best, d_best = math.log(alphas[k]), float(d_fixed[k])
    lo = math.log(alphas[max(k - 1, 0)])
    hi = math.log(alphas[min(k + 1, alphas.size - 1)])
    steps = 0
    while steps < max_steps and d_best > 0.0 and hi - lo > xtol * math.log(2.0):
        steps += 1
        trials = [x for x in (0.5 * (lo + best), 0.5 * (best + hi)) if lo < x < hi]
        scored = [(dist(math.exp(x)), x) for x in trials]
        if not scored:
            break
        d_new, x_new = min(scored)
        if d_new < d_best * (1.0 - rtol):
            lo, hi = (lo, best) if x_new < best else (best, hi)
            best, d_best = x_new, d_new
        elif all(abs(d - d_best) <= rtol * d_best for d, _ in scored):
            break
        else:
            lo, hi = 0.5 * (lo + best), 0.5 * (best + hi)
    alpha = math.exp(best)
    return ExposureMatch(alpha=alpha, ldr_image=expose(img, alpha), distance=d_best, steps=steps,
                         candidates=np.column_stack([alphas, d_fixed]))
