"""Trajectory errors as the TUM RGB-D benchmark defines them (Sturm et al., IROS 2012).

* ATE (``evaluate_ate.py``): the estimated positions are rigidly aligned to the true ones with
  Horn's closed form (Umeyama's SVD formulation, optional scale), then the per-frame distances
  are summarised (RMSE, mean, median, std, min, max).
* RPE (``evaluate_rpe.py --fixed_delta``): for pose pairs (i, j) a fixed interval apart,
  ``E = (est_i^-1 est_j) (gt_i^-1 gt_j)^-1`` as that script computes it (the paper writes the
  conjugate ``(gt_i^-1 gt_j)^-1 (est_i^-1 est_j)``: same angle, translations differ to second
  order); the translation norm and the rotation angle of E. Unlike the script, a pair may end on
  the last frame (the script drops pairs ending there).

Poses are world_from_camera 4x4 matrices. Frames without an estimate or without ground truth
(``None``) are left out of every figure; ``n`` says how many counted.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

Pose = np.ndarray | None


def align_umeyama(est: np.ndarray, gt: np.ndarray, with_scale: bool = False) -> tuple[np.ndarray, np.ndarray, float]:
    """(R, t, s) minimising sum |gt_k - (s R est_k + t)|^2 over rotations R (det +1), t and s (1 unless with_scale)."""
    est, gt = np.asarray(est, dtype=np.float64), np.asarray(gt, dtype=np.float64)
    if est.ndim != 2 or est.shape[1] != 3 or est.shape != gt.shape:
        raise ValueError(f"align_umeyama needs two (N, 3) arrays of the same shape, got {est.shape} and {gt.shape}")
    if len(est) < 3:
        raise ValueError(f"align_umeyama needs at least 3 positions, got {len(est)}")
    mu_e, mu_g = est.mean(axis=0), gt.mean(axis=0)
    e, g = est - mu_e, gt - mu_g
    U, D, Vt = np.linalg.svd(g.T @ e / len(est))
    S = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        S[2, 2] = -1.0
    R = U @ S @ Vt
    var_e = float((e * e).sum()) / len(est)
    s = float(np.trace(np.diag(D) @ S) / var_e) if with_scale and var_e > 0 else 1.0
    return R, mu_g - s * R @ mu_e, s


def matched(est: Sequence[Pose], gt: Sequence[Pose]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(indices, est (N,4,4), gt (N,4,4)) of the frames that have both an estimate and ground truth."""
    if len(est) != len(gt):
        raise ValueError(f"{len(est)} estimated poses but {len(gt)} ground-truth entries; associate them first")
    idx = np.array([k for k, (e, g) in enumerate(zip(est, gt)) if e is not None and g is not None], dtype=int)
    return (idx, np.array([est[k] for k in idx], dtype=np.float64).reshape(-1, 4, 4),
            np.array([gt[k] for k in idx], dtype=np.float64).reshape(-1, 4, 4))


def associate(est_stamps_ns: Sequence[int], est: Sequence[Pose], gt_stamps_ns: Sequence[int], gt: Sequence[Pose],
              max_dt_s: float = 0.02) -> tuple[np.ndarray, list[Pose], list[Pose]]:
    """Re-index ground truth onto the estimate's stamps: (stamps, est, gt per estimate stamp or None).

    Each estimate stamp takes the nearest ground-truth stamp within ``max_dt_s``, each used once
    (as TUM's ``associate.py``).
    """
    from probeless.datasets.tum import associate as nearest_pairs

    if len(est_stamps_ns) != len(est) or len(gt_stamps_ns) != len(gt):
        raise ValueError("each stamp list must be as long as its pose list")
    e_ns, g_ns = np.asarray(est_stamps_ns, dtype=np.int64), np.asarray(gt_stamps_ns, dtype=np.int64)
    g_order = np.argsort(g_ns, kind="stable")
    gt_for: list[Pose] = [None] * len(est)
    e_order = np.argsort(e_ns, kind="stable")
    for i, j in nearest_pairs(e_ns[e_order], g_ns[g_order], round(max_dt_s * 1e9)):
        gt_for[int(e_order[i])] = gt[int(g_order[j])]
    return e_ns, list(est), gt_for


def summary(values: np.ndarray) -> dict:
    """rmse, mean, median, std, min, max and n of a 1-D array (None figures when it is empty)."""
    v = np.asarray(values, dtype=np.float64)
    if v.size == 0:
        return {"rmse": None, "mean": None, "median": None, "std": None, "min": None, "max": None, "n": 0}
    return {"rmse": float(np.sqrt(np.mean(v * v))), "mean": float(v.mean()), "median": float(np.median(v)),
            "std": float(v.std()), "min": float(v.min()), "max": float(v.max()), "n": int(v.size)}


def ate_errors(est: Sequence[Pose], gt: Sequence[Pose], with_scale: bool = False) -> dict:
    """Per-frame ATE: indices, errors (m), aligned estimated and true positions, and the alignment (R, t, s)."""
    idx, E, G = matched(est, gt)
    R, t, s = align_umeyama(E[:, :3, 3], G[:, :3, 3], with_scale)
    out = {"indices": idx, "gt": G[:, :3, 3], "R": R, "t": t, "s": s}
    out["est_aligned"] = align_points(E[:, :3, 3], out)
    out["errors"] = np.linalg.norm(out["est_aligned"] - out["gt"], axis=1)
    return out


def align_points(points: np.ndarray, alignment: dict) -> np.ndarray:
    """Apply an :func:`ate_errors` alignment (s R p + t) to more positions (N, 3)."""
    return alignment["s"] * np.asarray(points, dtype=np.float64).reshape(-1, 3) @ alignment["R"].T + alignment["t"]


def ate(est: Sequence[Pose], gt: Sequence[Pose], with_scale: bool = False) -> dict:
    """ATE summary (metres): rmse, mean, median, std, min, max, n."""
    return summary(ate_errors(est, gt, with_scale)["errors"])


def rotation_angle(R: np.ndarray) -> float:
    """Angle (rad) of a rotation matrix, from its trace (clipped against rounding)."""
    return float(np.arccos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)))


def rpe_pairs(stamps_ns: Sequence[int], valid: np.ndarray, delta_frames: int | None,
              delta_s: float | None) -> list[tuple[int, int]]:
    """Pairs (i, j), both valid: j = i + delta_frames, or the frame nearest stamp_i + delta_s (within half a frame)."""
    if (delta_frames is None) == (delta_s is None):
        raise ValueError("give exactly one of delta_frames and delta_s")
    n = len(valid)
    if delta_frames is not None:
        if delta_frames < 1:
            raise ValueError(f"delta_frames must be >= 1, got {delta_frames}")
        return [(i, i + delta_frames) for i in range(n - delta_frames) if valid[i] and valid[i + delta_frames]]
    ns = np.asarray(stamps_ns, dtype=np.int64)
    if n < 2:
        return []
    if np.any(np.diff(ns) <= 0):
        raise ValueError("stamps must be strictly increasing to pair frames by delta_s")
    tol = np.median(np.diff(ns)) / 2.0
    target = ns + round(delta_s * 1e9)
    j = np.clip(np.searchsorted(ns, target), 1, n - 1)
    j = np.where(np.abs(ns[j - 1] - target) <= np.abs(ns[j] - target), j - 1, j)
    ok = (np.abs(ns[j] - target) <= tol) & (j > np.arange(n))
    return [(i, int(j[i])) for i in range(n) if ok[i] and valid[i] and valid[j[i]]]


def rpe(est: Sequence[Pose], gt: Sequence[Pose], stamps_ns: Sequence[int], *, delta_frames: int | None = None,
        delta_s: float | None = None) -> dict:
    """Relative pose error over a fixed interval: trans_* (m) and rot_*_deg summaries, n pairs, the delta."""
    if not len(est) == len(gt) == len(stamps_ns):
        raise ValueError(f"rpe needs equal lengths, got {len(est)} estimates, {len(gt)} ground truth, "
                         f"{len(stamps_ns)} stamps")
    valid = np.array([e is not None and g is not None for e, g in zip(est, gt)], dtype=bool)
    trans, rot = [], []
    for i, j in rpe_pairs(stamps_ns, valid, delta_frames, delta_s):
        rel_est = np.linalg.solve(est[i], est[j])
        rel_gt = np.linalg.solve(gt[i], gt[j])
        err = rel_est @ np.linalg.inv(rel_gt)
        trans.append(np.linalg.norm(err[:3, 3]))
        rot.append(np.degrees(rotation_angle(err[:3, :3])))
    t, r = summary(np.array(trans)), summary(np.array(rot))
    out = {f"trans_{k}": v for k, v in t.items() if k != "n"}
    out.update({f"rot_{k}_deg": v for k, v in r.items() if k != "n"})
    out["n"] = t["n"]
    out["delta"] = {"frames": delta_frames} if delta_frames is not None else {"s": delta_s}
    return out
