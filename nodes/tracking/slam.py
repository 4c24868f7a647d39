"""Dense SLAM node (paper §4.2): RGB-D frames -> the RGB-D camera pose and a coloured model of the room.

Inputs: ``rgb`` and ``depth`` (paired by identical stamps, or within ``slop_s``), ``camera_info``
(pinhole intrinsics; frames before it are skipped) and optionally ``initial_pose`` (world_from_rgbd
of the first frame: the pose stamped like it, else the latest received; a ground-truth stream
can be wired here, later poses are ignored). With ``wait_for_initial_pose`` the first frames are
held (up to ``HOLD_MAX``, in order) until a pose arrives: the frame stamped like it starts the model
(or, when the pose is newer than every held frame, the newest held frame), earlier frames are
skipped and later ones follow in order, so a pose that loses the race with its frame loses nothing.
Without a pose the ``initial_pose`` param applies.

Outputs: ``pose`` (world_from_rgbd, stamped with the RGB-D frame, only for tracked frames),
``tracking`` (:class:`TrackingState` for every frame processed) and the model, extracted from
the TSDF every ``model_period_s`` when it changed: ``model/points`` (coloured points, at most
``model_max_points``, each with ``stamps_ns``: the stamp of the last RGB-D frame fused into its
voxel block, same clock as the frames; :mod:`probeless.tracking.block_stamps`) and/or ``model/mesh``
(``model_output``).

Keeping up (2 CPU cores, 30 Hz camera): the node cannot process every frame. Run its
``rgb``/``depth`` inputs with ``policy: latest``: it then always works on the newest frame, and
frames it cannot process are dropped before it sees them (counted in ``tracking.frames_dropped``
from header.seq gaps, and by the runtime in diagnostics); a constant-velocity prediction from the
frame stamps bridges the gaps (:meth:`DenseSlam.predicted`). The defaults (half resolution,
mapping every 2nd tracked frame) and the measured rates behind them: docs/tracking/README.md.
Model extraction runs every ``model_period_s`` on the same thread.

Restarted (``restart: on-failure`` after a crash): the map died with the process. The node says so
(a warning at setup, and the reason ``restarted without a map: ...`` on ``tracking`` with the first
frame of the new model) and re-initialises like a first start: from the next ``initial_pose`` (with
``wait_for_initial_pose``; a ground-truth or relocalisation stream keeps the world frame), else from the
``initial_pose`` param, in which case the new map's world frame is the param's, not the lost map's.

A failed frame (solver failure, low fitness, NaN pose, implausible jump, empty or NaN depth) is
reported on ``tracking`` and logged (the first of a run of failures, then every 30th); the model
is not touched and the next frame is tracked from the last good pose (moved on by the motion
prediction). ``trajectory_out`` writes the tracked poses in TUM format (flushed every
``trajectory_flush_s`` and at close).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from probeless.color import quantize8
from probeless.launch.launcher import restart_count
from probeless.messages.diagnostics import TrackingState
from probeless.messages.geometry import PoseStamped
from probeless.messages.header import Header
from probeless.messages.mesh import PointCloud, TriangleMesh
from probeless.messages.sensor import CameraInfo, DepthImage, Image
from probeless.nodes.tracking.slam_io import open_trajectory, pose_param, pose_problem
from probeless.runtime import Node, param
from probeless.runtime.sync import ApproximateTimeSync, ExactTimeSync
from probeless.tracking.dense import DenseSlam, SlamParams
from probeless.tracking.slam_params import GRID_ROTATION_DEG
from probeless.tracking.tum import write_tum_lines
from probeless.tracking.weighted_icp import KINECT_SIGMA


def _sigma_problem(v: tuple[float, ...]) -> str | None:
    """depth_sigma's rule (a param check; length and finiteness are declared): a > 0, b >= 0."""
    return None if v[0] > 0 and v[1] >= 0 else f"needs a b z0, finite, a > 0, b >= 0; got {list(v)}"


def _depth_min_problem(depth_min: float, p) -> str | None:
    """depth_min's rule against depth_max (a param check; SlamParams needs 0 < depth_min < depth_max)."""
    return None if 0 < depth_min < p.depth_max else f"needs 0 < depth_min < depth_max ({p.depth_max}), got {depth_min}"


HOLD_MAX = 30  # first pairs held while camera_info or the initial pose is still on its way
LOG_EVERY = 30  # while tracking stays lost, log one failure in this many


class DenseSlamNode(Node):
    """Open3D tensor SLAM on CPU:0 behind a bus (see the module docstring)."""

    INPUTS = {"rgb": Image, "depth": DepthImage, "camera_info": CameraInfo, "initial_pose": PoseStamped}
    OUTPUTS = {"pose": PoseStamped, "tracking": TrackingState, "model/points": PointCloud, "model/mesh": TriangleMesh}

    @dataclass(frozen=True)
    class Params:
        voxel_size: float = param(0.01, min=0.001, max=0.5, doc="TSDF voxel edge [m]")
        block_count: int = param(10000, min=100, doc="initial voxel-block hash map capacity, grows when full [blocks]")
        depth_max: float = param(3.0, min=0.2, max=20.0, doc="depth used for tracking and mapping [m]")
        depth_min: float = param(0.1, min=0.0, max=10.0, check=_depth_min_problem,
                                 doc="nearest raycast depth [m]; 0 < depth_min < depth_max")
        depth_diff: float = param(0.07, min=0.001, max=1.0, doc="ICP correspondence distance [m]")
        trunc_voxel_multiplier: float = param(8.0, min=1.0, max=64.0, doc="TSDF truncation in voxels")
        scale: float = param(0.5, choices=(1.0, 0.5, 0.25), doc="track and map at this fraction of the resolution")
        integrate_every: int = param(2, min=1, max=100, doc="integrate every k-th tracked frame")
        raycast_every: int = param(2, min=1, max=100, doc="raycast the model every k-th tracked frame")
        min_fitness: float = param(0.3, min=0.0, max=1.0, doc="lower ICP inlier fraction = lost")
        max_translation_m: float = param(0.3, min=0.0, doc="larger motion per frame = lost [m]")
        max_rotation_deg: float = param(30.0, min=0.0, max=180.0, doc="larger rotation per frame = lost [deg]")
        min_valid_fraction: float = param(0.05, min=0.0, max=1.0, doc="less valid depth = invalid input [fraction]")
        grid_rotation_deg: tuple[float, ...] = param(GRID_ROTATION_DEG, length=3, finite=True,
                                                     doc="TSDF grid axes against the world, "
                                                     "xyz Euler [deg] (3 values; see SlamParams)")
        integrate_nearest_pixel: bool = param(True, doc="integrate each voxel from its nearest pixel (Open3D "
                                                        "alone takes the pixel up-left of it)")
        depth_weighting: bool = param(True, doc="refine each pose with points weighted by their depth noise "
                                                "(off for depth whose noise does not grow with distance)")
        depth_sigma: tuple[float, ...] = param(KINECT_SIGMA, length=3, finite=True, check=_sigma_problem,
                                               doc="depth noise sigma(z) = a + b (z - z0)^2 [m]: "
                                               "a b z0 (default Kinect v1)")
        refine_iterations: int = param(10, min=1, max=100, doc="Gauss-Newton steps of the weighted refinement, at most")
        refine_step: int = param(4, min=1, max=64, doc="every n-th pixel in the weighted refinement")
        initial_pose: tuple[float, ...] = param((), length=(0, 7), finite=True, check=pose_problem,
                                                doc="world_from_rgbd of the first frame: tx ty tz qx qy qz qw; "
                                                "empty = identity (or the initial_pose input)")
        wait_for_initial_pose: bool = param(False, doc="skip frames until the initial_pose input has a pose")
        slop_s: float = param(0.0, min=0.0, max=1.0, doc="rgb/depth pairing: 0 = identical stamps, else "
                                                         "nearest within this [s]")
        model_output: str = param("points", choices=("points", "mesh", "both", "none"), doc="model outputs")
        model_period_s: float = param(1.0, min=0.05, max=3600.0, doc="model extraction period (when changed) [s]")
        model_max_points: int = param(200000, min=1, doc="most points on model/points [count]")
        trajectory_out: str = param("", doc="TUM trajectory file of the tracked poses; empty = none")
        trajectory_flush_s: float = param(5.0, min=0.1, doc="how often the trajectory file is flushed [s]")

    def setup(self) -> None:
        p = self.params
        self.slam_params = SlamParams(
            voxel_size=p.voxel_size, block_count=p.block_count, depth_max=p.depth_max, depth_min=p.depth_min,
            depth_diff=p.depth_diff, trunc_voxel_multiplier=p.trunc_voxel_multiplier, scale=p.scale,
            integrate_every=p.integrate_every, raycast_every=p.raycast_every, min_fitness=p.min_fitness,
            max_translation_m=p.max_translation_m, max_rotation_deg=p.max_rotation_deg,
            grid_rotation_deg=tuple(p.grid_rotation_deg),
            integrate_nearest_pixel=p.integrate_nearest_pixel,
            min_valid_fraction=p.min_valid_fraction, depth_weighting=p.depth_weighting,
            depth_sigma=tuple(p.depth_sigma), refine_iterations=p.refine_iterations,
            refine_step=p.refine_step)
        self.T0 = pose_param(p.initial_pose, self.ctx.node_id)
        self.slam: DenseSlam | None = None
        self.info: CameraInfo | None = None
        self.init_poses: dict[int, np.ndarray] = {}
        self.latest_init: np.ndarray | None = None
        self.latest_init_ns: int | None = None  # stamp of latest_init
        self.held: list[dict] = []      # the first pairs, in order, waiting for an initial pose
        self.closed: set[str] = set()   # inputs at end of stream
        self.counts = dict(tracked=0, lost=0, invalid=0, skipped=0, dropped=0, consecutive=0, last_good=0)
        self.last_rgb_seq: int | None = None
        self.model_dirty, self.frame_id = False, "rgbd"
        self.restart_note = self._restart_note(restart_count())
        names = ["rgb", "depth"]
        if p.slop_s > 0:
            self.sync = ApproximateTimeSync(names, self._on_pair, round(p.slop_s * 1e9), on_unmatched=self._unmatched)
        else:
            self.sync = ExactTimeSync(names, self._on_pair, on_unmatched=self._unmatched)
        self.traj = open_trajectory(p.trajectory_out, self.ctx.node_id) if p.trajectory_out else None
        if self.traj:
            self.ctx.create_timer(p.trajectory_flush_s, self.traj.flush, name="trajectory_flush")
        if p.model_output != "none":
            self.ctx.create_timer(p.model_period_s, self._publish_model, name="model")

    def _restart_note(self, restarts: int) -> str:
        """Warn that a restarted process lost the map; the note goes with the first frame of the new model."""
        if not restarts:
            return ""
        source = ("the next initial_pose" if self.params.wait_for_initial_pose
                  else "the initial_pose param (the lost map's world frame is not kept)")
        note = f"restarted without a map (restart {restarts}): re-initialised from {source}"
        held = "; frames are held until then" if self.params.wait_for_initial_pose else ""
        self.ctx.log.warning("%s%s", note.replace("re-initialised", "re-initialising"), held)
        return note

    def on_input(self, name: str, msg) -> None:
        if name == "camera_info":
            self.info = msg
            if self.slam is None:
                self._release_held()
        elif name == "initial_pose":
            self._on_initial_pose(msg)
        else:
            if name == "rgb":
                seq = msg.header.seq
                if self.last_rgb_seq is not None and seq > self.last_rgb_seq + 1:
                    self.counts["dropped"] += seq - self.last_rgb_seq - 1
                self.last_rgb_seq = seq
            self.sync.add(name, msg)

    def _on_initial_pose(self, msg: PoseStamped) -> None:
        if self.slam is not None:
            return  # the pose of the first frame only; later ones (a ground-truth stream) are ignored
        stamp = msg.header.stamp_ns
        self.latest_init = msg.target_from_source
        self.init_poses[stamp] = msg.target_from_source
        while len(self.init_poses) > 256:
            self.init_poses.pop(next(iter(self.init_poses)))
        self.latest_init_ns = stamp
        self._release_held()

    def _waiting(self, pair: dict) -> bool:
        """True while the model cannot start at ``pair``: no camera_info yet, or no initial pose for it yet."""
        if self.info is None:
            return True
        t = pair["rgb"].header.stamp_ns
        newer_pose = self.latest_init_ns is not None and self.latest_init_ns >= t
        return self.params.wait_for_initial_pose and t not in self.init_poses and not newer_pose

    def _release_held(self) -> None:
        """Process the held pairs in order once the model can start; the rest stay held."""
        held, self.held = self.held, []
        for k, pair in enumerate(held):
            if self.slam is None:
                if self._waiting(pair):
                    self.held = held[k:]
                    return
                t = pair["rgb"].header.stamp_ns
                if (self.params.wait_for_initial_pose and t not in self.init_poses
                        and any(h["rgb"].header.stamp_ns <= self.latest_init_ns for h in held[k + 1:])):
                    self._skip(pair["rgb"].header, "a later frame is nearer the initial pose")
                    continue
            self._on_pair(pair)  # starts the model (own pose, the nearest newer one, or the param), then tracks

    def _unmatched(self, name: str, msg, reason: str) -> None:
        if name == "rgb":
            self.counts["skipped"] += 1

    def _skip(self, header: Header, reason: str) -> None:
        self.counts["skipped"] += 1
        self._publish_state(header, "initializing", reason, float("nan"), 0.0)

    def _start(self, msgs: dict) -> bool:
        """Create the SLAM model at the first usable frame; False (frame skipped or held) until it can."""
        rgb, info, p = msgs["rgb"], self.info, self.params
        if self._waiting(msgs):
            self.held.append(msgs)  # its camera_info or pose may come just after it
            if len(self.held) > HOLD_MAX:
                self._skip(self.held.pop(0)["rgb"].header,
                           "no camera_info yet" if info is None else "waiting for initial_pose")
            return False
        if info.model != "pinhole" or (info.width, info.height) != (rgb.width, rgb.height):
            self._skip(rgb.header, f"camera_info is {info.model} {info.width}x{info.height}, need pinhole "
                                   f"{rgb.width}x{rgb.height}")
            return False
        T0 = self.init_poses.get(rgb.header.stamp_ns)
        T0 = T0 if T0 is not None else self.latest_init if self.latest_init is not None else self.T0
        self.slam = DenseSlam(self.slam_params, info.K, info.width, info.height, T0, timed=self.ctx.timed)
        self.frame_id = rgb.header.frame_id or "rgbd"
        self.ctx.log.info("SLAM started at stamp %d, %dx%d at scale %g", rgb.header.stamp_ns, info.width,
                          info.height, p.scale)
        return True

    def _on_pair(self, msgs: dict) -> None:
        rgb, depth = msgs["rgb"], msgs["depth"]
        if self.slam is None and not self._start(msgs):
            return
        t0 = time.perf_counter()
        r = self.slam.step(rgb.data, depth.data, depth.depth_scale, rgb.header.stamp_ns)
        step_ms = (time.perf_counter() - t0) * 1e3
        c, stamp = self.counts, rgb.header.stamp_ns
        if r.state == "ok":
            if c["consecutive"]:
                self.ctx.log.info("tracking resumed at %d after %d failed frame(s)", stamp, c["consecutive"])
            c["tracked"] += 1
            c["consecutive"], c["last_good"] = 0, stamp
            self.model_dirty = True
            self.ctx.publish("pose", PoseStamped(Header(stamp, "world"), self.frame_id, r.world_from_rgbd))
            if self.traj:
                write_tum_lines(self.traj, [stamp], [r.world_from_rgbd])
        else:
            c["lost" if r.state == "lost" else "invalid"] += 1
            c["consecutive"] += 1
            if c["consecutive"] % LOG_EVERY == 1:  # the first failure, then every LOG_EVERY-th
                self.ctx.log.warning("frame %d: %s (%s); %d failed in a row", stamp, r.state, r.reason,
                                     c["consecutive"])
        reason, self.restart_note = "; ".join(filter(None, (self.restart_note, r.reason))), ""
        self._publish_state(rgb.header, r.state, reason, r.fitness, step_ms)

    def _publish_state(self, header: Header, state: str, reason: str, fitness: float, step_ms: float) -> None:
        c = self.counts
        self.ctx.publish("tracking", TrackingState(
            Header(header.stamp_ns, header.frame_id), state, reason, c["tracked"], c["lost"], c["invalid"],
            c["skipped"], c["dropped"], c["consecutive"], c["last_good"], fitness, step_ms))

    def _publish_model(self) -> None:
        if self.slam is None or not self.model_dirty:
            return
        self.model_dirty = False
        header, out = Header(self.counts["last_good"], "world"), self.params.model_output
        if out in ("points", "both"):
            with self.ctx.timed("extract_points"):
                pts, cols, normals = self.slam.extract_pointcloud(self.params.model_max_points, normals=True)
                stamps = self.slam.fusion_stamps(pts)
            self.ctx.publish("model/points", PointCloud(header, pts, quantize8(cols), normals=normals,  # sRGB 0..1
                                                        stamps_ns=stamps))
        if out in ("mesh", "both"):
            with self.ctx.timed("extract_mesh"):
                v, tri, cols = self.slam.extract_mesh()
            self.ctx.publish("model/mesh", TriangleMesh(header, v, tri, vertex_colors=quantize8(cols)))

    def on_input_closed(self, name: str) -> None:
        self.closed.add(name)
        if {"rgb", "depth"} <= self.closed:  # not before: the other input may still hold this frame's partner
            self.sync.flush()
        if name == "initial_pose" and self.held and self.slam is None and self.params.wait_for_initial_pose:
            waiting, self.held = self.held, []
            for pair in waiting:
                self._skip(pair["rgb"].header, "initial_pose ended before a pose arrived")

    def close(self) -> None:
        for pair in getattr(self, "held", ()):
            self._skip(pair["rgb"].header, "still waiting for camera_info or initial_pose at the end")
        self.held = []
        if getattr(self, "slam", None) is not None:
            if self.params.model_output != "none":
                self._publish_model()  # the final model, whatever the period
            self.slam.release()
            self.slam = None
        if getattr(self, "traj", None):
            self.traj.close()
        if hasattr(self, "counts"):
            self.ctx.log.info("SLAM: %s", ", ".join(f"{k}={v}" for k, v in self.counts.items() if k != "last_good"))
