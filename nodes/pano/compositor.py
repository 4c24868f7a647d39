"""360° IBL compositor node (paper 002): objects lit by the HDR frame over the view of the LDR frame.

Inputs, paired by header stamp (exactly): ``image`` (rgb8 LDR equirect, the video source),
``hdr`` (rgbf16/rgbf32 equirect from ``itmo``) and ``diffuse`` (rgbf32 diffuse radiance map from
``diffuse_map``). Per frame the view follows the scripted head path
(:func:`probeless.pano.view.head_pose`, time = stamp minus the first stamp): background = the
perspective view of ``image``, objects = :class:`probeless.pano.render.PanoRenderer` times
``exposure``, encoded for display (:mod:`probeless.pano.composite`; ``display: auto`` inverts
what the ``operator`` of the upstream ``itmo`` node did to the stored values). ``mode: stereo``
renders two eyes ``ipd_m`` apart, side by side, at the paper's HMD size per eye.
Output ``image``: the composited rgb8 view, stamped like the input frame.

Object mesh paths that do not exist relative to the working folder are looked up relative to
the repository (so the default teapot, ``launch/scenes/meshes/teapot.obj``, works from anywhere).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from typing import Any

import numpy as np

from probeless.errors import SchemaError
from probeless.ibl.objects import object_from_dict, objects_problem
from probeless.messages.sensor import Image
from probeless.pano.composite import DISPLAY, DISPLAY_FOR_OPERATOR, render_view
from probeless.pano.objects import DEFAULT_OBJECTS, MONO_SIZE, resolve_mesh
from probeless.pano.render import PanoRenderer
from probeless.pano.view import HMD_EYE_SIZE, head_pose, view_equirect
from probeless.runtime import Node, param
from probeless.runtime.sync import ExactTimeSync


class PanoCompositor(Node):
    """``image`` + ``hdr`` + ``diffuse`` (same stamp) -> composited ``image`` (see the module docstring)."""

    INPUTS = {"image": Image, "hdr": Image, "diffuse": Image}
    OUTPUTS = {"image": Image}

    @dataclass(frozen=True)
    class Params:
        objects: tuple[Any, ...] = param(DEFAULT_OBJECTS, check=lambda v: objects_problem(v, resolve_mesh),
                                         doc="virtual objects: list of {id, mesh, position, radius|scale, "
                                             "yaw_deg, up, material} (see probeless.ibl.objects; unique ids, a "
                                             "relative mesh path missing here is taken from the repository); "
                                             "world z up, viewer at 0")
        mode: str = param("mono", choices=("mono", "stereo"), doc="one view, or two eyes side by side")
        width: int = param(0, min=0, max=8192, doc="view (per eye) width; 0 = 1280 mono, 1182 stereo [px]")
        height: int = param(0, min=0, max=8192, doc="view (per eye) height; 0 = 720 mono, 1464 stereo [px]")
        fov_deg: float = param(90.0, min=1.0, max=170.0, doc="horizontal field of view of a view (eye) [deg]")
        ipd_m: float = param(0.064, min=0.0, max=1.0, doc="interpupillary distance (stereo) [m]")
        yaw0_deg: float = param(-5.0, min=-360.0, max=360.0, doc="head yaw at the first frame, from +x to +y [deg]")
        yaw_deg_per_s: float = param(5.0, min=-360.0, max=360.0, doc="head yaw rate [deg/s]")
        pitch_deg: float = param(-8.0, min=-89.0, max=89.0, doc="mean head pitch, up positive [deg]")
        pitch_amp_deg: float = param(2.0, min=0.0, max=45.0, doc="amplitude of the head nod [deg]")
        pitch_period_s: float = param(4.0, min=0.01, max=1e6, doc="period of the head nod [s]")
        exposure: float = param(1.0, min=0.0, max=1e6, doc="scale of the linear render before encoding [-]")
        display: str = param("auto", choices=("auto",) + DISPLAY, doc="how objects are encoded for display: "
                             "direct, gamma (2.2), srgb; auto = the inverse of how `operator` read the frame")
        operator: str = param("paper", choices=tuple(DISPLAY_FOR_OPERATOR), doc="the itmo operator upstream "
                              "(only for display: auto)")
        background: str = param("gpu", choices=("gpu", "remap"), doc="background view: GPU pass or cv2.remap")
        lod_bias: float = param(0.0, min=-4.0, max=4.0, doc="glossy ring samples' mip level offset: 0 = the "
                                                            "paper's rule (texel spacing = sample spacing), -1 = "
                                                            "one level finer (closer to the Phong lobe integral)")
        near: float = param(0.02, min=1e-4, max=10.0, doc="near clip plane [m]")
        far: float = param(100.0, min=0.1, max=1e5, doc="far clip plane [m]")

    def setup(self) -> None:
        p = self.params
        objects = [object_from_dict(resolve_mesh(o), f"objects[{i}]") for i, o in enumerate(p.objects)]
        self.renderer = PanoRenderer(objects, lod_bias=p.lod_bias, near=p.near, far=p.far)
        default = HMD_EYE_SIZE if p.mode == "stereo" else MONO_SIZE
        self.size = (p.width or default[0], p.height or default[1])
        self.display = DISPLAY_FOR_OPERATOR[p.operator] if p.display == "auto" else p.display
        self.sync = ExactTimeSync(["image", "hdr", "diffuse"], self._on_frame, on_unmatched=self._unmatched)
        self.t0_ns: int | None = None
        self.counts: Counter[str] = Counter()

    def on_input(self, name: str, msg: Image) -> None:
        self.sync.add(name, msg)

    def _unmatched(self, name: str, msg, reason: str) -> None:
        self.counts[f"unpaired_{name}:{reason}"] += 1

    def _check(self, msgs: dict) -> None:
        img, hdr, dif = msgs["image"], msgs["hdr"], msgs["diffuse"]
        if img.encoding != "rgb8":
            raise SchemaError(f"pano_compositor: image must be rgb8, got {img.encoding!r}")
        for name, msg in (("hdr", hdr), ("diffuse", dif)):
            if msg.encoding not in ("rgbf16", "rgbf32"):
                raise SchemaError(f"pano_compositor: {name} must be rgbf16 or rgbf32, got {msg.encoding!r}")

    def _on_frame(self, msgs: dict) -> None:
        self._check(msgs)
        p, img = self.params, msgs["image"]
        if self.t0_ns is None:
            self.t0_ns = img.header.stamp_ns
        t_s = (img.header.stamp_ns - self.t0_ns) * 1e-9
        with self.ctx.timed("upload"):
            self.renderer.set_environment(msgs["hdr"].data, msgs["diffuse"].data)
            if p.background == "gpu":
                self.renderer.set_background(img.data)
        head = head_pose(t_s, yaw0_deg=p.yaw0_deg, yaw_deg_per_s=p.yaw_deg_per_s, pitch_deg=p.pitch_deg,
                         pitch_amp_deg=p.pitch_amp_deg, pitch_period_s=p.pitch_period_s)
        remap = None if p.background == "gpu" else \
            (lambda pose: view_equirect(img.data, pose, p.fov_deg, *self.size))
        out = render_view(self.renderer, head, p.fov_deg, *self.size, stereo=p.mode == "stereo", ipd_m=p.ipd_m,
                          exposure=p.exposure, display=self.display, background=remap, timed=self.ctx.timed)
        self.counts["frames"] += 1
        self.ctx.publish("image", Image(img.header, np.ascontiguousarray(out), "rgb8"))

    def close(self) -> None:
        if hasattr(self, "sync"):
            self.sync.flush()
            self.ctx.log.info("pano compositor: %s", dict(sorted(self.counts.items())))
        if getattr(self, "renderer", None) is not None:
            self.renderer.release()
