"""Fisheye intrinsics from chessboard detections: cv2.omnidir (Mei) or cv2.fisheye (Kannala-Brandt).

Object points are in metres, so the per-view translations are too. The RMS reported is recomputed
here by reprojecting every used corner with the returned parameters (cv2.omnidir.projectPoints /
cv2.fisheye.projectPoints); OpenCV's own figure is kept beside it for comparison. Views are
dropped, each with its reason, when OpenCV rejects them (omnidir's initialisation, fisheye's
CALIB_CHECK_COND) or when their RMS is an outlier among the views (a wrong detection).
Detection itself is in :mod:`probeless.cameras.chessboard`.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np

from probeless.cameras.chessboard import BoardDetection, board_points
from probeless.errors import CalibrationError
from probeless.messages.header import Header
from probeless.messages.sensor import CameraInfo

FISHEYE_MODELS = ("omnidir", "kannala_brandt")
MIN_BOARDS = 3
_CRITERIA = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 300, 1e-10)


@dataclass
class CalibrationResult:
    """A fisheye calibration and what it was computed from."""

    info: CameraInfo
    rms_px: float                         # recomputed over every used corner
    opencv_rms_px: float                  # the figure cv2.*.calibrate returned
    per_image_rms_px: dict[str, float]    # image name -> RMS of its corners
    skipped: dict[str, str]               # image name -> why it was not used
    detected: dict[str, np.ndarray]       # image name -> (N, 2) detected corners (used images)
    reprojected: dict[str, np.ndarray]    # image name -> (N, 2) reprojected corners (used images)
    poses: dict[str, tuple[np.ndarray, np.ndarray]]  # image name -> board pose (rvec, tvec [m]) in the camera
    notes: list[str] = field(default_factory=list)


def _rms(err: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum(err * err, axis=1))))


def calibrate_omnidir(obj: list[np.ndarray], img: list[np.ndarray], size: tuple[int, int]):
    """cv2.omnidir.calibrate (skew fixed at 0) -> (K, xi, D, rvecs, tvecs, used indices, opencv rms)."""
    o = [p.reshape(-1, 1, 3).astype(np.float64) for p in obj]
    i = [p.reshape(-1, 1, 2).astype(np.float64) for p in img]
    try:
        rms, K, xi, D, rvecs, tvecs, idx = cv2.omnidir.calibrate(o, i, size, None, None, None,
                                                                 cv2.omnidir.CALIB_FIX_SKEW, _CRITERIA)
    except cv2.error as exc:
        raise CalibrationError(f"cv2.omnidir.calibrate failed: {str(exc).strip()}") from None
    used = [int(k) for k in np.asarray(idx).ravel()] if idx is not None else list(range(len(obj)))
    return K, float(np.ravel(xi)[0]), np.ravel(D), list(rvecs), list(tvecs), used, float(rms)


def _fisheye_flag(name: str) -> int:
    # OpenCV 4 keeps these in cv2.fisheye, OpenCV 5 in cv2.
    return int(getattr(cv2.fisheye, name, None) or getattr(cv2, name))


def calibrate_kannala_brandt(obj: list[np.ndarray], img: list[np.ndarray], size: tuple[int, int],
                             K0: np.ndarray | None = None):
    """cv2.fisheye.calibrate (CALIB_RECOMPUTE_EXTRINSIC | CALIB_FIX_SKEW | CALIB_CHECK_COND), dropping
    every view it calls ill-conditioned and retrying -> (K, D, rvecs, tvecs, used, dropped, opencv rms).

    ``K0`` is an initial camera matrix (CALIB_USE_INTRINSIC_GUESS); without it OpenCV starts from
    f = max(W, H) / pi at the image centre, from which wide-angle views often fail CHECK_COND.
    """
    flags = sum(_fisheye_flag(n) for n in ("CALIB_RECOMPUTE_EXTRINSIC", "CALIB_FIX_SKEW", "CALIB_CHECK_COND"))
    if K0 is not None:
        flags |= _fisheye_flag("CALIB_USE_INTRINSIC_GUESS")
    used, dropped = list(range(len(obj))), []
    while len(used) >= MIN_BOARDS:
        o = [obj[k].reshape(1, -1, 3).astype(np.float64) for k in used]
        i = [img[k].reshape(1, -1, 2).astype(np.float64) for k in used]
        K = None if K0 is None else np.array(K0, dtype=np.float64)
        try:
            rms, K, D, rvecs, tvecs = cv2.fisheye.calibrate(o, i, size, K, None if K0 is None else np.zeros(4),
                                                            flags=flags, criteria=_CRITERIA)
            return K, np.ravel(D), list(rvecs), list(tvecs), used, dropped, float(rms)
        except cv2.error as exc:
            m = re.search(r"input array (\d+)", str(exc))
            if m is None or int(m.group(1)) >= len(used):
                raise CalibrationError(f"cv2.fisheye.calibrate failed: {str(exc).strip()}") from None
            dropped.append(used.pop(int(m.group(1))))
    raise CalibrationError(f"cv2.fisheye.calibrate: fewer than {MIN_BOARDS} views left after dropping "
                           f"{len(dropped)} ill-conditioned one(s)")


def reproject(info: CameraInfo, obj: np.ndarray, rvec: np.ndarray, tvec: np.ndarray) -> np.ndarray:
    """(N, 2) pixels of board points ``obj`` seen from (rvec, tvec), by OpenCV's own projection."""
    rvec, tvec = np.asarray(rvec, np.float64).reshape(3, 1), np.asarray(tvec, np.float64).reshape(3, 1)
    if info.model == "omnidir":
        px, _ = cv2.omnidir.projectPoints(obj.reshape(-1, 1, 3), rvec, tvec, info.K, info.xi, info.D.reshape(1, 4))
    else:
        px, _ = cv2.fisheye.projectPoints(obj.reshape(1, -1, 3), rvec, tvec, info.K, info.D)
    return px.reshape(-1, 2)


def calibrate_fisheye(detections: Sequence[BoardDetection], square_m: float, model: str = "omnidir",
                      frame_id: str = "fisheye", *, max_view_rms_px: float = 2.0) -> CalibrationResult:
    """Calibrate from board detections; CalibrationError with fewer than MIN_BOARDS usable boards.

    A view whose RMS exceeds max(``max_view_rms_px``, 4 x the median view RMS) is dropped and the
    calibration repeated. kannala_brandt starts from the omnidir calibration of the same views.
    """
    if model not in FISHEYE_MODELS:
        raise CalibrationError(f"unknown fisheye model {model!r}; expected one of {FISHEYE_MODELS}")
    skipped = {d.name: d.reason for d in detections if d.corners is None}
    views = [d for d in detections if d.corners is not None]
    size = views[0].size if views else (0, 0)
    skipped.update({d.name: f"image size {d.size[0]}x{d.size[1]} differs from {size[0]}x{size[1]}"
                    for d in views if d.size != size})
    views = [d for d in views if d.size == size]
    larger = [d for d in detections if d.corners is None and d.grid != (0, 0)]
    if len(views) < MIN_BOARDS or len(larger) >= len(views):  # the latter: most likely a wrong --board
        raise CalibrationError(_too_few_message(detections, len(views)))
    notes: list[str] = []
    K0 = None
    if model == "kannala_brandt":
        K0, views = _kb_start(detections, views, square_m, frame_id, max_view_rms_px, skipped, notes)
    while True:
        info, opencv_rms, used, poses, rejected = _solve(model, views, square_m, size, frame_id, K0)
        skipped.update(rejected)
        if len(used) < MIN_BOARDS:
            raise CalibrationError(f"only {len(used)} view(s) survived calibration, need {MIN_BOARDS}; "
                                   f"skipped: {skipped}")
        reprojected = {d.name: reproject(info, board_points(d.grid, square_m), *pose) for d, pose in zip(used, poses)}
        per_image = {d.name: _rms(reprojected[d.name] - d.corners) for d in used}
        worst, median = max(per_image, key=per_image.get), float(np.median(list(per_image.values())))
        if per_image[worst] <= max(max_view_rms_px, 4 * median) or len(used) <= MIN_BOARDS:
            break
        skipped[worst] = (f"reprojection RMS {per_image[worst]:.2f} px, an outlier among the views "
                          f"(median {median:.2f} px): dropped and recalibrated")
        views = [d for d in used if d.name != worst]
    detected = {d.name: d.corners for d in used}
    rms = _rms(np.concatenate([reprojected[n] - detected[n] for n in detected]))
    board_poses = {d.name: (np.ravel(r), np.ravel(t)) for d, (r, t) in zip(used, poses)}
    return CalibrationResult(info, rms, opencv_rms, per_image, skipped, detected, reprojected, board_poses, notes)


def _solve(model, views, square_m, size, frame_id, K0):
    """One OpenCV calibration -> (info, opencv rms, used views, [(rvec, tvec)], {name: why rejected})."""
    obj = [board_points(d.grid, square_m) for d in views]
    img = [d.corners for d in views]
    if model == "omnidir":
        K, xi, D, rvecs, tvecs, used, opencv_rms = calibrate_omnidir(obj, img, size)
        rejected = {views[k].name: "rejected by cv2.omnidir.calibrate (initialisation failed for this view)"
                    for k in sorted(set(range(len(views))) - set(used))}
        info = CameraInfo(Header(0, frame_id), size[0], size[1], "omnidir", K, D, xi=xi)
    else:
        K, D, rvecs, tvecs, used, dropped, opencv_rms = calibrate_kannala_brandt(obj, img, size, K0)
        rejected = {views[k].name: "ill-conditioned for cv2.fisheye.calibrate (CALIB_CHECK_COND): dropped"
                    for k in dropped}
        info = CameraInfo(Header(0, frame_id), size[0], size[1], "kannala_brandt", K, D)
    return info, opencv_rms, [views[k] for k in used], list(zip(rvecs, tvecs)), rejected


def _kb_start(detections, views, square_m, frame_id, max_view_rms_px, skipped, notes):
    """(initial K, views) for cv2.fisheye from an omnidir calibration: both models have the slope
    fx / (1 + xi) at the centre. OpenCV's own start (f = max(W, H) / pi) fails CALIB_CHECK_COND on
    most views of a wide-angle lens; it is used only when the omnidir fit fails."""
    try:
        base = calibrate_fisheye(detections, square_m, "omnidir", frame_id, max_view_rms_px=max_view_rms_px)
    except CalibrationError as exc:
        notes.append(f"kannala_brandt initialised by OpenCV's default (the omnidir fit failed: {exc})")
        return None, views
    K, xi = base.info.K, base.info.xi
    f = (K[0, 0] + K[1, 1]) / 2 / (1 + xi)
    notes.append(f"kannala_brandt initialised from an omnidir fit (RMS {base.rms_px:.3f} px): f = {f:.1f} px")
    skipped.update({n: f"{why} (in the omnidir fit that initialises kannala_brandt)"
                    for n, why in base.skipped.items() if n not in skipped})
    K0 = np.array([[f, 0, K[0, 2]], [0, f, K[1, 2]], [0, 0, 1]], dtype=np.float64)
    return K0, [d for d in views if d.name in base.per_image_rms_px]


def _too_few_message(detections: Sequence[BoardDetection], n_found: int) -> str:
    msg = f"board found in {n_found} of {len(detections)} image(s)"
    msg += f", need at least {MIN_BOARDS}" if n_found < MIN_BOARDS else ""
    larger = [d for d in detections if d.corners is None and d.grid != (0, 0)]
    if larger:
        cols, rows = max((d.grid for d in larger), key=lambda g: g[0] * g[1])
        c, r = sorted((cols - 1, rows - 1))
        msg += (f"; {len(larger)} image(s) show a larger board, up to {cols}x{rows} inner corners: "
                f"try --board {c}x{r} (squares between the inner corners, as OCamCalib counts them)")
    return msg
