"""IBL compositor node (paper §4.8): virtual objects lit by their envmaps, composited into the RGB frame.

Objects: the ``objects_file`` param (a scene file's ``virtual_objects``, or an objects file:
:mod:`probeless.scene.objects_file`; objects without a material get ``material``) and the ``objects`` list.

Inputs: ``rgb`` (rgb8) and ``pose`` (world_from_rgb camera, same stamp; paired exactly),
``camera_info`` (pinhole; distortion is ignored), and the lighting of each object: ``envmap``
(Cubemap) and ``sh`` (SHCoefficients), e.g. an envmap node's ``envmaps`` / ``shs`` (every object on one
topic). Any further input whose name starts with ``envmap`` or
``sh`` (e.g. ``envmap_teapot``) is treated the same way, so one input can be wired per object
topic; messages are routed by their ``object_id`` and the latest one per object is used.

``sh_from: envmap`` projects the SH from the envmap here instead of waiting for ``sh``.
Shading (:mod:`probeless.ibl.render`): diffuse from the SH; specular GGX (alpha = roughness²) with Schlick Fresnel
(f0 = a metal's colour, or 0.04 / the base colour by metalness), the DFG term and Filament's multiple-scattering
compensation, from the GGX-prefiltered chain the renderer builds from the envmap's faces (the message's box ``mips``
are not used) plus the map's brightest texels as exact lights; mirrors, glass and smooth lobes antialiased. Its
agreement with Mitsuba 3: ``probeless eval ibl`` (docs/ibl/eval_ibl.md).
``exposure`` maps the envmap's linear units to the RGB camera's: for an LDR envmap (the fisheye's
sRGB output) it is rgb exposure / fisheye exposure; for linear radiance the RGB exposure.
With ``occlusion: true`` a ``depth`` input (DepthImage registered to rgb, same stamp) is paired
too, and real surfaces nearer than an object hide it.
Output ``image``: the augmented rgb8 frame, one per paired frame (objects without lighting yet are
left out and counted).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, replace
from typing import Any

from probeless.errors import ParamError, SchemaError
from probeless.ibl.composite import composite, render_camera
from probeless.ibl.lighting import lighting_from_messages
from probeless.ibl.objects import all_objects, material_problem, object_from_dict, objects_problem
from probeless.ibl.render import AA_SAMPLES, LOBES, SPEC_SAMPLES, IblRenderer
from probeless.messages.geometry import PoseStamped
from probeless.messages.lighting import Cubemap, SHCoefficients
from probeless.messages.sensor import CameraInfo, DepthImage, Image
from probeless.runtime import Node, param
from probeless.runtime.oncelog import OnceLog
from probeless.runtime.sync import ExactTimeSync
from probeless.scene.objects_file import objects_file_problem


class IblCompositor(Node):
    """``rgb`` + ``pose`` + ``camera_info`` + ``envmap``/``sh`` per object -> ``image``."""

    INPUTS = {"rgb": Image, "pose": PoseStamped, "camera_info": CameraInfo, "envmap": Cubemap,
              "sh": SHCoefficients, "depth": DepthImage, "*": None}
    OUTPUTS = {"image": Image}

    @dataclass(frozen=True)
    class Params:
        objects: tuple[Any, ...] = param((), check=objects_problem,
                                         doc="virtual objects: list of {id, mesh, position, radius|scale, "
                                             "yaw_deg, up, anchor, material: {type, ...}, contact_shadow} "
                                             "(see probeless.ibl.objects)")
        objects_file: str = param("", path="file", must_exist=True, check=objects_file_problem,
                                  doc="scene file (its virtual_objects) or objects file, added to `objects`; '' = none")
        material: Any = param(None, check=material_problem,
                              doc="material of objects_file objects that name none, e.g. {type: mirror}; "
                                  "null = mirror")
        exposure: float = param(1.0, min=0.0, max=1e6, doc="envmap linear units -> RGB camera linear units [-]")
        sh_from: str = param("topic", choices=("topic", "envmap"), doc="SH from the sh input, or projected "
                                                                       "from the envmap here")
        near: float = param(0.02, min=1e-4, max=10.0, doc="near clip plane [m]")
        far: float = param(50.0, min=0.1, max=1e5, doc="far clip plane [m]")
        occlusion: bool = param(False, doc="pair a depth input with each frame and hide objects behind real "
                                           "surfaces")
        lobe: str = param("hybrid", choices=LOBES,
                          doc="specular lobe: hybrid = importance-sampled with the brightest texels as lights "
                              "(agrees with Mitsuba, docs/ibl/eval_ibl.md); split_sum = GGX-prefiltered chain + "
                              "DFG, one lookup per pixel (fastest, 0.10-0.26 off at roughness 0.2-0.8); "
                              "sampled = importance sampling of the whole map; texel_sum = exact sums over a small mip "
                              "level (slow references)")
        spec_samples: int = param(SPEC_SAMPLES, min=1, max=4096,
                                  doc="least lookups per pixel of a rough specular lobe (hybrid; more where the "
                                      "pixel's footprint covers more map texels, up to 2048) [count]")
        aa_samples: int = param(AA_SAMPLES, min=1, max=1024,
                                doc="least lookups spread over each pixel for mirror and smooth lobes (more with the "
                                    "footprint, as spec_samples); glass uses exactly this many [count]")

    def setup(self) -> None:
        p = self.params
        objects = [object_from_dict(o, f"objects[{i}]") for i, o in enumerate(all_objects(p))]  # checked at load
        self.renderer = IblRenderer(objects, exposure=p.exposure, near=p.near, far=p.far, lobe=p.lobe,
                                    spec_samples=p.spec_samples, aa_samples=p.aa_samples)
        names = ["rgb", "pose"] + (["depth"] if p.occlusion else [])
        self.sync = ExactTimeSync(names, self._on_frame, on_unmatched=self._unmatched)
        self.info: CameraInfo | None = None
        self.envmaps: dict[str, Cubemap] = {}
        self.shs: dict[str, SHCoefficients] = {}
        self.dirty: set[str] = set()
        self.counts: Counter[str] = Counter()
        self.once = OnceLog(self.ctx.log)


    def on_input(self, name: str, msg) -> None:
        if name in ("rgb", "pose") or (name == "depth" and self.params.occlusion):
            self.sync.add(name, msg)
        elif name == "camera_info":
            if render_camera(msg, "ibl_compositor"):
                self.once.warning("distortion", "camera_info has distortion coefficients: the render ignores them")
            self.info = msg
        elif name == "depth":
            raise ParamError("a depth input is wired but occlusion is false", node_id=self.ctx.node_id,
                             key="occlusion")
        elif name.startswith("envmap") and isinstance(msg, Cubemap):
            self._lighting(msg.object_id, self.envmaps, msg)
        elif name.startswith("sh") and isinstance(msg, SHCoefficients):
            self._lighting(msg.object_id, self.shs, msg)
        else:
            raise SchemaError(f"ibl_compositor: input {name!r} got a {type(msg).__name__} (envmap* inputs take "
                              f"Cubemap, sh* inputs SHCoefficients)")

    def _lighting(self, object_id: str, store: dict, msg) -> None:
        if object_id not in self.renderer.objects:
            self.counts[f"unknown_object:{object_id}"] += 1
            return
        store[object_id] = msg
        self.dirty.add(object_id)

    def _unmatched(self, name: str, msg, reason: str) -> None:
        self.counts[f"unpaired_{name}:{reason}"] += 1

    def _update_lighting(self) -> None:
        for oid in sorted(self.dirty):
            env = self.envmaps.get(oid)
            sh = self.shs.get(oid) if self.params.sh_from == "topic" else None
            if env is None or (self.params.sh_from == "topic" and sh is None):
                continue  # wait for the other half
            with self.ctx.timed("upload"):
                self.renderer.set_lighting(oid, lighting_from_messages(env, sh))
            self.dirty.discard(oid)

    def _on_frame(self, msgs: dict) -> None:
        img, pose = msgs["rgb"], msgs["pose"]
        if img.encoding != "rgb8":
            raise SchemaError(f"ibl_compositor: rgb must be rgb8, got {img.encoding!r}")
        if self.info is None:
            self.counts["no_camera_info"] += 1
            self.once.warning("info", "no camera_info yet: frames pass through unaugmented")
            self.ctx.publish("image", img)
            return
        if (self.info.width, self.info.height) != (img.width, img.height):
            raise SchemaError(f"ibl_compositor: rgb is {img.width}x{img.height}, camera_info says "
                              f"{self.info.width}x{self.info.height}")
        self._update_lighting()
        with self.ctx.timed("render"):
            result = self.renderer.render(self.info.K, pose.target_from_source, img.width, img.height)
        for oid in result.missing:
            self.counts[f"unlit:{oid}"] += 1
        with self.ctx.timed("composite"):
            depth = msgs["depth"].metres() if "depth" in msgs else None
            out = composite(img.data, result, depth)
        self.counts["frames"] += 1
        self.ctx.publish("image", replace(img, data=out))

    def close(self) -> None:
        if hasattr(self, "sync"):
            self.sync.flush()
            self.ctx.log.info("ibl compositor: %s", dict(sorted(self.counts.items())))
        if getattr(self, "renderer", None) is not None:
            self.renderer.release()
