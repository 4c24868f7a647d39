"""``cloud_file``: reads a PLY/PCD point cloud (:func:`probeless.hdr.io.read_cloud`) and publishes it
as a ``mesh/PointCloud`` (float linear colours) every ``1 / rate_hz`` seconds, ``count`` times."""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from probeless.hdr.io import CLOUD_SUFFIXES, read_cloud, require_ldr
from probeless.messages.header import Header
from probeless.messages.mesh import PointCloud
from probeless.runtime import Node, param


def _cloud_type_problem(path: str) -> str | None:
    """The path's rule (a param check): a file type read_cloud reads."""
    suffix = os.path.splitext(path)[1].lower()
    if suffix not in CLOUD_SUFFIXES:
        return f"{path}: unknown point cloud type {suffix!r}, expected one of {CLOUD_SUFFIXES}"
    return None


class CloudFile(Node):
    """Publishes one point cloud file repeatedly on ``cloud`` (see the module docstring)."""

    OUTPUTS = {"cloud": PointCloud}

    @dataclass(frozen=True)
    class Params:
        path: str = param(path="file", must_exist=True, check=_cloud_type_problem,
                          doc="coloured point cloud: .ply (uchar colours sRGB, float linear 0..1) or .pcd (sRGB)")
        rate_hz: float = param(1.0, min=1e-3, max=1000.0, doc="publishing rate [Hz]")
        count: int = param(0, min=0, doc="publish this many times, then stop; 0 = until stopped")
        frame_id: str = param("world", doc="frame_id of the cloud")

    def setup(self) -> None:
        points, colors, normals = read_cloud(self.params.path)
        require_ldr(self.params.path, colors)  # a PointCloud carries LDR colours
        for a in (points, colors) + (() if normals is None else (normals,)):
            a.setflags(write=False)  # the same arrays go out every time
        self.points, self.colors = points, colors
        self.normals = np.zeros((0, 3), np.float32) if normals is None else normals
        self.published = 0
        self.timer = self.ctx.create_timer(1.0 / self.params.rate_hz, self.tick, name="cloud")

    def tick(self) -> None:
        """Publish the cloud once; stop after ``count``."""
        p = self.params
        self.ctx.publish("cloud", PointCloud(Header(self.ctx.now_ns(), p.frame_id), self.points, self.colors,
                                             self.normals))
        self.published += 1
        if p.count and self.published >= p.count:
            self.timer.cancel()
            self.ctx.stop()
