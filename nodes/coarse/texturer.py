"""Coarse-model texturer node (paper §4.3–4.5): the room's atlas, textured from the fisheye on the GPU.

Each undistorted fisheye frame and its pose (``fisheye_pose``, stamped identically, from
``pose_interp``) update the atlas once its brightness change ``delta`` for the same stamp has
arrived from ``brightness_estimator`` (or, after ``delta_timeout_s``, with Δ = 0, counted as
``delta_timeout``); frames are applied in stamp order. With ``use_delta: false`` nothing waits.

Outputs: ``atlas`` (rgba8: camera LDR colour, A = 255 where observed directly; stamp = the last
fisheye frame applied) every ``atlas_every`` frames - the estimator needs every one; ``observed``
(mono8: 255 observed, 128 inpainted, 0 nothing) and ``occlusion`` (mono8: 255 = visible from this
frame's viewpoint) every ``mask_every`` frames; ``mesh`` (the prism with atlas uvs) once per floorplan.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import numpy as np

from probeless.cameras import model_from_info
from probeless.coarse.model import CoarseConfig, CoarseModel
from probeless.coarse.texels import coarse_mesh
from probeless.errors import ProbelessError
from probeless.messages.geometry import Floorplan, PoseStamped
from probeless.messages.header import Header
from probeless.messages.lighting import BrightnessDelta
from probeless.messages.mesh import TriangleMesh
from probeless.messages.sensor import CameraInfo, Image
from probeless.runtime import Node, param
from probeless.runtime.sync import ExactTimeSync


class CoarseTexturer(Node):
    """``fisheye`` + ``fisheye_pose`` (+ ``delta``) -> ``atlas``, ``observed``, ``occlusion``, ``mesh``."""

    INPUTS = {"fisheye": Image, "fisheye_pose": PoseStamped, "camera_info": CameraInfo, "floorplan": Floorplan,
              "delta": BrightnessDelta}
    OUTPUTS = {"atlas": Image, "observed": Image, "occlusion": Image, "mesh": TriangleMesh}

    @dataclass(frozen=True)
    class Params:
        atlas_size: int = param(2048, min=16, max=16384, doc="atlas side when texels_per_m is 0 [texels]")
        texels_per_m: float = param(0.0, min=0.0, max=10000.0, doc="uniform texel density; 0 = fit atlas_size "
                                                                   "[texels/m]")
        fov_deg: float = param(180.0, min=1.0, max=359.0, doc="texels beyond fov/2 off the fisheye axis are "
                                                               "out of view [deg]")
        use_delta: bool = param(True, doc="wait for the brightness change of each frame (false: apply Δ = 0)")
        delta_timeout_s: float = param(1.0, min=0.0, max=60.0, doc="apply a frame with Δ = 0 after waiting "
                                                                   "this long for its delta [s, node clock]")
        atlas_every: int = param(1, min=0, max=100000, doc="publish the atlas every n-th frame; 0 = never")
        mask_every: int = param(10, min=0, max=100000, doc="publish observed/occlusion every n-th frame; 0 = never")
        inpaint: bool = param(True, doc="fill never-observed texels (OpenCV Telea, per surface)")
        occlusion: bool = param(True, doc="false: ignore the room's self-occlusion (an ablation)")
        inpaint_scale: float = param(0.25, min=0.01, max=1.0, doc="inpainting resolution / atlas resolution")
        inpaint_min_new_texels: int = param(2000, min=1, max=10**9, doc="re-inpaint after this many newly "
                                                                        "observed texels [count]")
        queue_frames: int = param(8, min=1, max=1000, doc="frames waiting for their delta before the oldest "
                                                          "is applied with Δ = 0 [count]")

    def setup(self) -> None:
        p = self.params
        self.config = CoarseConfig(p.atlas_size, p.texels_per_m, p.fov_deg, p.inpaint, p.inpaint_scale,
                                   p.inpaint_min_new_texels, occlusion=p.occlusion)
        self.sync = ExactTimeSync(["fisheye", "fisheye_pose"], self._on_pair, on_unmatched=self._unmatched)
        self.model: CoarseModel | None = None
        self.camera = None
        self.ready: list[tuple[Image, PoseStamped, int]] = []   # (frame, pose, arrival ns), stamp order
        self.deltas: dict[int, BrightnessDelta] = {}
        self.t0_ns: int | None = None
        self.last_applied = -1  # stamp of the last frame applied [ns]
        self.delta_closed = False
        self.counts: Counter[str] = Counter()
        self.ctx.create_timer(0.02, self._flush, name="delta_timeout")

    def on_input(self, name: str, msg) -> None:
        if name in ("fisheye", "fisheye_pose"):
            self.sync.add(name, msg)
        elif name == "camera_info":
            self.camera = model_from_info(msg)
        elif name == "floorplan":
            self._on_floorplan(msg)
        else:
            self.deltas[msg.header.stamp_ns] = msg
            self._flush()

    def _on_floorplan(self, msg: Floorplan) -> None:
        if self.model is not None and np.array_equal(msg.vertices, self.model.layout.floorplan) \
                and msg.ceiling_height == self.model.layout.ceiling_height:
            return
        if self.model is not None:
            self.model.release()
        self.model = CoarseModel(msg.vertices, msg.ceiling_height, self.config)
        lay = self.model.layout
        self.ctx.log.info("atlas %dx%d at %.1f texels/m for a %d-wall room", lay.width, lay.height,
                          lay.texels_per_m, len(lay.walls))
        v, t, uv, _ = coarse_mesh(lay)
        self.ctx.publish("mesh", TriangleMesh(Header(msg.header.stamp_ns, msg.header.frame_id or "world"),
                                              v, t, uvs=uv))

    def _unmatched(self, name: str, msg, reason: str) -> None:
        self.counts[f"unpaired_{name}:{reason}"] += 1

    def _on_pair(self, msgs: dict) -> None:
        self.ready.append((msgs["fisheye"], msgs["fisheye_pose"], self.ctx.now_ns()))
        self._flush()

    def _flush(self, final: bool = False) -> None:
        """Apply every waiting frame whose delta is in, or that waited too long (all of them when ``final``)."""
        p = self.params
        while self.ready:
            img, pose, arrived = self.ready[0]
            stamp = img.header.stamp_ns
            delta = self.deltas.pop(stamp, None)
            waited = self.ctx.now_ns() - arrived > p.delta_timeout_s * 1e9
            gone = final or self.delta_closed
            if p.use_delta and delta is None and not (waited or gone) and len(self.ready) <= p.queue_frames:
                return
            self.ready.pop(0)
            if p.use_delta and delta is None:
                self.counts["delta_missing" if gone else "delta_timeout"] += 1
            self.last_applied = stamp
            self._apply(img, pose, delta)
        # a delta may come in before its frame has been paired: keep those newer than the last frame applied
        for stale in [s for s in self.deltas if s <= self.last_applied] + sorted(self.deltas)[:-64]:
            if self.deltas.pop(stale, None) is not None:
                self.counts["delta_unused"] += 1

    def on_input_closed(self, name: str) -> None:
        if name == "delta":  # no more deltas will come: nothing may wait for one any more
            self.delta_closed = True
            self._flush()

    def _apply(self, img: Image, pose: PoseStamped, delta: BrightnessDelta | None) -> None:
        if self.model is None or self.camera is None:
            self.counts["no_floorplan" if self.model is None else "no_camera_info"] += 1
            return
        stamp = img.header.stamp_ns
        self.t0_ns = stamp if self.t0_ns is None else self.t0_ns
        d = delta.delta if delta is not None and delta.sampled and self.params.use_delta else np.zeros(3)
        try:
            with self.ctx.timed("occlusion"):
                T = self.model.occlude(pose.target_from_source)
            with self.ctx.timed("texture_update"):
                self.model.update(img.data, self.camera, T, d, (stamp - self.t0_ns) * 1e-9)
            with self.ctx.timed("inpaint"):
                self.model.inpaint_if_due()
        except ProbelessError as exc:
            self.counts[f"skipped:{type(exc).__name__}"] += 1
            self.ctx.log.warning("frame %d not applied: %s", stamp, exc)
            return
        self.counts["applied"] += 1
        self._publish(Header(stamp, "world"))

    def _publish(self, header: Header) -> None:
        n, p = self.model.frames, self.params
        if p.atlas_every and n % p.atlas_every == 0:
            with self.ctx.timed("read_atlas"):
                self.ctx.publish("atlas", Image(header, np.ascontiguousarray(self.model.gpu.read_packed()), "rgba8"))
        if p.mask_every and n % p.mask_every == 0:
            self.ctx.publish("observed", Image(header, self.model.observed_image()[..., None], "mono8"))
            occ = self.model.gpu.read_occlusion().astype(np.uint8) * np.uint8(255)
            self.ctx.publish("occlusion", Image(header, occ[..., None], "mono8"))

    def close(self) -> None:
        if hasattr(self, "ready"):
            self.sync.flush()
            self._flush(final=True)
        if hasattr(self, "counts"):
            self.ctx.log.info("coarse texturer: %s", dict(sorted(self.counts.items())))
        if getattr(self, "model", None) is not None:
            self.model.release()
