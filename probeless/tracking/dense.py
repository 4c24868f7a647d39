"""One Open3D tensor SLAM model on CPU:0: tracking, integration, raycasting and model extraction.

See :mod:`probeless.tracking.offline` for the overview; this module holds the per-frame core.
Tracking is what ``Model.track_frame_to_model`` does (multi-scale RGB-D odometry of the input frame
against the raycast frame) but started from a constant-velocity prediction of the pose instead of
the raycast pose, so skipped frames (a node that drops what it cannot process) do not lose
tracking, and (``depth_weighting``) refined with every point weighted by its depth noise
(:mod:`.weighted_icp`: Open3D weighs near and far structured-light depth alike). Odometry returns
``raycast_from_input``, so ``world_from_input = world_from_raycast @ it`` where
``world_from_raycast`` is the pose the last raycast was made at. Each integration records its
frame's stamp on the voxel blocks it touched (:mod:`.block_stamps`), so extracted points and
vertices can say when they were last fused (:meth:`DenseSlam.fusion_stamps`).
"""

from __future__ import annotations

import contextlib
import time
from collections import deque
from typing import Any, Callable

import numpy as np

from probeless.errors import ProbelessError
from probeless.tracking.block_stamps import BlockStamps
from probeless.tracking.model_extract import extract_mesh, extract_pointcloud, extraction_threshold
from probeless.tracking.slam_input import prepare_frame
from probeless.tracking.slam_math import motion, open3d_message, predict_pose, raycast_pose, scaled_K
from probeless.tracking.slam_params import SlamParams, StepResult  # noqa: F401 (re-exported)
from probeless.tracking.weighted_icp import refine_point_to_plane

DEVICE = "CPU:0"


def grid_from_world(rotation_deg) -> np.ndarray:
    """(4, 4) rotation of the TSDF grid's axes against the world's (xyz Euler angles [deg])."""
    from scipy.spatial.transform import Rotation

    G = np.eye(4)
    G[:3, :3] = Rotation.from_euler("xyz", np.asarray(rotation_deg, np.float64), degrees=True).as_matrix()
    return G


class DenseSlam:
    """One tensor SLAM model on CPU:0 (pure: no bus). Frames are (H, W) = (height, width)."""

    def __init__(self, params: SlamParams, K: np.ndarray, width: int, height: int,
                 world_from_rgbd0: np.ndarray = np.eye(4), *, timed: Callable[[str], Any] | None = None):
        import open3d as o3d

        # Open3D warns on every frame (range map reallocation, frame id jumps): errors still come as exceptions
        o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
        self.o3d, self.params, self.timed = o3d, params, timed
        self.n = round(1.0 / params.scale)
        self.width, self.height = width, height
        self.device = o3d.core.Device(DEVICE)
        # copies throughout: Open3D rejects unaligned arrays (zero-copy message buffers can be)
        T0 = np.array(world_from_rgbd0, dtype=np.float64)
        if T0.shape != (4, 4) or not np.all(np.isfinite(T0)):
            raise ProbelessError(f"DenseSlam: initial pose must be a finite 4x4 matrix, got {T0.shape}")
        self.grid_from_world = grid_from_world(params.grid_rotation_deg)
        self.model = o3d.t.pipelines.slam.Model(params.voxel_size, params.block_resolution, params.block_count,
                                                o3d.core.Tensor(self.grid_from_world @ T0), self.device)
        h, w = len(range(0, height, self.n)), len(range(0, width, self.n))
        Ks = scaled_K(K, self.n)
        K_t = o3d.core.Tensor(Ks)
        # Open3D's integration reads pixel (int(u), int(v)) of each voxel's projection, i.e. the pixel
        # half a pixel up-left of the nearest one on average: half a pixel more on the principal
        # point makes it the nearest (the input Frame's intrinsics serve integration only).
        K_int = Ks.copy()
        K_int[:2, 2] += 0.5 if params.integrate_nearest_pixel else 0.0
        self.input = o3d.t.pipelines.slam.Frame(h, w, o3d.core.Tensor(K_int), self.device)
        self.raycast = o3d.t.pipelines.slam.Frame(h, w, K_t, self.device)
        # the raycast carries no colour (point-to-plane tracking ignores it): a placeholder avoids Open3D's warning
        self.raycast.set_data("color", o3d.core.Tensor(np.zeros((h, w, 3), np.float32)))
        self.K, self.K_np = K_t, Ks
        self.criteria = [o3d.t.pipelines.odometry.OdometryConvergenceCriteria(i) for i in params.iterations]
        self.loss = o3d.t.pipelines.odometry.OdometryLossParams(params.depth_diff)
        self.odometry = o3d.t.pipelines.odometry.rgbd_odometry_multi_scale  # a seam for tests
        self.method = o3d.t.pipelines.odometry.Method.PointToPlane
        self._depth: np.ndarray | None = None  # the loaded frame's depth (uint16, tracking resolution)
        self.pose = T0                  # last good world_from_rgbd
        self.raycast_pose = T0          # pose the raycast frame was made at
        self.tracked = 0                # frames tracked (including the first)
        self.integrated = 0             # frames integrated into the model
        self.since_good = 0             # frames since the last good one
        self.calls = 0                  # frames fed (the time base without stamps)
        self.good: deque = deque(maxlen=2)  # (time, pose) of the last good frames, for the motion prediction
        self.block_stamps = BlockStamps(params.voxel_size, params.block_resolution)  # last fusion per voxel block
        self.stamp = 0                  # the current frame's stamp (stamp_ns, else the call count)
        self.fused_stamp = 0            # stamp of the last frame integrated

    def release(self) -> None:
        """Free the Open3D model and frames now. Open3D checks for unfreed memory when the process
        exits and turns the exit status into 1 if any is left (objects still referenced at exit)."""
        self.model = self.input = self.raycast = None

    @property
    def initialized(self) -> bool:
        return self.tracked > 0

    def _prepare(self, rgb: np.ndarray, depth: np.ndarray, depth_scale: float) -> str:
        """Load the frame into the input Frame; returns "" or why the input is unusable."""
        why, depth, rgb = prepare_frame(rgb, depth, depth_scale, self.width, self.height, self.n, self.params)
        if not why:
            Image, Tensor = self.o3d.t.geometry.Image, self.o3d.core.Tensor
            self.input.set_data_from_image("depth", Image(Tensor(depth)))
            self.input.set_data_from_image("color", Image(Tensor(rgb)))
            self._depth = depth  # for the weighted refinement
        return why

    def _track(self, depth_scale: float, guess: np.ndarray) -> tuple[np.ndarray | None, str, float]:
        """(world_from_rgbd or None, reason, fitness) of the loaded frame against the raycast, ICP
        started at ``guess`` (world_from_rgbd). What ``Model.track_frame_to_model`` does, which
        always starts at the raycast pose."""
        p, o3d = self.params, self.o3d
        init = np.linalg.inv(self.raycast_pose) @ guess
        try:
            r = self.odometry(
                o3d.t.geometry.RGBDImage(self.input.get_data_as_image("color"), self.input.get_data_as_image("depth")),
                o3d.t.geometry.RGBDImage(self.raycast.get_data_as_image("color"),
                                         self.raycast.get_data_as_image("depth")),
                self.K, o3d.core.Tensor(init), depth_scale, p.depth_max, self.criteria, self.method, self.loss)
        except RuntimeError as exc:  # "Singular 6x6 linear system" and other solver failures
            return None, f"tracking failed: {open3d_message(exc)}", float("nan")
        rel = r.transformation.cpu().numpy()
        if p.depth_weighting and np.all(np.isfinite(rel)):
            rel = self._refine(rel, depth_scale)
        T = self.raycast_pose @ rel
        if not np.all(np.isfinite(T)):
            return None, "tracking gave a non-finite pose", r.fitness
        if r.fitness < p.min_fitness:
            return None, f"fitness {r.fitness:.2f} < {p.min_fitness}", r.fitness
        dt, dr = motion(guess, T)
        k = self.since_good + 1
        if dt > p.max_translation_m * k or dr > p.max_rotation_deg * k:
            return None, f"implausible motion {dt:.3f} m, {dr:.1f} deg from the prediction over {k} frame(s)", r.fitness
        return T, "", r.fitness

    def _refine(self, raycast_from_input: np.ndarray, depth_scale: float) -> np.ndarray:
        """Open3D's estimate refined with each point weighted by its depth noise (:mod:`.weighted_icp`)."""
        p = self.params
        src = self._depth.astype(np.float32) / depth_scale
        src[(src > p.depth_max) | (src < p.depth_min)] = 0.0
        tgt = self.raycast.get_data_as_image("depth").as_tensor().numpy().reshape(src.shape) / np.float32(depth_scale)
        T, _ = refine_point_to_plane(src, tgt, self.K_np, raycast_from_input, sigma=p.depth_sigma,
                                     iterations=p.refine_iterations, max_distance=p.depth_diff, step=p.refine_step)
        return T

    def predicted(self, t: float) -> np.ndarray:
        """Pose expected at time ``t`` from the last two good poses (constant velocity)."""
        if len(self.good) < 2:
            return self.pose
        (t0, T0), (t1, T1) = self.good
        return predict_pose(T0, t0, T1, t1, t)

    def _track_from_guesses(self, depth_scale: float, t: float) -> tuple[np.ndarray | None, str, float]:
        """Track from the constant-velocity prediction, then (if that fails) from the last good pose."""
        pred = self.predicted(t)
        T, why, fitness = self._track(depth_scale, pred)
        if T is None and not np.allclose(pred, self.pose):
            T2, why2, fitness2 = self._track(depth_scale, self.pose)
            if T2 is not None:
                return T2, why2, fitness2
        return T, why, fitness

    @contextlib.contextmanager
    def _stage(self, name: str, costs: dict):
        """Time a stage into ``costs`` [ms] (and into the caller's ``timed`` hook, e.g. node diagnostics)."""
        t = time.perf_counter()
        with self.timed(name) if self.timed else contextlib.nullcontext():
            yield
        costs[name] = (time.perf_counter() - t) * 1e3

    def _map(self, T: np.ndarray, depth_scale: float, costs: dict) -> None:
        """Integrate and/or raycast the tracked frame at pose T, as due."""
        p, o3c = self.params, self.o3d.core
        Tg = self.grid_from_world @ T  # the model lives in grid coordinates
        self.model.update_frame_pose(self.tracked, o3c.Tensor(Tg))
        if self.tracked % p.integrate_every == 0:
            with self._stage("integrate", costs):
                self.model.integrate(self.input, depth_scale, p.depth_max, p.trunc_voxel_multiplier)
                # the blocks this integration updated (Open3D keeps them for the raycast): < 1 ms
                self.block_stamps.touch(self.model.frustum_block_coords.cpu().numpy(), self.stamp)
            self.integrated += 1
            self.fused_stamp = self.stamp
        if self.tracked % p.raycast_every == 0:
            with self._stage("raycast", costs):
                if p.raycast_shift:
                    self.model.transformation_frame_to_world = o3c.Tensor(raycast_pose(Tg, p.voxel_size))
                # Open3D's default weight threshold min(frame id, 3) assumes one integration per frame
                self.model.synthesize_model_frame(self.raycast, depth_scale, p.depth_min, p.depth_max,
                                                  p.trunc_voxel_multiplier, False, float(min(self.integrated - 1, 3)))
            self.raycast_pose = T

    def step(self, rgb: np.ndarray, depth_uint16: np.ndarray, depth_scale: float,
             stamp_ns: int | None = None) -> StepResult:
        """Track one frame and update the model (see the module docstring); never raises on bad data.

        ``stamp_ns`` (capture time) lets the motion prediction account for frames skipped in between
        and stamps the voxel blocks the frame is fused into; without it frames are taken as equally
        spaced and the call count stands in for the stamp."""
        self.calls += 1
        self.stamp = int(stamp_ns) if stamp_ns is not None else self.calls
        t = float(self.stamp)
        costs: dict[str, float] = {}
        with self._stage("prepare", costs):
            why = self._prepare(rgb, depth_uint16, float(depth_scale))
        if why:
            self.since_good += self.initialized
            return StepResult(None, "invalid_input", why, costs)
        T, fitness = self.pose, float("nan")
        if self.initialized:
            with self._stage("track", costs):
                T, why, fitness = self._track_from_guesses(float(depth_scale), t)
            if T is None:
                self.since_good += 1
                return StepResult(None, "lost", why, costs, fitness)
        self._map(T, float(depth_scale), costs)
        self.pose, self.since_good = T, 0
        self.good.append((t, T))
        self.tracked += 1
        return StepResult(T.copy(), "ok", "", costs, fitness)

    def extraction_threshold(self) -> float:
        """Voxel weight a surface needs to be extracted (:func:`.model_extract.extraction_threshold`)."""
        return extraction_threshold(self.integrated)

    def extract_pointcloud(self, max_points: int | None = None,
                           normals: bool = False) -> tuple[np.ndarray, ...]:
        """(points (N, 3) float32 [m, world], colours (N, 3) float32 0..1), at most ``max_points``; with
        ``normals`` also their unit normals (N, 3) [world] (rows of 0: none)."""
        pts, cols, nrm = extract_pointcloud(self.model, self.extraction_threshold(), max_points)
        return (self._to_world(pts), cols, self._to_world(nrm)) if normals else (self._to_world(pts), cols)

    def fusion_stamps(self, points_world: np.ndarray) -> np.ndarray:
        """(N,) int64: when each point (N, 3) [m, world] of the extracted model was last fused, i.e. the
        stamp of the last frame integrated into its voxel block (:mod:`.block_stamps`; the frames' clock,
        or the call count without stamps). Points in no integrated block get the last fused stamp."""
        G = self.grid_from_world
        pts = np.asarray(points_world, dtype=np.float64).reshape(-1, 3)
        grid = pts if np.array_equal(G, np.eye(4)) else pts @ G[:3, :3].T
        return self.block_stamps.lookup(grid, default=self.fused_stamp)

    def _to_world(self, pts: np.ndarray) -> np.ndarray:
        G = self.grid_from_world
        if np.array_equal(G, np.eye(4)):
            return pts
        return np.ascontiguousarray((pts.astype(np.float64) @ G[:3, :3]).astype(np.float32))  # G^-1 = G^T

    def extract_mesh(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(vertices (V, 3) float32 [m, world], triangles (T, 3) int32, colours (V, 3) float32 0..1)."""
        v, tri, cols = extract_mesh(self.model, self.extraction_threshold())
        return self._to_world(v), tri, cols
