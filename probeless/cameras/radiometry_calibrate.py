"""Radiometric calibration as pure functions: the inverse response curve from an exposure stack, vignetting and
white balance from a flat field (what ``probeless calibrate response|vignetting`` run; docs/cameras/radiometry.md).

Response (:func:`calibrate_response`): Debevec & Malik (SIGGRAPH 1997) on every sampled pixel of the stack rather
than OpenCV's ``createCalibrateDebevec``'s 70 (the pixels' log irradiances are eliminated, so the system is 256 x 256
whatever the pixel count), codes read by interpolation so that several frames per exposure can be averaged first
(:func:`average_frames`: less noise; their spread says which samples the noise biases), normalised to 1 at code 255
(the curve is known up to scale; 1 = full well). Without the smoothness term the table has a saw-tooth of a few per
cent where codes quantise alike at every exposure (OpenCV's Robertson shows it too).

Vignetting and white balance (:func:`calibrate_flat_field`): a flat field (uniform radiance over the field of view)
linearised by the inverse response is ``A_c V(r)``; ``V = 1 + k1 r^2 + k2 r^4 + k3 r^6`` with ``r`` the distance from
the centre (fitted unless given) in units of half the diagonal between the corner pixels' centres (the rig's model,
probeless.scene.sensor_effects.vignetting_map); the white-balance gains are ``A_c / A_green`` (the flat field must be
neutral: white or grey).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from probeless.errors import CalibrationError

CODES = 256
MIN_PIXELS = 500   # fewest usable pixels per channel for either fit
MIN_SAMPLES = 50   # a code counts as measured with this many (interpolation-weighted) samples
SMOOTHNESS = 3.0   # Debevec-Malik lambda, per sqrt(samples per code)
SNR_MIN = 20.0     # a noisy sample counts where its code is >= this many times its frame-to-frame std


def hat_weights(lo: float = 2.0, hi: float = 254.0) -> np.ndarray:
    """(256,) Debevec-Malik hat weights, 0 at and outside [``lo``, ``hi``] (noise-bound and clipped codes)."""
    z = np.arange(CODES, dtype=np.float64)
    return np.clip(np.minimum(z - lo, hi - z) / (0.5 * (hi - lo)), 0.0, 1.0)


def log_second_differences() -> np.ndarray:
    """(253, 256) second differences of g over ln z (codes 2..254; rows scaled to the plain second difference where
    codes are dense): a power law, linear in ln z, costs nothing, so the smoothing does not bend the dark end of a
    gamma curve as second differences over z do."""
    x = np.log(np.arange(1, CODES, dtype=np.float64))  # x[i - 1] = ln i
    D = np.zeros((CODES - 3, CODES))
    for row, i in enumerate(range(2, CODES - 1)):
        h1, h2 = x[i - 1] - x[i - 2], x[i] - x[i - 1]
        hbar = 0.5 * (h1 + h2)
        D[row, i - 1], D[row, i], D[row, i + 1] = hbar / h1, -hbar / h1 - hbar / h2, hbar / h2
    return D / np.abs(D[-1, CODES - 2]) * 2.0


def debevec_log_response(codes: np.ndarray, exposures, *, usable: np.ndarray | None = None,
                         smoothness: float = SMOOTHNESS, lo: float = 2.0,
                         hi: float = 254.0) -> tuple[np.ndarray, np.ndarray]:
    """(g (256,) = ln f^-1 of one channel up to a constant, 0 at code 128; samples (256,) per code) by Debevec and
    Malik's least squares ``w (g(z_ij) - ln E_i - ln t_j) = 0`` on every pixel, with a second-difference term of
    weight ``smoothness^2 * samples / 256`` over ln z (:func:`log_second_differences`). ``codes`` (J, P): P pixels
    at J exposures; a fractional code (the mean of several frames) reads g by linear interpolation. The pixels'
    ``ln E_i`` are eliminated (Schur complement), leaving a 256 x 256 system. ``usable`` (J, P) bool: the samples
    to use (default all)."""
    from scipy import sparse

    z = np.clip(np.asarray(codes, np.float64), 0, CODES - 1)
    n_pix = z.shape[1]
    w = np.interp(z, np.arange(CODES), hat_weights(lo, hi))
    if usable is not None:
        w = np.where(usable, w, 0.0)
    jj, pp = np.nonzero(w > 0)
    n = len(jj)
    base = np.minimum(np.floor(z[jj, pp]).astype(np.int64), CODES - 2)
    frac, ww, rows = z[jj, pp] - base, w[jj, pp], np.arange(n)
    samples = np.bincount(base, 1 - frac, CODES) + np.bincount(base + 1, frac, CODES)
    if np.count_nonzero(samples >= MIN_SAMPLES) < 16:
        raise CalibrationError(f"only {np.count_nonzero(samples >= MIN_SAMPLES)} code value(s) are well exposed in "
                               "the stack: take exposures from dark to nearly clipped in steps of 1 stop or less, of a "
                               "scene with many brightness levels")
    Ag = sparse.csr_matrix((np.concatenate([ww * (1 - frac), ww * frac]),
                            (np.concatenate([rows, rows]), np.concatenate([base, base + 1]))), shape=(n, CODES))
    Ae = sparse.csr_matrix((-ww, (rows, pp)), shape=(n, n_pix))
    y = ww * np.log(np.asarray(exposures, np.float64))[jj]
    B = (Ag.T @ Ae).tocsr()
    d = np.bincount(pp, ww * ww, n_pix)
    dinv = np.where(d > 0, 1.0 / np.maximum(d, 1e-300), 0.0)
    S = (Ag.T @ Ag).toarray() - (B @ sparse.diags(dinv) @ B.T).toarray()
    rhs = Ag.T @ y - B @ (dinv * (Ae.T @ y))
    D = log_second_differences()
    S += smoothness ** 2 * (n / CODES) * (D.T @ D)
    S[128, 128] += 1e6 * max(n / CODES, 1.0)  # gauge: g(128) = 0
    S[0, 0] += 1.0  # code 0 (ln 0) is outside the smoothing; unused (f^-1(0) = 0)
    return np.linalg.solve(S, rhs), samples


def normalise_at_255(g: np.ndarray, top: tuple[int, int] = (200, 250)) -> np.ndarray:
    """(256,) inverse response ``exp(g)`` scaled to 1 at code 255 by the local power law ``g = a + b ln z`` fitted on
    codes ``top`` (code 255 itself is every signal at or above full well: its samples say little); exactly 1 at 255 and
    0 at code 0."""
    z = np.arange(top[0], top[1] + 1)
    b, a = np.polyfit(np.log(z), g[z], 1)
    inv = np.minimum(np.exp(g - (a + b * np.log(255.0))), 1.0)
    inv[0], inv[255] = 0.0, 1.0
    return inv


def power_law_below(inverse: np.ndarray, z0: int) -> np.ndarray:
    """``inverse`` with codes 1..``z0`` - 1 (below any well-measured sample) extrapolated by the local power law
    at ``z0`` (monotonic, whatever the few noisy samples below ``z0`` did to the fit)."""
    out = inverse.copy()
    if z0 <= 2:
        return out
    slope = (np.log(inverse[z0 + 2]) - np.log(inverse[z0])) / (np.log(z0 + 2) - np.log(z0))
    z = np.arange(1, z0)
    out[1:z0] = inverse[z0] * (z / z0) ** max(slope, 1e-3)
    return out


@dataclass
class ResponseFit:
    """Inverse responses (3, 256) normalised to 1 at 255, and what went into them."""

    inverse: np.ndarray
    pixels: int
    exposures: int
    valid_codes: tuple[int, int]   # first..last code with MIN_SAMPLES usable samples in every channel; outside:
    #                                extrapolated (below: the power law at the first)
    notes: list[str] = field(default_factory=list)


def calibrate_response(images: list[np.ndarray], exposures: list[float], *, noise: list[np.ndarray] | None = None,
                       max_pixels: int = 5000, smoothness: float = SMOOTHNESS, lo: float = 2.0, hi: float = 254.0,
                       seed: int = 0) -> ResponseFit:
    """Inverse response per channel from a static exposure stack: ``images`` (H, W, 3) uint8 or averaged float
    codes, one per entry of ``exposures`` (several frames at one exposure: average them first, see
    :func:`average_frames`). At most ``max_pixels`` pixels (a fixed random subset) are used.

    ``noise``: the frame-to-frame std of each image's codes (:func:`average_frames`); a sample is then used only
    where it is at least ``SNR_MIN`` times its noise: averaging codes of noisy frames is biased (the curve is not
    linear, and 0 clips), by about ``gamma (gamma - 1) / 2 (std / code)^2`` in linear terms: 0.3 % for gamma 2.2 there.
    Without it, codes the sensor's noise dominates bend the whole fit (take >= 4 frames per exposure)."""
    if len(images) != len(exposures):
        raise CalibrationError(f"{len(images)} image(s) but {len(exposures)} exposure(s)")
    t = np.asarray(exposures, np.float64)
    if len(np.unique(t)) < 3:
        raise CalibrationError(f"a response needs at least 3 different exposures, got {len(np.unique(t))}")
    if not (np.isfinite(t).all() and (t > 0).all()):
        raise CalibrationError("exposures must be finite and > 0")
    shapes = {im.shape for im in images}
    if len(shapes) != 1 or len(next(iter(shapes))) != 3 or next(iter(shapes))[2] != 3:
        raise CalibrationError(f"the images must all be (H, W, 3) of one size, got {sorted(shapes)}")
    stack = np.stack([np.asarray(im, np.float64).reshape(-1, 3) for im in images])  # (J, P, 3)
    seen = np.any(stack > 0.5, axis=(0, 2))  # drop pixels black in every frame (outside the image circle)
    idx = np.flatnonzero(seen)
    if len(idx) < MIN_PIXELS:
        raise CalibrationError(f"only {len(idx)} pixel(s) are not black in every frame; need {MIN_PIXELS}")
    if len(idx) > max_pixels:
        idx = np.sort(np.random.default_rng(seed).choice(idx, max_pixels, replace=False))
    usable = None
    if noise is not None:
        sd = np.stack([np.asarray(n, np.float64).reshape(-1, 3) for n in noise])[:, idx]
        usable = stack[:, idx] >= SNR_MIN * sd
    fits = [debevec_log_response(stack[:, idx, c], t, usable=None if usable is None else usable[..., c],
                                 smoothness=smoothness, lo=lo, hi=hi) for c in range(3)]
    sampled = [np.flatnonzero(count >= MIN_SAMPLES) for _, count in fits]
    if any(len(s) < 16 for s in sampled):
        raise CalibrationError(f"fewer than 16 code values have {MIN_SAMPLES} usable samples in some channel: "
                               "take more exposures or frames, of a scene with many brightness levels")
    valid = (int(max(s[0] for s in sampled)), int(min(s[-1] for s in sampled)))
    inverse = np.stack([power_law_below(normalise_at_255(g), valid[0]) for g, _ in fits])
    notes = []
    if usable is not None:
        lit = stack[:, idx] > 0.5
        dropped = int(np.count_nonzero(lit & ~usable))
        notes.append(f"{dropped} of {int(np.count_nonzero(lit))} samples left out: their code is under {SNR_MIN:g} "
                     f"times their frame-to-frame noise (averaging would bias them)")
    if valid[0] > 16 or valid[1] < 240:
        notes.append(f"only codes {valid[0]}..{valid[1]} are measured: outside them the curve is extrapolated "
                     "(add darker or brighter exposures; at the dark end the sensor's noise may be the limit)")
    if np.any(np.diff(inverse[:, valid[0]:valid[1] + 1], axis=1) <= 0):
        notes.append("the fitted inverse response is not increasing everywhere: the stack may have too few "
                     "well-exposed pixels at some codes (add exposures or frames)")
    return ResponseFit(inverse, len(idx), len(t), valid, notes)


def average_frames(images: list[np.ndarray], exposures: list[float]):
    """(mean codes, per-frame temporal std of the codes or None, exposures): frames with equal exposure averaged
    (float codes, less noise), in increasing exposure. The std is None unless every exposure has >= 2 frames."""
    t = np.asarray(exposures, np.float64)
    means, stds, out_t = [], [], []
    for e in np.unique(t):
        sel = np.stack([np.asarray(images[i], np.float64) for i in np.flatnonzero(t == e)])
        means.append(sel.mean(axis=0))
        stds.append(sel.std(axis=0, ddof=1) if len(sel) > 1 else None)
        out_t.append(float(e))
    return means, (None if any(s is None for s in stds) else stds), out_t


def linearise(codes: np.ndarray, inverse: np.ndarray) -> np.ndarray:
    """(H, W, 3) linear signal (1 = full well) of (fractional) codes through the (3, 256) inverse response."""
    codes = np.asarray(codes, np.float64)
    return np.stack([np.interp(codes[..., c], np.arange(CODES), inverse[c]) for c in range(3)], axis=-1)


def vignetting_factor(r2: np.ndarray, coeffs) -> np.ndarray:
    """``1 + k1 r^2 + k2 r^4 + k3 r^6`` at squared radii ``r2``."""
    return 1.0 + sum(k * r2 ** (i + 1) for i, k in enumerate(coeffs))


@dataclass
class FlatFieldFit:
    """Vignetting (poly coefficients, centre) and white-balance gains relative to green of a flat field."""

    coeffs: np.ndarray
    center: tuple[float, float]
    gains: np.ndarray
    width: int
    height: int
    pixels: int
    rms: float           # RMS relative residual of the fit [-]
    notes: list[str] = field(default_factory=list)


def calibrate_flat_field(images: list[np.ndarray], inverse: np.ndarray, *, terms: int = 3,
                         center: tuple[float, float] | None = None, lo: float = 20.0, hi: float = 235.0,
                         max_pixels: int = 40000, seed: int = 0) -> FlatFieldFit:
    """Vignetting and white balance from flat-field frames (uint8 or float codes, (H, W, 3), one exposure) and the
    (3, 256) inverse response: pixels with every channel's code in [``lo``, ``hi``] are fitted (least squares on the
    relative residual), the centre too unless given."""
    from scipy.optimize import least_squares

    if not 1 <= terms <= 3:
        raise CalibrationError(f"vignetting takes 1 to 3 terms (k1 r^2 .. k3 r^6), got {terms}")
    codes = np.mean([np.asarray(im, np.float64) for im in images], axis=0)
    if codes.ndim != 3 or codes.shape[2] != 3:
        raise CalibrationError(f"flat-field images must be (H, W, 3), got {codes.shape}")
    h, w = codes.shape[:2]
    ok = np.all((codes >= lo) & (codes <= hi), axis=-1)
    v, u = np.nonzero(ok)
    if len(v) < MIN_PIXELS:
        raise CalibrationError(f"only {len(v)} flat-field pixel(s) have codes in [{lo:g}, {hi:g}] in every channel; "
                               f"need {MIN_PIXELS}: change the exposure so the field is neither dark nor clipped")
    if len(v) > max_pixels:
        keep = np.random.default_rng(seed).choice(len(v), max_pixels, replace=False)
        v, u = v[keep], u[keep]
    lin = linearise(codes[v, u], inverse)  # (N, 3)
    norm = 0.25 * ((w - 1) ** 2 + (h - 1) ** 2)
    c0 = ((w - 1) / 2, (h - 1) / 2) if center is None else center

    def residual(p):
        cx, cy = (p[:2] if center is None else center)
        ks = p[-terms:]
        amps = p[-terms - 3:-terms]
        r2 = ((u - cx) ** 2 + (v - cy) ** 2) / norm
        model = vignetting_factor(r2, ks)[:, None] * amps[None, :]
        return (model / lin - 1.0).ravel()

    p0 = np.concatenate([[] if center is not None else c0, np.median(lin, axis=0), np.zeros(terms)])
    fit = least_squares(residual, p0, x_scale="jac")
    cx, cy = (fit.x[:2] if center is None else center)
    amps, ks = fit.x[-terms - 3:-terms], fit.x[-terms:]
    notes = []
    r2 = ((u - cx) ** 2 + (v - cy) ** 2) / norm
    if r2.max() < 0.25:
        notes.append(f"the usable pixels reach only r = {np.sqrt(r2.max()):.2f} (of the half diagonal): the fit is "
                     "an extrapolation beyond it")
    return FlatFieldFit(np.asarray(ks), (float(cx), float(cy)), amps / amps[1], w, h, len(v),
                        float(np.sqrt(np.mean(fit.fun ** 2))), notes)
