"""Point-to-plane ICP with each point weighted by its depth noise (pure numpy).

Open3D's RGB-D odometry weighs every pixel alike. Structured-light depth (Kinect v1, Xtion) is not
alike: its axial noise grows with the square of the distance (Nguyen, Izadi & Lovell, 3DIMPACT
2012: sigma(z) = 0.0012 + 0.0019 (z - 0.4)^2 m, 2 mm at 1 m, 14 mm at 3 m), so far points, which
are many, pull the pose with errors 5-50x those of near ones. :func:`refine_point_to_plane` takes
Open3D's estimate and runs a few Gauss-Newton steps of the same point-to-plane problem (projective
association against the raycast depth, Huber loss) with weights 1 / sigma(z)^2: the weighted
least-squares (maximum-likelihood) pose under that noise.
"""

from __future__ import annotations

import numpy as np

from probeless.tracking.slam_math import se3_exp

# sigma(z) = a + b (z - z0)^2 [m] of Kinect v1 depth (Nguyen et al. 2012, axial noise)
KINECT_SIGMA = (0.0012, 0.0019, 0.4)


def depth_weights(z: np.ndarray, sigma: tuple[float, float, float]) -> np.ndarray:
    """1 / sigma(z)^2 for depths ``z`` [m], normalised to mean 1."""
    a, b, z0 = sigma
    w = 1.0 / (a + b * (z - z0) ** 2) ** 2
    return w / w.mean() if len(w) else w


def _backproject(depth_m: np.ndarray, K: np.ndarray, v: np.ndarray, u: np.ndarray) -> np.ndarray:
    z = depth_m[v, u]
    return np.stack([(u - K[0, 2]) / K[0, 0] * z, (v - K[1, 2]) / K[1, 1] * z, z], axis=-1)


def _target_planes(tgt: np.ndarray, K: np.ndarray, v: np.ndarray, u: np.ndarray):
    """(points (N, 3), unit normals (N, 3), ok (N,)) of the target depth at interior pixels (v, u):
    normals from central differences, rejected across depth edges or at holes. Computed at the
    pixels hit only: cheaper than whole maps for the few thousand points a refinement uses."""
    c = _backproject(tgt, K, v, u)
    right, left = _backproject(tgt, K, v, u + 1), _backproject(tgt, K, v, u - 1)
    down, up = _backproject(tgt, K, v + 1, u), _backproject(tgt, K, v - 1, u)
    dx, dy = right - left, down - up
    near = 0.05 * np.maximum(c[:, 2], 0.1)  # neighbours 5 % of the depth apart at most: no edge
    ok = (c[:, 2] > 0) & (np.linalg.norm(dx, axis=1) < near) & (np.linalg.norm(dy, axis=1) < near)
    ok &= (tgt[v, u + 1] > 0) & (tgt[v, u - 1] > 0) & (tgt[v + 1, u] > 0) & (tgt[v - 1, u] > 0)
    n = np.cross(dx, dy)
    norm = np.linalg.norm(n, axis=1)
    ok &= norm > 0
    return c, n / np.where(ok, norm, 1.0)[:, None], ok


def refine_point_to_plane(src_m: np.ndarray, tgt_m: np.ndarray, K: np.ndarray, tgt_from_src: np.ndarray, *,
                          sigma: tuple[float, float, float] = KINECT_SIGMA, iterations: int = 10,
                          max_distance: float = 0.07, huber: float = 0.05, step: int = 4,
                          tolerance_m: float = 1e-4) -> tuple[np.ndarray, int]:
    """(tgt_from_src refined, correspondences in the last step) of the noise-weighted point-to-plane
    problem (module docstring). ``src_m``, ``tgt_m``: (H, W) depth [m] (0 = invalid) of the source
    frame and the target (raycast) frame, same pinhole ``K``; every ``step``-th source pixel;
    residuals over ``max_distance`` [m] are outliers, Huber beyond ``huber`` [m]; at most
    ``iterations`` steps, fewer once a step moves less than ``tolerance_m`` (and its rotation less
    than ``tolerance_m`` rad: the motion of a point 1 m away). Returns the
    input pose unchanged when the system is under-determined (fewer than 6 correspondences or a
    singular normal matrix)."""
    h, w = tgt_m.shape
    v, u = np.mgrid[0:h:step, 0:w:step]
    v, u = v.ravel(), u.ravel()
    keep = src_m[v, u] > 0
    P = _backproject(src_m, K, v[keep], u[keep])
    wz = depth_weights(P[:, 2], sigma)
    T, used = np.array(tgt_from_src, dtype=np.float64), 0
    for _ in range(iterations):
        Q = P @ T[:3, :3].T + T[:3, 3]
        front = Q[:, 2] > 1e-3
        zq = np.where(front, Q[:, 2], 1.0)
        uq = np.rint(K[0, 0] * Q[:, 0] / zq + K[0, 2]).astype(np.int64)
        vq = np.rint(K[1, 1] * Q[:, 1] / zq + K[1, 2]).astype(np.int64)
        inside = front & (uq >= 1) & (uq < w - 1) & (vq >= 1) & (vq < h - 1)
        Q, W, uq, vq = Q[inside], wz[inside], uq[inside], vq[inside]
        C, N, ok = _target_planes(tgt_m, K, vq, uq)
        Q, W, C, N = Q[ok], W[ok], C[ok], N[ok]
        r = np.einsum("ij,ij->i", N, Q - C)
        inl = np.abs(r) < max_distance
        Q, W, N, r = Q[inl], W[inl], N[inl], r[inl]
        if len(r) < 6:
            return T, len(r)
        W = W * np.where(np.abs(r) <= huber, 1.0, huber / np.maximum(np.abs(r), 1e-12))
        J = np.hstack([np.cross(Q, N), N])  # d r / d (omega, v) of a left perturbation exp(xi) T
        JW = J * W[:, None]
        H, g = JW.T @ J, JW.T @ r
        if np.linalg.cond(H) > 1e12:
            return T, len(r)
        xi = -np.linalg.solve(H, g)
        T = se3_exp(xi) @ T
        used = len(r)
        if np.linalg.norm(xi[3:]) < tolerance_m and np.linalg.norm(xi[:3]) < tolerance_m:  # rad ~ m at 1 m
            break
    return T, used
