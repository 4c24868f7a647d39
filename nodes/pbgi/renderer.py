"""``pbgi_renderer``: virtual objects relit by the room's point cloud (point-based GI, paper 001 §5), composited into
the RGB frame. It swaps for ``ibl_compositor`` in one ``node:`` line: same ``objects`` / ``objects_file`` /
``material``, same frame inputs, same output.

Inputs: ``cloud`` (``mesh/PointCloud``: the SLAM node's ``model/points`` or ``cloud_file``, uint8 colours sRGB, float
linear; or ``mesh/HdrPointCloud``: ``hdr_expander``'s radiance), ``rgb`` (rgb8) and ``pose`` (world_from_rgb camera,
same stamp; paired exactly), ``camera_info`` (pinhole; distortion ignored), with ``occlusion: true`` ``depth``
(DepthImage registered to rgb, same stamp: real surfaces nearer than an object hide it), and optionally ``envmap``
(``lighting/Cubemap``, routed by ``object_id``: that object's far field instead of the cloud's cubemap).
Output ``image``: the rgb8 frame with the relit objects, one per paired frame.

Each cloud message is the whole cloud and replaces the previous one, but the BSH is rebuilt only for the first
cloud and then for one that has grown by ``min_growth`` since the last build (normals estimated when missing:
:mod:`probeless.pbgi.cloud`). Frames before any cloud (or camera_info) pass through unaugmented and are counted;
empty clouds are skipped and counted. Modes, far fields and ``render_size``: :mod:`probeless.pbgi.relight`.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, replace
from typing import Any

from probeless.errors import ParamError, PbgiError, SchemaError
from probeless.ibl.composite import render_camera
from probeless.ibl.lighting import linear_faces
from probeless.ibl.objects import all_objects, material_problem
from probeless.messages.geometry import PoseStamped
from probeless.messages.lighting import Cubemap
from probeless.messages.mesh import HdrPointCloud, PointCloud
from probeless.messages.sensor import CameraInfo, DepthImage, Image
from probeless.pbgi.bsh import MAX_CLUSTER_RADIUS
from probeless.pbgi.cloud import cloud_arrays
from probeless.pbgi.relight import FAR_FACE, MODES, Relighter, composite_relit, pbgi_objects, pbgi_objects_problem
from probeless.pbgi.render import SUPERSAMPLE
from probeless.runtime import Node, param
from probeless.runtime.oncelog import OnceLog
from probeless.runtime.sync import ExactTimeSync
from probeless.scene.objects_file import objects_file_problem


class PbgiRendererNode(Node):
    """``cloud`` + ``rgb`` + ``pose`` + ``camera_info`` [+ ``depth``, ``envmap``] -> ``image`` (module docstring)."""

    INPUTS = {"cloud": None, "rgb": Image, "pose": PoseStamped, "camera_info": CameraInfo, "depth": DepthImage,
              "envmap": Cubemap}
    OUTPUTS = {"image": Image}

    @dataclass(frozen=True)
    class Params:
        objects: tuple[Any, ...] = param((), check=pbgi_objects_problem,
                                         doc="virtual objects, as ibl_compositor's (probeless.ibl.objects); "
                                             "materials diffuse, metal, mirror or principled")
        objects_file: str = param("", path="file", must_exist=True, check=objects_file_problem,
                                  doc="scene file (its virtual_objects) or objects file, added to `objects`; '' = none")
        material: Any = param(None, check=material_problem,
                              doc="material of objects_file objects that name none; null = mirror")
        variant: str = param("hybrid", choices=("classic", "mipmapped", "hybrid"), doc="micro-buffer traversal")
        micro: int = param(24, choices=(16, 24, 32), doc="micro-buffer side [texels]")
        supersample: int = param(SUPERSAMPLE, choices=(1, 2, 3, 4),
                                 doc="micro-buffer raster texels per texel side (1: the paper's; "
                                     "probeless.pbgi.render)")
        mode: str = param("full", choices=MODES, doc="full: PBGI of the whole cloud; near_field: PBGI within "
                                                      "near_radius, cubemap beyond; envmap: the cubemap only")
        near_radius: float = param(1.0, min=0.01, max=1e3, doc="near_field: radius about each object's centre [m]")
        far_face: int = param(FAR_FACE, min=8, max=1024, doc="far-field cubemap face made from the cloud [texels]")
        exposure: float = param(1.0, min=0.0, max=1e6, doc="cloud units -> RGB camera linear units [-]")
        min_growth: float = param(0.1, min=0.0, max=1e6,
                                  doc="rebuild the BSH only when the cloud grew by this fraction since the last build")
        tc: float = param(0.01, min=0.0, max=1e6, doc="BSH pruning: RMS colour distance below this [cloud units]")
        max_cluster: float = param(MAX_CLUSTER_RADIUS, min=0.0, max=100.0,
                                   doc="BSH pruning: largest cluster radius [m] (probeless.pbgi.bsh)")
        tn: float = param(0.98, min=-1.0, max=1.0, doc="BSH pruning: normal agreement (cos) above this")
        voxel: float = param(0.0, min=0.0, max=10.0,
                             doc="BSH leaf voxel [m]; 0 = 0.45 x the point spacing (bsh.VOXEL_PER_SPACING)")
        render_size: int = param(0, min=0, max=16384, doc="render at most this wide and upscale [px]; 0 = full size")
        near: float = param(0.02, min=1e-4, max=10.0, doc="near clip plane [m]")
        far: float = param(100.0, min=0.1, max=1e5, doc="far clip plane [m]")
        occlusion: bool = param(False, doc="pair a depth input with each frame and hide objects behind real "
                                           "surfaces")

    def setup(self) -> None:
        p = self.params
        self.relighter = Relighter(pbgi_objects(all_objects(p)), mode=p.mode, near_radius=p.near_radius,
                                   far_face=p.far_face, tc=p.tc, tn=p.tn, voxel=p.voxel or None,
                                   max_radius=p.max_cluster, variant=p.variant,
                                   micro=p.micro, supersample=p.supersample, exposure=p.exposure,
                                   near=p.near, far=p.far)
        names = ["rgb", "pose"] + (["depth"] if p.occlusion else [])
        self.sync = ExactTimeSync(names, self._on_frame, on_unmatched=self._unmatched)
        self.info: CameraInfo | None = None
        self.last_points = 0  # points at the last BSH build (0: none yet)
        self.counts: Counter[str] = Counter()
        self.once = OnceLog(self.ctx.log)


    def on_input(self, name: str, msg) -> None:
        if name in ("rgb", "pose") or (name == "depth" and self.params.occlusion):
            self.sync.add(name, msg)
        elif name == "depth":
            raise ParamError("a depth input is wired but occlusion is false", node_id=self.ctx.node_id,
                             key="occlusion")
        elif name == "camera_info":
            if render_camera(msg, "pbgi_renderer"):
                self.once.warning("distortion", "camera_info has distortion coefficients: the render ignores them")
            self.info = msg
        elif name == "cloud":
            self._on_cloud(msg)
        else:  # envmap
            if msg.object_id not in {o.id for o in self.relighter.objects}:
                self.counts[f"unknown_object:{msg.object_id}"] += 1
                return
            self.relighter.set_envmap(msg.object_id, linear_faces(msg.faces, msg.linear))

    def _on_cloud(self, msg) -> None:
        if not isinstance(msg, (PointCloud, HdrPointCloud)):
            raise SchemaError(f"pbgi_renderer: input 'cloud' takes mesh/PointCloud or mesh/HdrPointCloud, got "
                              f"{type(msg).__name__}")
        if len(msg) == 0:  # a SLAM model before its first fusion
            self.counts["empty_clouds"] += 1
            return
        if self.last_points and len(msg) < self.last_points * (1.0 + self.params.min_growth):
            self.counts["clouds_kept_old"] += 1
            return
        try:
            with self.ctx.timed("normals"):
                points, radiance, normals = cloud_arrays(msg, estimate=self.params.mode != "envmap")
            with self.ctx.timed("bsh"):
                report = self.relighter.set_cloud(points, radiance, normals)
        except PbgiError as exc:
            raise SchemaError(f"pbgi_renderer: input 'cloud': {exc}") from None
        self.last_points = len(msg)
        self.counts["bsh_builds"] += 1
        self.ctx.log.info("cloud of %d points%s", len(msg), "" if report is None else
                          f": BSH of {report.n_nodes_pruned} nodes in {report.total:.2f} s")

    def _unmatched(self, name: str, msg, reason: str) -> None:
        self.counts[f"unpaired_{name}:{reason}"] += 1

    def _on_frame(self, msgs: dict) -> None:
        img, pose = msgs["rgb"], msgs["pose"]
        if img.encoding != "rgb8":
            raise SchemaError(f"pbgi_renderer: input 'rgb': must be rgb8, got {img.encoding!r}")
        if self.info is None or not self.relighter.ready:
            what = "camera_info" if self.info is None else "cloud"
            self.counts[f"no_{what}"] += 1
            self.once.warning(what, f"no {what} yet: frames pass through unaugmented")
            self.ctx.publish("image", img)
            return
        if (self.info.width, self.info.height) != (img.width, img.height):
            raise SchemaError(f"pbgi_renderer: input 'rgb': {img.width}x{img.height}, camera_info says "
                              f"{self.info.width}x{self.info.height}")
        with self.ctx.timed("render"):
            relit = self.relighter.render(self.info.K, pose.target_from_source, img.width, img.height,
                                          self.params.render_size)
        with self.ctx.timed("composite"):
            depth = msgs["depth"].metres() if "depth" in msgs else None
            out = composite_relit(img.data, relit, depth)
        self.counts["frames"] += 1
        self.counts["object_pixels"] += int(relit.mask.sum())
        self.ctx.publish("image", replace(img, data=out))

    def close(self) -> None:
        if hasattr(self, "sync"):
            self.sync.flush()
            self.ctx.log.info("pbgi renderer: %s", dict(sorted(self.counts.items())))
        if getattr(self, "relighter", None) is not None:
            self.relighter.release()
            self.relighter = None
