"""Dense RGB-D SLAM with Open3D's tensor pipeline on the CPU (paper §4.2 used InfiniTAM).

:class:`DenseSlam` (:mod:`.dense`) wraps one ``o3d.t.pipelines.slam.Model`` (a TSDF voxel-block
grid) on ``CPU:0``: each :meth:`DenseSlam.step` tracks the frame against a raycast of the model
(point-to-plane ICP, coarse to fine, then refined with points weighted by their depth noise),
then integrates it and raycasts the model again at the new
pose. Mapping can run every k-th frame (``integrate_every``, ``raycast_every``) and everything at
1/n resolution (``scale``) to keep up on a small CPU. Bad frames never raise: they come back as
state ``lost`` (Open3D's "Singular 6x6 linear system", low fitness, NaN or implausible motion) or
``invalid_input`` (too little valid depth), the model is left alone, and the next frame is
tracked from the last good pose, moved on by a constant-velocity prediction (which also bridges
frames a node had to skip).

Two corrections to Open3D 0.18-0.20 as shipped: the raycast is made from a camera shifted by half
a voxel (its zero-crossing search reads voxels without interpolation, which otherwise biases the
model by ~v/2 along +x+y+z and makes tracking drift by that much per re-integration:
:func:`.slam_math.raycast_pose`; 7-Scenes, 30 frames: 42 -> 9 mm largest error), and the raycast
weight threshold counts integrations, not frames (mapping every k-th frame would otherwise
raycast an empty model).

:func:`run_slam` runs it over a dataset folder, scene file or recording (:mod:`.sources`).
"""

from __future__ import annotations

import time
from collections.abc import Collection
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Literal

import numpy as np

from probeless.errors import ProbelessError
from probeless.tracking.dense import DenseSlam, SlamParams, StepResult  # noqa: F401 (re-exported)
from probeless.tracking.sources import RgbdSample, rgbd_samples

STATES = ("initializing", "ok", "lost", "invalid_input")


@dataclass
class SlamRun:
    """Everything an offline run produced, one entry per frame fed (poses None where not tracked)."""

    stamps_ns: np.ndarray                           # (N,) int64 colour stamps [ns]
    poses: list[np.ndarray | None]                  # world_from_rgbd (4, 4) or None
    states: list[str]                               # per-frame state (see STATES)
    costs_ms: dict[str, list[float]]                # stage -> durations of the frames that ran it [ms]
    frames: int                                     # frames fed
    failures: int                                   # frames lost or invalid
    gt: list[np.ndarray | None]                     # ground-truth world_from_rgbd or None
    reasons: list[str] = field(default_factory=list)  # why a frame was not tracked ("" when ok)
    wall_s: float = 0.0                             # SLAM time only (no decoding or rendering) [s]
    params: SlamParams | None = None                # the settings the run used

    def mean_costs_ms(self) -> dict[str, float]:
        """Mean duration per stage over the frames that ran it [ms]."""
        return {k: float(np.mean(v)) for k, v in self.costs_ms.items() if v}


def run_slam(path: str | Path, params: SlamParams | None = None, *, start: int = 0, max_frames: int = 0,
             stride: int = 1, progress: bool = True,
             initial_pose: Literal["gt"] | np.ndarray | None = "gt", source_depth_model: bool = False,
             explicit: Collection[str] = ()) -> SlamRun:
    """Dense SLAM over the frames of ``path`` (dataset folder, scene file or recording).

    ``initial_pose``: ``"gt"`` = the first frame's ground truth (so the estimate lives in the
    ground-truth world frame; identity when the source has none), a 4x4 world_from_rgbd, or None
    (identity). The paper assumes the initial RGB-D pose is known. ``source_depth_model``: adapt
    ``params`` to what the source says of its depth (:func:`source_params`), except the fields named
    in ``explicit``; ``run.params`` holds the settings used.
    """
    from probeless.progress import progress as bar

    params = params or SlamParams()
    samples, count = rgbd_samples(path, start=start, max_frames=max_frames, stride=stride)
    run = SlamRun(np.zeros(0, np.int64), [], [], {}, 0, 0, [])
    stamps, slam = [], None
    with bar(count, f"SLAM {Path(path).name}", enabled=progress) as tick:
        for s in samples:
            if slam is None:
                if source_depth_model:
                    params = source_params(params, s, explicit)
                run.params = params
                slam = DenseSlam(params, s.K, s.rgb.shape[1], s.rgb.shape[0],
                                 _initial(initial_pose, s.gt_world_from_rgbd))
            t0 = time.perf_counter()
            r = slam.step(s.rgb, s.depth, s.depth_scale, s.stamp_ns)
            run.wall_s += time.perf_counter() - t0
            stamps.append(s.stamp_ns)
            run.poses.append(r.world_from_rgbd)
            run.states.append(r.state)
            run.reasons.append(r.reason)
            run.gt.append(s.gt_world_from_rgbd)
            for stage, ms in r.costs_ms.items():
                run.costs_ms.setdefault(stage, []).append(ms)
            run.failures += r.state != "ok"
            tick()
    run.stamps_ns, run.frames = np.asarray(stamps, dtype=np.int64), len(stamps)
    return run


def source_params(params: SlamParams, sample: RgbdSample, explicit: Collection[str] = ()) -> SlamParams:
    """``params`` fitted to the depth the source describes (the synthetic rig does; datasets don't):
    ``depth_max`` = its accurate range, and its noise model for the depth weighting (off where the
    noise is the same at every depth: nothing to weight). Fields in ``explicit`` stay as given."""
    change: dict = {}
    if sample.depth_range_m is not None and "depth_max" not in explicit:
        change["depth_max"] = float(sample.depth_range_m)
    if sample.depth_sigma is not None and not {"depth_weighting", "depth_sigma"} & set(explicit):
        sigma = tuple(float(x) for x in sample.depth_sigma)
        if sigma[1] == 0:
            change["depth_weighting"] = False
        else:
            change["depth_sigma"] = sigma
    return replace(params, **change)


def _initial(initial_pose, gt: np.ndarray | None) -> np.ndarray:
    """The 4x4 world_from_rgbd of the first frame (rule in :func:`run_slam`)."""
    if isinstance(initial_pose, str):
        if initial_pose != "gt":
            raise ProbelessError(f"initial_pose: expected 'gt', a 4x4 matrix or None, got {initial_pose!r}")
        return np.eye(4) if gt is None else np.asarray(gt, dtype=np.float64)
    if initial_pose is None:
        return np.eye(4)
    T = np.asarray(initial_pose, dtype=np.float64)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise ProbelessError(f"initial_pose: expected a finite 4x4 matrix, got shape {T.shape}")
    return T
