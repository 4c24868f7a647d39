"""Baseline environment-map node (paper §5.3): a drop-in swap for the cubemap renderer.

Each undistorted fisheye frame and its pose (same stamp) are pasted into one accumulating cubemap,
rotation only (see :mod:`probeless.envmap.baseline`). The map ignores translation, so every object
gets the same faces; the object's position only labels the message. Objects as in the cubemap
renderer: ``objects_file``, ``object_ids`` / ``object_positions`` params, and an ``object_poses`` PoseStamped
whose ``child_frame_id`` is an object id moves it (an unknown id adds one). Outputs ``envmap/<id>``
(``Cubemap``, ``linear = False``: camera LDR, uint8 0..255 or float 0..1) under the cubemap
renderer's names (and every object on ``envmaps`` / ``shs``), with its ``object_*`` and ``face_size`` / ``dtype``
params, so consumers need no change; ``Cubemap.observed`` marks the texels some fisheye frame covered.
It also publishes ``sh/<id>`` (SH of the map linearised with the sRGB curve, as the renderer does) and
accepts the renderer's inputs (``floorplan``, ``atlas``, ``points``, ``dense_mesh``, ``delta``, ignored,
counted), and the renderer accepts the fisheye inputs: an envmap node wired with both sets swaps
with a one-line ``node:`` change (``launch/probeless.yaml``'s ``envmap_node`` arg; ``launch/baseline.yaml``).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import numpy as np

from probeless.cameras import model_from_info
from probeless.color import srgb_to_linear
from probeless.envmap.baseline import BaselineMap
from probeless.envmap.objects import (
    move_object,
    node_objects,
    object_ids_problem,
    object_positions_problem,
    write_nets,
)
from probeless.envmap.sh import project_cubemap
from probeless.messages.geometry import Floorplan, PoseStamped
from probeless.messages.header import Header
from probeless.messages.lighting import BrightnessDelta, Cubemap, SHCoefficients
from probeless.messages.mesh import PointCloud, TriangleMesh
from probeless.messages.sensor import CameraInfo, Image
from probeless.runtime import Node, param
from probeless.runtime.sync import ExactTimeSync
from probeless.scene.objects_file import objects_file_problem


def _encode(faces: np.ndarray, dtype: str) -> np.ndarray:
    f = np.clip(faces, 0.0, 1.0)
    return (f * 255.0 + 0.5).astype(np.uint8) if dtype == "uint8" else f.astype(dtype)


class BaselineEnvmap(Node):
    """``fisheye`` + ``fisheye_pose`` (+ ``camera_info``) -> ``envmap/<id>`` for every object."""

    INPUTS = {"fisheye": Image, "fisheye_pose": PoseStamped, "camera_info": CameraInfo, "object_poses": PoseStamped,
              # the cubemap renderer's inputs, accepted so the two nodes swap by their node: line alone
              "floorplan": Floorplan, "atlas": Image, "points": PointCloud, "dense_mesh": TriangleMesh,
              "delta": BrightnessDelta}
    IGNORED = ("floorplan", "atlas", "points", "dense_mesh", "delta")
    OUTPUTS = {"envmap/*": Cubemap, "sh/*": SHCoefficients, "envmaps": Cubemap, "shs": SHCoefficients}

    @dataclass(frozen=True)
    class Params:
        objects_file: str = param("", path="file", must_exist=True, check=objects_file_problem,
                                  doc="scene file (its virtual_objects) or objects file; '' = only the params below")
        object_ids: tuple[str, ...] = param((), check=object_ids_problem,
                                            doc="virtual objects to publish an environment map for")
        object_positions: tuple[tuple[float, ...], ...] = param((), check=object_positions_problem,
                                                                doc="[x, y, z] per object id [m, world]; only "
                                                                    "labels the message")
        face_size: int = param(256, min=1, max=4096, doc="cubemap face size [texels]")
        fov_deg: float = param(183.0, min=1.0, max=359.0, doc="directions beyond fov/2 off the fisheye axis are "
                                                               "not written [deg]")
        publish_every: int = param(1, min=1, max=100000, doc="publish the maps every n-th frame [count]")
        dtype: str = param("uint8", choices=("uint8", "float16", "float32"), doc="face type: uint8 0..255 or "
                                                                                 "float 0..1 (camera LDR)")
        dense: bool = param(False, doc="baseline + dense: draw the dense model (points input, needs floorplan) on top")
        net_dir: str = param("", doc="write the final map of each object as <net_dir>/cubemap_net_<id>.png; '' = none")
        alpha: bool = param(False, doc="add an alpha channel: 255 (1.0) where observed, 0 never observed")

    def setup(self) -> None:
        p = self.params
        self.objects = node_objects(p.objects_file, p.object_ids, p.object_positions, self.ctx.node_id)
        self.sync = ExactTimeSync(["fisheye", "fisheye_pose"], self._on_pair, on_unmatched=self._unmatched)
        self.map: BaselineMap | None = None
        self.counts: Counter[str] = Counter()
        self.overlay = None          # DenseOverlay once a floorplan arrived (dense: true)
        self.points = None           # the newest dense model (PointCloud)
        self.last_faces: dict[str, np.ndarray] = {}

    def on_input(self, name: str, msg) -> None:
        if self.params.dense and name in ("floorplan", "points"):
            self._on_dense_input(name, msg)
        elif name in self.IGNORED:
            self.counts[f"ignored:{name}"] += 1
        elif name == "camera_info":
            model = model_from_info(msg)
            if self.map is None:
                self.map = BaselineMap(self.params.face_size, model, self.params.fov_deg)
            else:
                self.map.model = model  # the direction table does not depend on the camera
        elif name == "object_poses":
            move_object(self.objects, msg, self.counts)
        else:
            self.sync.add(name, msg)

    def _on_dense_input(self, name: str, msg) -> None:
        from probeless.envmap.overlay import DenseOverlay

        if name == "floorplan" and self.overlay is None:
            self.overlay = DenseOverlay(msg.vertices, msg.ceiling_height)
        elif name == "points":
            self.points = msg
        if self.overlay is not None and self.points is not None:
            self.overlay.set_points(self.points.points, self.points.colors)

    def _unmatched(self, name: str, msg, reason: str) -> None:
        self.counts[f"unpaired_{name}:{reason}"] += 1

    def _on_pair(self, msgs: dict) -> None:
        if self.map is None:
            self.counts["no_camera_info"] += 1
            return
        img, pose = msgs["fisheye"], msgs["fisheye_pose"]
        with self.ctx.timed("update"):
            self.map.update(img.data, pose.target_from_source)
        self.counts["applied"] += 1
        if self.map.frames % self.params.publish_every == 0:
            self._publish(Header(img.header.stamp_ns, "world"))

    def _publish(self, header: Header) -> None:
        p = self.params
        with self.ctx.timed("publish"):
            faces = self.map.faces_as(p.dtype, p.alpha)  # shared by every object's message (read-only)
            observed = self.map.observed() if hasattr(self.map, "observed") else np.zeros((0, 0, 0), bool)
            coeffs = project_cubemap(srgb_to_linear(np.clip(self.map.faces, 0, 1)), 5).astype(np.float32)
            for oid, position in self.objects.items():
                obj_faces, obj_coeffs = faces, coeffs
                if self.overlay is not None and self.points is not None:  # baseline + dense: per object
                    ldr, _ = self.overlay.over(self.map.faces, position)
                    self.last_faces[oid] = ldr
                    obj_faces = _encode(ldr, p.dtype)
                    obj_coeffs = project_cubemap(srgb_to_linear(np.clip(ldr, 0, 1)), 5).astype(np.float32)
                cube = Cubemap(header, oid, position, obj_faces, linear=False, observed=observed)
                sh = SHCoefficients(header, oid, 5, obj_coeffs)
                for envmap_out, sh_out in ((f"envmap/{oid}", f"sh/{oid}"), ("envmaps", "shs")):
                    self.ctx.publish(envmap_out, cube)
                    self.ctx.publish(sh_out, sh)

    def close(self) -> None:
        if getattr(self, "map", None) is not None and self.params.net_dir:
            write_nets({oid: self.last_faces.get(oid, self.map.faces) for oid in self.objects}, self.params.net_dir)
        if getattr(self, "overlay", None) is not None:
            self.overlay.release()
        if hasattr(self, "sync"):
            self.sync.flush()
            self.ctx.log.info("baseline envmap: %s", dict(sorted(self.counts.items())))
