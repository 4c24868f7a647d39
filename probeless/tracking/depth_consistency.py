"""How well a trajectory explains the depth images it was estimated from (no ground truth needed).

For frame pairs (i, i + gap) the depth of frame i is back-projected, moved into frame j by the
trajectory's relative pose ``inv(world_from_j) @ world_from_i`` and projected; where it lands on a
valid pixel of frame j, the residual is the predicted depth minus frame j's measured depth there.
Occlusions and disocclusions show up as large residuals, so residuals beyond ``outlier_m`` are
counted but left out of the median. Two trajectories of the same frames can be compared this way:
the one with the lower residual fits the data better. This is how the 7-Scenes reference poses
(KinectFusion estimates, not measurements) are checked against ours (docs/tracking).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Consistency:
    """Depth residuals of one trajectory over the frame pairs a fixed gap apart."""

    median_m: float | None      # median |residual| of the inliers [m] (None: no pairs)
    mean_m: float | None        # mean |residual| of the inliers [m]
    inlier_fraction: float      # residuals within outlier_m, of all that landed on valid depth
    pairs: int                  # frame pairs used (both poses known)
    samples: int                # residuals counted (inliers and outliers)


def pair_residuals(depth_i: np.ndarray, depth_j: np.ndarray, K: np.ndarray, depth_scale: float,
                   j_from_i: np.ndarray, *, depth_min: float = 0.1, depth_max: float = 3.0,
                   step: int = 4) -> np.ndarray:
    """Signed residuals [m] (predicted - measured depth in frame j) of every ``step``-th pixel of
    ``depth_i`` with depth in [depth_min, depth_max] that lands on a valid pixel of ``depth_j``
    (nearest pixel; same K for both; depth in units of 1/depth_scale m, 0 = invalid)."""
    h, w = depth_i.shape
    v, u = np.mgrid[0:h:step, 0:w:step]
    z = depth_i[::step, ::step].astype(np.float64) / depth_scale
    keep = (z >= depth_min) & (z <= depth_max)
    u, v, z = u[keep], v[keep], z[keep]
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    p = np.stack([(u - cx) / fx * z, (v - cy) / fy * z, z])
    q = j_from_i[:3, :3] @ p + j_from_i[:3, 3:4]
    zq = q[2]
    front = zq > 1e-6
    uq = np.rint(fx * q[0, front] / zq[front] + cx).astype(np.int64)
    vq = np.rint(fy * q[1, front] / zq[front] + cy).astype(np.int64)
    zq = zq[front]
    inside = (uq >= 0) & (uq < w) & (vq >= 0) & (vq < h)
    measured = depth_j[vq[inside], uq[inside]].astype(np.float64) / depth_scale
    valid = (measured >= depth_min) & (measured <= depth_max)
    return zq[inside][valid] - measured[valid]


def depth_consistency(depths: Sequence[np.ndarray], poses: Sequence[np.ndarray | None], K: np.ndarray,
                      depth_scale: float, gap: int, *, outlier_m: float = 0.1, depth_min: float = 0.1,
                      depth_max: float = 3.0, step: int = 4) -> Consistency:
    """:class:`Consistency` of ``poses`` (world_from_camera, None = unknown) over the pairs
    (i, i + gap) of ``depths`` (see the module docstring)."""
    if gap < 1:
        raise ValueError(f"depth_consistency: gap must be >= 1, got {gap}")
    if len(depths) != len(poses):
        raise ValueError(f"depth_consistency: {len(depths)} depth images but {len(poses)} poses")
    res, pairs = [], 0
    for i in range(len(depths) - gap):
        Ti, Tj = poses[i], poses[i + gap]
        if Ti is None or Tj is None:
            continue
        pairs += 1
        res.append(np.abs(pair_residuals(depths[i], depths[i + gap], K, depth_scale, np.linalg.inv(Tj) @ Ti,
                                         depth_min=depth_min, depth_max=depth_max, step=step)))
    r = np.concatenate(res) if res else np.zeros(0)
    inl = r[r <= outlier_m]
    if not len(inl):
        return Consistency(None, None, 0.0, pairs, len(r))
    return Consistency(float(np.median(inl)), float(inl.mean()), len(inl) / len(r), pairs, len(r))


def consistency_report(run, dataset: str, gaps: Sequence[int], *, start: int = 0, max_frames: int = 0,
                       stride: int = 1) -> dict:
    """``{gap: {"estimate": ..., "ground_truth": ...}}`` (:class:`Consistency` fields, [m]) of an
    offline SLAM run (:class:`.slam.SlamRun`), its frames read again from ``dataset``."""
    from dataclasses import asdict

    from probeless.tracking.sources import rgbd_samples

    samples, _ = rgbd_samples(dataset, start=start, max_frames=max_frames, stride=stride)
    depths, K, scale = [], None, 1.0
    for s in samples:
        depths.append(s.depth)
        K, scale = s.K, s.depth_scale
    depths = depths[:run.frames]
    dmax = run.params.depth_max if run.params else 3.0
    out = {}
    for gap in gaps:
        out[str(gap)] = {name: asdict(depth_consistency(depths, poses, K, scale, gap, depth_max=dmax))
                         for name, poses in (("estimate", run.poses), ("ground_truth", run.gt))}
    return out


def format_consistency(report: dict) -> list[str]:
    """One line per gap of :func:`consistency_report`'s dict."""
    def mm(c: dict) -> str:
        return "n/a" if c["median_m"] is None else f"{c['median_m'] * 1e3:.2f} mm ({c['inlier_fraction']:.1%} inliers)"
    return [f"depth residual, frames {gap} apart (median): estimate {mm(r['estimate'])}, "
            f"ground truth {mm(r['ground_truth'])}, {r['estimate']['pairs']} pairs" for gap, r in report.items()]
