"""Settings and per-frame result of :class:`probeless.tracking.dense.DenseSlam` (importable without Open3D)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from probeless.errors import ProbelessError
from probeless.tracking.weighted_icp import KINECT_SIGMA

# The TSDF grid is turned against the world (xyz Euler angles) so that no grid axis is parallel to
# the walls, floor or ceiling of a room. Open3D's raycast reads the TSDF of the voxel containing each
# sample, so a surface parallel to the voxel faces is seen quantised to the voxel, and frame-to-model
# ICP against it under-estimates motions smaller than a voxel (the estimated path came out 1-3 %
# short on the synthetic rooms). Turned, the quantisation averages out over the surface: ATE on the
# rooms 25.1 -> 19.7 mm (l_shaped_lounge), 30.6 -> 25.9 (partition_room), 16.3 -> 12.0 (convex_room);
# 7-Scenes, whose world axes follow no wall, is unchanged (42.5 -> 42.1). Any angles far from
# multiples of 90 deg do; these are not tuned.
GRID_ROTATION_DEG = (17.0, 23.0, 31.0)


@dataclass(frozen=True)
class SlamParams:
    """Dense SLAM settings. Defaults: Open3D's dense_slam example, except as noted."""

    voxel_size: float = 0.01            # TSDF voxel edge [m]; 1 cm (Open3D: 5.8 mm) is room scale and ~2x cheaper
    block_resolution: int = 16          # voxels per block edge
    block_count: int = 10000            # initial hash map capacity [blocks] (example: 40000 = 2 GB); grows when full
    depth_max: float = 3.0              # depth used for tracking and integration [m]
    depth_min: float = 0.1              # nearest raycast depth [m]
    depth_diff: float = 0.07            # ICP correspondence distance [m]
    trunc_voxel_multiplier: float = 8.0  # TSDF truncation = this x voxel_size
    integrate_every: int = 1            # integrate every k-th tracked frame
    raycast_every: int = 1              # raycast the model every k-th tracked frame
    scale: float = 1.0                  # 1/n: track and map at 1/n resolution (0.5 = half)
    min_fitness: float = 0.3            # fewer inlier correspondences (fraction) = lost
    max_translation_m: float = 0.3      # larger motion per frame = lost [m]
    max_rotation_deg: float = 30.0      # larger rotation per frame = lost [deg]
    min_valid_fraction: float = 0.05    # fewer valid depth pixels (fraction) = invalid input
    iterations: tuple[int, ...] = (6, 3, 1)  # ICP iterations per pyramid level, coarse to fine
    raycast_shift: bool = True          # undo the raycast's mean half-voxel bias (slam_math.raycast_pose)
    grid_rotation_deg: tuple[float, float, float] = GRID_ROTATION_DEG  # TSDF grid axes vs world (below) [deg]
    integrate_nearest_pixel: bool = True  # integrate each voxel from its nearest pixel, not Open3D's floor (dense.py)
    depth_weighting: bool = True        # refine each pose with points weighted by 1/sigma(z)^2 (weighted_icp.py)
    depth_sigma: tuple[float, float, float] = KINECT_SIGMA  # depth noise sigma(z) = a + b (z - z0)^2 [m]: (a, b, z0)
    refine_iterations: int = 10         # Gauss-Newton steps of the weighted refinement, at most (0.1 mm steps stop it)
    refine_step: int = 4                # every n-th pixel (of the tracking resolution) in the refinement

    def __post_init__(self) -> None:
        n = round(1.0 / self.scale) if self.scale > 0 else 0
        if n < 1 or abs(1.0 / n - self.scale) > 1e-9:
            raise ProbelessError("SlamParams.scale: must be 1/n for an integer n >= 1 (1, 0.5, 0.25...), "
                                 f"got {self.scale}")
        if self.integrate_every < 1 or self.raycast_every < 1:
            raise ProbelessError("SlamParams.integrate_every and raycast_every: must be >= 1, got "
                                 f"{self.integrate_every} and {self.raycast_every}")
        if self.depth_weighting and (self.refine_iterations < 1 or self.refine_step < 1 or len(self.depth_sigma) != 3
                                     or not all(np.isfinite(self.depth_sigma)) or self.depth_sigma[0] <= 0
                                     or self.depth_sigma[1] < 0):
            raise ProbelessError("SlamParams: depth weighting needs refine_iterations, refine_step >= 1 and "
                                 f"depth_sigma (a, b, z0) finite with a > 0, b >= 0; got {self}")
        if not 0 < self.depth_min < self.depth_max or self.voxel_size <= 0 or not self.iterations:
            raise ProbelessError("SlamParams: need 0 < depth_min < depth_max, voxel_size > 0 and iterations; "
                                 f"got {self}")


@dataclass(frozen=True)
class StepResult:
    """Outcome of one frame: the pose where tracked, the state and why, and stage costs [ms]."""

    world_from_rgbd: np.ndarray | None      # (4, 4), None unless state == "ok"
    state: str                              # ok | lost | invalid_input
    reason: str = ""                        # why the frame was not tracked
    costs_ms: dict = field(default_factory=dict)  # prepare / track / integrate / raycast [ms]
    fitness: float = float("nan")           # ICP inlier fraction (nan when not tracked)
