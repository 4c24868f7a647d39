"""The rigid transform between the RGB-D camera and the fisheye, from point matches (Levenberg-Marquardt).

``fisheye_from_rgbd`` maps RGB-D camera coordinates to fisheye camera coordinates,
p_f = R p_r + t. It is found, as in the paper, by minimising the fisheye reprojection error of
3-D points seen by the RGB-D camera (lifted with its depth) over the six pose parameters with
scipy's Levenberg-Marquardt (``least_squares(method="lm")``). LM cannot use a robust loss, so
outliers are rejected by re-solving: after each solve, matches whose residual exceeds
max(k, 5 x the median inlier residual) are dropped, until the inlier set stops changing.

The initial guess, unless given, is :func:`default_init`: the fisheye looking straight up from a
forward-looking RGB-D camera at the same position (rpy_deg = [-90, 0, 0], translation 0). Before
the pixel-space solve, one LM solve aligns the viewing directions (unit rays, always defined)
from that guess, so the pixel-space solve starts where every point projects validly.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from probeless.cameras.base import CameraModel, normalize_rows
from probeless.errors import CalibrationError
from probeless.geom.rotation import transform_from, transform_from_rpy

DEFAULT_INIT_RPY_DEG = (-90.0, 0.0, 0.0)
MIN_MATCHES = 6
_INVALID_PX = 1e3   # residual of a point outside the fisheye's domain (constant: no gradient)


@dataclass(frozen=True)
class ExtrinsicsReport:
    """How well the solved transform explains the matches."""

    rms_px: float        # reprojection RMS over the inliers [px]
    median_px: float     # median inlier residual [px]
    inliers: int         # matches kept
    matches: int         # matches given
    rounds: int          # outlier-rejection rounds (LM solves in pixel space)
    iterations: int      # residual evaluations of all LM solves (scipy's nfev)
    threshold_px: float  # final outlier threshold [px]

    def as_dict(self) -> dict:
        """Plain-Python fields (for YAML)."""
        return {k: (float(v) if isinstance(v, float) else int(v)) for k, v in asdict(self).items()}


def from_rpy(translation, rpy_deg) -> np.ndarray:
    """4x4 transform from translation [m] and rpy_deg (scipy ``from_euler('xyz', ..., degrees=True)``)."""
    return transform_from_rpy(translation, rpy_deg)


def to_rpy(T: np.ndarray) -> tuple[list[float], list[float]]:
    """(translation [m], rpy_deg) of a 4x4 transform, the inverse of :func:`from_rpy`."""
    rpy = Rotation.from_matrix(T[:3, :3]).as_euler("xyz", degrees=True)
    return [float(v) for v in T[:3, 3]], [float(v) for v in rpy]


def default_init() -> np.ndarray:
    """The coarse initial fisheye_from_rgbd: fisheye looking up, cameras at the same point."""
    return from_rpy((0.0, 0.0, 0.0), DEFAULT_INIT_RPY_DEG)


def rotation_error_deg(R_a: np.ndarray, R_b: np.ndarray) -> float:
    """Angle of the rotation R_a R_b^T [deg]."""
    return float(np.degrees(Rotation.from_matrix(R_a @ R_b.T).magnitude()))


def _pose(x: np.ndarray, R0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    # x = (rotation vector of the correction applied after R0, translation)
    return Rotation.from_rotvec(x[:3]).as_matrix() @ R0, x[3:]


def reprojection_errors(T: np.ndarray, points: np.ndarray, pixels: np.ndarray,
                        fisheye: CameraModel) -> np.ndarray:
    """(N,) pixel distance between ``fisheye.project(T p)`` and the matched pixels (inf if invalid)."""
    px, valid = fisheye.project(points @ T[:3, :3].T + T[:3, 3])
    err = np.linalg.norm(px - pixels, axis=1)
    err[~valid] = np.inf
    return err


def solve_fisheye_from_rgbd(points_rgbd: np.ndarray, pixels_fisheye: np.ndarray, fisheye: CameraModel,
                            init: np.ndarray | None = None, *, outlier_px: float = 3.0,
                            max_rounds: int = 10) -> tuple[np.ndarray, ExtrinsicsReport]:
    """Solve fisheye_from_rgbd (4x4) from (N, 3) RGB-D-frame points and their (N, 2) fisheye pixels.

    CalibrationError when fewer than MIN_MATCHES matches (or inliers) remain.
    """
    P = np.asarray(points_rgbd, dtype=np.float64).reshape(-1, 3)
    uv = np.asarray(pixels_fisheye, dtype=np.float64).reshape(-1, 2)
    if len(P) != len(uv):
        raise CalibrationError(f"extrinsics: {len(P)} points but {len(uv)} pixels")
    rays, usable = fisheye.unproject(uv)
    usable &= np.isfinite(P).all(axis=1)
    if usable.sum() < MIN_MATCHES:
        raise CalibrationError(f"extrinsics: {int(usable.sum())} usable matches, need at least {MIN_MATCHES}")
    T0 = default_init() if init is None else np.asarray(init, dtype=np.float64)
    R0, nfev = T0[:3, :3], 0

    def ray_residuals(x, idx):
        R, t = _pose(x, R0)
        return (normalize_rows(P[idx] @ R.T + t) - rays[idx]).ravel()

    def px_residuals(x, idx):
        R, t = _pose(x, R0)
        px, valid = fisheye.project(P[idx] @ R.T + t)
        r = px - uv[idx]
        r[~valid] = _INVALID_PX
        return r.ravel()

    x = np.concatenate([np.zeros(3), T0[:3, 3]])
    sol = least_squares(ray_residuals, x, method="lm", args=(np.flatnonzero(usable),))
    x, nfev = sol.x, nfev + sol.nfev
    inliers, threshold, rounds = usable.copy(), np.inf, 0
    while rounds < max_rounds:
        if inliers.sum() < MIN_MATCHES:
            raise CalibrationError(f"extrinsics: only {int(inliers.sum())} inliers within {threshold:.1f} px "
                                   f"of {len(P)} matches, need at least {MIN_MATCHES}")
        sol = least_squares(px_residuals, x, method="lm", x_scale="jac", args=(np.flatnonzero(inliers),))
        x, nfev, rounds = sol.x, nfev + sol.nfev, rounds + 1
        err = reprojection_errors(transform_from(*_pose(x, R0)), P, uv, fisheye)
        err[~usable] = np.inf
        threshold = max(outlier_px, 5.0 * float(np.median(err[inliers])))
        new = err <= threshold
        if np.array_equal(new, inliers):
            break
        inliers = new
    T = transform_from(*_pose(x, R0))
    e = err[inliers]
    report = ExtrinsicsReport(float(np.sqrt(np.mean(e * e))), float(np.median(e)), int(inliers.sum()), len(P),
                              rounds, int(nfev), float(threshold))
    return T, report


def save_extrinsics(path, T: np.ndarray, report: ExtrinsicsReport | None = None, extra: dict | None = None) -> None:
    """Write ``fisheye_from_rgbd: {translation, rpy_deg}`` (the scene-file form), the 4x4 matrix,
    the solver report and any ``extra`` keys as YAML."""
    import yaml

    translation, rpy = to_rpy(T)
    data = {"fisheye_from_rgbd": {"translation": translation, "rpy_deg": rpy},
            "fisheye_from_rgbd_matrix": np.asarray(T, dtype=np.float64).tolist()}
    if report is not None:
        data["report"] = report.as_dict()
    data.update(extra or {})
    with open(path, "w", encoding="utf-8") as f:
        yaml.safe_dump(data, f, sort_keys=False, default_flow_style=None)


def load_extrinsics(path) -> np.ndarray:
    """The 4x4 fisheye_from_rgbd of a file written by :func:`save_extrinsics` (or any YAML mapping
    with a ``fisheye_from_rgbd: {translation, rpy_deg}`` key, or a scene file's ``rig.fisheye_from_rgbd``: the true
    extrinsics of a synthetic rig, not an ``extends:`` base's); CalibrationError naming the key at fault."""
    import yaml

    try:
        with open(path, encoding="utf-8") as f:
            data = yaml.safe_load(f)
    except (OSError, yaml.YAMLError) as exc:
        raise CalibrationError(f"{path}: cannot read extrinsics: {exc}") from None
    block = data.get("fisheye_from_rgbd") if isinstance(data, dict) else None
    if block is None and isinstance(data, dict) and isinstance(data.get("rig"), dict):
        block = data["rig"].get("fisheye_from_rgbd")
    if not isinstance(block, dict):
        raise CalibrationError(f"{path}: key 'fisheye_from_rgbd' missing or not a mapping")
    try:
        t, rpy = (np.array(block[k], dtype=np.float64) for k in ("translation", "rpy_deg"))
    except (KeyError, TypeError, ValueError) as exc:
        raise CalibrationError(f"{path}: key 'fisheye_from_rgbd': needs translation and rpy_deg lists "
                               f"({exc})") from None
    if t.shape != (3,) or rpy.shape != (3,) or not (np.isfinite(t).all() and np.isfinite(rpy).all()):
        raise CalibrationError(f"{path}: key 'fisheye_from_rgbd': translation and rpy_deg must be 3 finite numbers")
    return from_rpy(t, rpy)
