"""Image errors of lit spheres against the true-HDR ones, and which lighting map wins.

Per object (the pixels of all views together, linear camera units, ``ref`` = the true-HDR spheres):

* ``rel_rmse``: ``||est - ref|| / ||ref||`` over pixels and channels;
* ``psnr``: PSNR [dB] after display encoding of both (clip to 0..1, sRGB), peak 1, from the
  display ``mse`` (infinite where both saturate to the same white);
* ``scale``: the least-squares ``s = <est, ref> / <est, est>``, fitted per object image;
  ``rel_rmse_scaled`` is the relative RMSE of ``s * est``: the shape of the lighting with its (for
  most ITMOs arbitrary) overall level taken out.

:func:`winners` ranks the maps per object and metric.
"""

from __future__ import annotations

import numpy as np

from probeless.color import linear_to_srgb

METRICS = {"rel_rmse": "min", "rel_rmse_scaled": "min", "psnr": "max"}  # metric -> which is better


def display(linear: np.ndarray) -> np.ndarray:
    """Linear camera values to display values 0..1: clipped, sRGB-encoded."""
    return linear_to_srgb(np.clip(np.asarray(linear, np.float64), 0.0, 1.0))


def _rel(est: np.ndarray, ref: np.ndarray) -> float:
    den = float(np.sqrt(np.sum(ref * ref)))
    num = float(np.sqrt(np.sum((est - ref) ** 2)))
    return num / den if den > 0 else (0.0 if num == 0 else float("inf"))


def image_errors(est: np.ndarray, ref: np.ndarray) -> dict[str, float]:
    """The errors of the module doc for (..., 3) radiance ``est`` against ``ref`` of the same shape."""
    e = np.asarray(est, np.float64).reshape(-1, 3)
    r = np.asarray(ref, np.float64).reshape(-1, 3)
    ee = float(np.sum(e * e))
    s = float(np.sum(e * r)) / ee if ee > 0 else 0.0
    mse = float(np.mean((display(e) - display(r)) ** 2))
    return {"rel_rmse": _rel(e, r), "psnr": _psnr(mse), "mse": mse, "scale": s, "rel_rmse_scaled": _rel(s * e, r)}


def _psnr(mse: float) -> float:
    return float("inf") if mse == 0 else float(10.0 * np.log10(1.0 / mse))


def rank(values: dict[str, float], sense: str, baseline: str = "ldr") -> dict:
    """The best of ``values`` (map -> metric; ``sense`` "min" or "max"), the runner-up and the margins.

    Margins are ratios (``other / best``, >= 1) for "min" metrics (relative RMSEs) and differences
    (``best - other`` in dB, >= 0) for "max" ones (PSNRs).
    """
    ranked = sorted(values, key=values.get, reverse=sense == "max")
    best = ranked[0]
    second = ranked[1] if len(ranked) > 1 else best

    def margin(other: str) -> float:
        a, b = values[best], values[other]
        if a == b:  # ties, infinite PSNRs included
            return 0.0 if sense == "max" else 1.0
        if sense == "max":
            return a - b
        return b / a if a > 0 else float("inf")

    return {"best": best, "value": values[best], "runner_up": second, "margin_over_runner_up": margin(second),
            f"margin_over_{baseline}": margin(baseline) if baseline in values else float("nan"), "ranking": ranked}


def winners(errors: dict[str, dict[str, dict[str, float]]]) -> dict[str, dict[str, dict]]:
    """``[object][metric]`` -> :func:`rank` of the maps, from ``errors[map][object][metric]``."""
    objects = next(iter(errors.values())).keys()
    return {o: {k: rank({m: errors[m][o][k] for m in errors}, sense) for k, sense in METRICS.items()}
            for o in objects}


def mean_errors(runs: list[dict[str, dict[str, dict[str, float]]]]) -> dict[str, dict[str, dict[str, float]]]:
    """``[map][object]`` errors averaged over several panoramas' ``runs``; the PSNR of the mean MSE."""
    def mean(m: str, o: str) -> dict[str, float]:
        out = {k: float(np.mean([r[m][o][k] for r in runs])) for k in ("rel_rmse", "rel_rmse_scaled", "mse")}
        return {**out, "psnr": _psnr(out["mse"])}

    return {m: {o: mean(m, o) for o in runs[0][m]} for m in runs[0]}
