"""``cloud_views``: a virtual camera over a point cloud file -- frames of a scan that has no RGB frames of its own.

Reads a .ply/.pcd cloud (:func:`probeless.pbgi.cloud.read_cloud_file`: sRGB colours, or an HDR PLY), and publishes
``frames`` views of it splatted with :class:`~probeless.hdr.splat.SplatRenderer` from cameras on an arc about
``target`` (:func:`probeless.pbgi.cameras.arc_poses`), one every ``1 / rate_hz`` s after ``delay_s``, then stops, so
the graph ends. Outputs, named like the synthetic rig's, all with the same stamp per frame: ``rgb`` (rgb8: the
linear colours sRGB-encoded, black where no point), ``depth`` (uint16 mm, 0 where no point), ``gt/rgbd_pose``
(world_from_camera, OpenCV axes: exact, it is the virtual camera's) and ``rgbd/camera_info`` (pinhole from
``intrinsics``, an Open3D PinholeCameraIntrinsic JSON, or ``width`` x ``height`` with ``fx`` = ``fy`` = ``focal``,
centred).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from probeless.color import to_srgb8
from probeless.datasets.textfiles import read_open3d_intrinsics
from probeless.hdr.io import CLOUD_SUFFIXES
from probeless.hdr.splat import SplatRenderer, point_spacing
from probeless.messages.geometry import PoseStamped
from probeless.messages.header import Header
from probeless.messages.sensor import CameraInfo, DepthImage, Image
from probeless.pbgi.cameras import arc_poses
from probeless.pbgi.cloud import read_cloud_file
from probeless.runtime import Node, param


def _cloud_suffix_problem(path: str) -> str | None:
    return None if Path(path).suffix.lower() in CLOUD_SUFFIXES else \
        f"{path}: unknown point cloud type, expected one of {CLOUD_SUFFIXES}"


def _nonzero(v) -> str | None:
    return None if np.linalg.norm(np.asarray(v, float)) > 1e-9 else "must not be the zero vector"


class CloudViews(Node):
    """Publishes ``frames`` splatted views of a cloud file along an arc (see the module docstring)."""

    OUTPUTS = {"rgb": Image, "depth": DepthImage, "gt/rgbd_pose": PoseStamped, "rgbd/camera_info": CameraInfo}

    @dataclass(frozen=True)
    class Params:
        path: str = param(path="file", must_exist=True, check=_cloud_suffix_problem,
                          doc="point cloud: .ply or .pcd (colours sRGB, or an HDR PLY)")
        target: tuple[float, ...] = param(length=3, doc="point every camera looks at [m, cloud frame]")
        direction: tuple[float, ...] = param(length=3, check=_nonzero,
                                             doc="from the target towards the middle camera [cloud frame]")
        up: tuple[float, ...] = param((0.0, 0.0, 1.0), length=3, check=_nonzero, doc="image up [cloud frame]")
        distance: float = param(1.2, min=0.05, max=1e3, doc="camera distance from the target [m]")
        arc_deg: float = param(30.0, min=0.0, max=360.0, doc="arc swept about up [deg]")
        frames: int = param(8, min=1, max=100_000, doc="views published, then the node stops")
        rate_hz: float = param(2.0, min=1e-3, max=1000.0, doc="views per second")
        delay_s: float = param(1.0, min=0.0, max=3600.0, doc="wait before the first view (the cloud goes first) [s]")
        intrinsics: str = param("", path="file", must_exist=True, doc="Open3D intrinsics JSON; empty: the below")
        width: int = param(640, min=8, max=8192, doc="image width without intrinsics [px]")
        height: int = param(480, min=8, max=8192, doc="image height without intrinsics [px]")
        focal: float = param(525.0, min=1.0, max=1e5, doc="fx = fy without intrinsics [px]")
        frame_id: str = param("world", doc="frame of the poses (the cloud's)")

    def setup(self) -> None:
        p = self.params
        if p.intrinsics:
            intr, _ = read_open3d_intrinsics(Path(p.intrinsics))
            self.K, self.size = intr.K, (intr.width, intr.height)
        else:
            self.K = np.array([[p.focal, 0, (p.width - 1) / 2], [0, p.focal, (p.height - 1) / 2], [0, 0, 1.0]])
            self.size = (p.width, p.height)
        self.points, self.colors, _ = read_cloud_file(p.path)
        self.spacing = point_spacing(self.points)
        self.poses = arc_poses(p.target, p.direction, p.distance, p.up, p.arc_deg, p.frames)
        self.splat = SplatRenderer()
        self.sent = 0
        self.start_ns: int | None = None
        self.timer = self.ctx.create_timer(1.0 / p.rate_hz, self.tick, name="views")

    def tick(self) -> None:
        """Publish the next view once ``delay_s`` has passed; stop after the last."""
        now = self.ctx.now_ns()
        self.start_ns = now if self.start_ns is None else self.start_ns
        if now - self.start_ns < self.params.delay_s * 1e9:
            return
        pose = self.poses[self.sent]
        with self.ctx.timed("splat"):
            view = self.splat.render(self.points, self.colors, self.spacing, self.K, pose, self.size)
        w, h = self.size
        header = Header(now, "rgb")
        depth_mm = np.clip(np.rint(view.depth * 1000.0), 0, 65535).astype(np.uint16)
        self.ctx.publish("rgbd/camera_info", CameraInfo(header, w, h, "pinhole", self.K))
        self.ctx.publish("depth", DepthImage(header, depth_mm, 1000.0))
        self.ctx.publish("gt/rgbd_pose", PoseStamped(Header(now, self.params.frame_id), "rgb", pose))
        self.ctx.publish("rgb", Image(header, to_srgb8(view.color), "rgb8"))
        self.sent += 1
        if self.sent >= self.params.frames:
            self.timer.cancel()
            self.ctx.stop()

    def close(self) -> None:
        if getattr(self, "splat", None) is not None:
            self.splat.release()
            self.splat.ctx.release()
            self.ctx.log.info("cloud views: %d frame(s) published", self.sent)
