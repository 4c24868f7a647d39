"""RGB-D camera motion between two frames, to carry RGB-D points to the time of a fisheye frame.

The two cameras of the rig are not triggered together (the synthetic rig's fisheye runs 13 ms
after the RGB-D camera), so while the rig moves a fisheye frame sees the scene from a slightly
different pose than the nearest RGB-D frame: up to 10 mm and 0.4 degrees on the synthetic
trajectories, which biases the extrinsics by several millimetres. Visual odometry between the
RGB-D frame and its neighbour on the other side of the fisheye stamp (SIFT matches, depth of the
first frame, RANSAC PnP then LM refinement) gives that motion; assuming constant velocity, a
fraction of it moves the points to the fisheye's time.
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from probeless.cameras.matching import lift, to_gray
from probeless.errors import CalibrationError

MIN_INLIERS = 30


def rgbd_motion(rgb_a: np.ndarray, depth_a: np.ndarray, rgb_b: np.ndarray, K: np.ndarray, *,
                ratio: float = 0.75, ransac_px: float = 2.0, contrast: float = 0.01) -> tuple[np.ndarray, int]:
    """(b_from_a 4x4, inliers): the pose of RGB-D frame a in frame b (p_b = R p_a + t), from SIFT
    matches lifted with a's depth (metres). CalibrationError with fewer than MIN_INLIERS inliers."""
    K = np.asarray(K, dtype=np.float64)
    sift = cv2.SIFT_create(nfeatures=4000, contrastThreshold=contrast)
    ga, gb = to_gray(rgb_a), to_gray(rgb_b)
    kp_a, des_a = sift.detectAndCompute(ga, ((depth_a > 0) * 255).astype(np.uint8))
    kp_b, des_b = sift.detectAndCompute(gb, None)
    if des_a is None or des_b is None or len(kp_a) < 2 or len(kp_b) < 2:
        raise CalibrationError("RGB-D motion: no features to match between the two frames")
    pairs = [m for m, n in (p for p in cv2.BFMatcher(cv2.NORM_L2).knnMatch(des_a, des_b, k=2) if len(p) == 2)
             if m.distance < ratio * n.distance]
    px_a = np.array([kp_a[m.queryIdx].pt for m in pairs], dtype=np.float64).reshape(-1, 2)
    px_b = np.array([kp_b[m.trainIdx].pt for m in pairs], dtype=np.float64).reshape(-1, 2)
    pts, ok = lift(px_a, depth_a, K, 0.05)
    pts, px_b = pts[ok], px_b[ok]
    if len(pts) < MIN_INLIERS:
        raise CalibrationError(f"RGB-D motion: {len(pts)} matches between the two frames, need {MIN_INLIERS}")
    found, rvec, tvec, idx = cv2.solvePnPRansac(pts, px_b, K, None, reprojectionError=ransac_px,
                                                iterationsCount=300, confidence=0.999, flags=cv2.SOLVEPNP_EPNP)
    if not found or idx is None or len(idx) < MIN_INLIERS:
        raise CalibrationError(f"RGB-D motion: {0 if idx is None else len(idx)} consistent matches, "
                               f"need {MIN_INLIERS}")
    idx = idx.ravel()
    rvec, tvec = cv2.solvePnPRefineLM(pts[idx], px_b[idx], K, None, rvec, tvec)
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = cv2.Rodrigues(rvec)[0], tvec.ravel()
    return T, len(idx)


def scale_motion(T: np.ndarray, s: float) -> np.ndarray:
    """The fraction ``s`` of a rigid motion at constant velocity (rotation vector and translation
    scaled by s; exact for the rotation, first order for the translation of a screw motion)."""
    out = np.eye(4)
    out[:3, :3] = Rotation.from_rotvec(Rotation.from_matrix(T[:3, :3]).as_rotvec() * s).as_matrix()
    out[:3, 3] = T[:3, 3] * s
    return out


def motion_to_stamp(b_from_a: np.ndarray, stamp_a: int, stamp_b: int, stamp: int) -> np.ndarray:
    """The motion from frame a (at ``stamp_a``) to ``stamp``, given the motion a -> b, at constant velocity."""
    if stamp_b == stamp_a:
        raise CalibrationError("RGB-D motion: the two frames have the same stamp")
    return scale_motion(b_from_a, (stamp - stamp_a) / (stamp_b - stamp_a))
