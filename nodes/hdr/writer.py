"""``hdr_cloud_writer``: writes each ``mesh/HdrPointCloud`` on ``cloud`` to a PLY file
(:func:`probeless.hdr.io.write_hdr_ply`: float32 linear, unbounded radiance); a later cloud replaces
the file, so it holds the last one."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from probeless.hdr.io import write_hdr_ply
from probeless.messages.mesh import HdrPointCloud
from probeless.runtime import Node, param
from probeless.runtime.params import writable_file_problem


class HdrCloudWriter(Node):
    """Writes the latest ``cloud`` to ``path`` (see the module docstring)."""

    INPUTS = {"cloud": HdrPointCloud}

    @dataclass(frozen=True)
    class Params:
        path: str = param(check=writable_file_problem,
                          doc="output .ply file (parent folders are created; rewritten by each cloud)")

    def setup(self) -> None:
        Path(self.params.path).parent.mkdir(parents=True, exist_ok=True)
        self.written = 0

    def on_input(self, name: str, msg: HdrPointCloud) -> None:
        with self.ctx.timed("write"):
            write_hdr_ply(self.params.path, msg.points, msg.radiance, msg.normals if len(msg.normals) else None)
        self.written += 1

    def close(self) -> None:
        if getattr(self, "written", 0):
            self.ctx.log.info("wrote %s (%d cloud(s))", self.params.path, self.written)
