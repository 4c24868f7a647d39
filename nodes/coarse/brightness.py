"""Brightness-change estimator node (paper §4.6): Δ of each fisheye frame against the coarse model's atlas.

Fisheye frames and their poses pair by identical stamp. Δ of frame k is measured against the
atlas that already holds frame k-1 (the previous paired frame): the texturer applies frame k-1
once Δ_(k-1) is out and then publishes that atlas (stamp = k-1), so frame k waits for an atlas
stamped >= stamp(k-1). The first frame ever publishes Δ = 0 (``sampled`` False) at once. A frame
that waited ``atlas_timeout_s`` (node clock) is measured against the newest atlas held
(``stale_atlas``) or published unsampled (``no_atlas``). Bad input (non-finite pose, wrong image
or atlas size, camera outside the floorplan) publishes an unsampled Δ = 0 and is counted; counters
are in ``self.counts`` and logged at close. ``enabled: false`` publishes Δ = 0 for every frame
(the "without Δ" experiment).

The atlas is the texturer's rgba8 image: RGB in camera LDR units, A nonzero (255) where the texel
was observed directly. Its layout comes from ``atlas_size`` / ``texels_per_m`` exactly as in the
texturer (:func:`probeless.coarse.model.make_layout`); a received atlas of another shape is
rejected with an error naming both shapes. Δ uses ``samples`` random core texels (drawn once per
layout with ``seed``); ``fov_deg`` should equal the texturer's.
"""

from __future__ import annotations

from collections import Counter, deque
from dataclasses import dataclass

import numpy as np

from probeless.cameras import model_from_info
from probeless.coarse.brightness import DEADBAND, apply_deadband, draw_sample, estimate_delta
from probeless.coarse.model import CoarseConfig, make_layout
from probeless.coarse.texels import texel_map
from probeless.errors import GeometryError, ProbelessError
from probeless.messages.geometry import Floorplan, PoseStamped
from probeless.messages.header import Header
from probeless.messages.lighting import BrightnessDelta
from probeless.messages.sensor import CameraInfo, Image
from probeless.runtime import Node, param
from probeless.runtime.oncelog import OnceLog
from probeless.runtime.sync import ExactTimeSync


@dataclass
class _Frame:
    image: Image
    pose: PoseStamped
    needs_ns: int       # the atlas must hold this stamp (the previous frame)
    arrived_ns: int     # node clock when paired


class BrightnessEstimator(Node):
    """``fisheye`` + ``fisheye_pose`` + ``atlas`` (+ ``camera_info``, ``floorplan``) -> ``delta`` per frame."""

    INPUTS = {"fisheye": Image, "fisheye_pose": PoseStamped, "camera_info": CameraInfo, "floorplan": Floorplan,
              "atlas": Image}
    OUTPUTS = {"delta": BrightnessDelta}

    @dataclass(frozen=True)
    class Params:
        atlas_size: int = param(2048, min=16, max=16384, doc="atlas side when texels_per_m is 0 [texels] "
                                                             "(as the texturer's)")
        texels_per_m: float = param(0.0, min=0.0, max=10000.0, doc="texel density; 0 = fit atlas_size "
                                                                   "[texels/m] (as the texturer's)")
        samples: int = param(65536, min=0, max=10**9, doc="random core texels used per frame; 0 = all")
        seed: int = param(0, min=0, doc="seed of the texel sample (drawn once per layout)")
        fov_deg: float = param(185.0, min=1.0, max=359.0, doc="texels beyond fov/2 off the fisheye axis are "
                                                               "out of view [deg]")
        dark: float = param(0.01, min=0.0, max=1.0, doc="black: all channels <= this [0..1 LDR]")
        saturated: float = param(0.98, min=0.0, max=1.0, doc="saturated: any channel >= this [0..1 LDR]")
        occlusion_offset_texels: float = param(1.5, min=0.0, max=100.0, doc="wall texels are tested this far "
                                                                            "inside the room [texels]")
        atlas_timeout_s: float = param(0.5, min=0.0, max=60.0, doc="wait this long for the atlas holding the "
                                                                   "previous frame, then use the newest [s]")
        max_pending: int = param(8, min=1, max=1000, doc="frames waiting for their atlas before the oldest "
                                                         "is measured against the newest atlas [count]")
        enabled: bool = param(True, doc="false: publish Δ = 0 (sampled false) for every frame")
        deadband: float = param(DEADBAND, min=0.0, max=1.0, doc="Δ below this in every channel is published as 0 "
                                                                "(no drift in a static room) [0..1 LDR]")

    def setup(self) -> None:
        self.counts: Counter[str] = Counter()
        self.sync = ExactTimeSync(["fisheye", "fisheye_pose"], self._on_pair, on_unmatched=self._unmatched)
        self.pending: deque[_Frame] = deque()
        self.previous_ns: int | None = None
        self.atlas: Image | None = None
        self.camera = None
        self.geometry = None          # (Floorplan message, layout, texmap, sample)
        self.once = OnceLog(self.ctx.log)
        timeout = self.params.atlas_timeout_s
        self.ctx.create_timer(min(0.05, max(0.005, timeout / 4)), self._flush, name="atlas_timeout")

    def on_input(self, name: str, msg) -> None:
        if name in ("fisheye", "fisheye_pose"):
            self.sync.add(name, msg)
        elif name == "camera_info":
            try:
                self.camera = model_from_info(msg)
            except ProbelessError as exc:
                self.once.error("camera_info", f"unusable camera_info: {exc}")
                self.counts["bad_camera_info"] += 1
        elif name == "floorplan":
            self._on_floorplan(msg)
        elif self.geometry is None or self._atlas_fits(msg):
            self.atlas = msg
        else:
            self.counts["atlas_rejected"] += 1
        self._flush()

    def _on_floorplan(self, msg: Floorplan) -> None:
        if self.geometry is not None and np.array_equal(msg.vertices, self.geometry[0].vertices) \
                and msg.ceiling_height == self.geometry[0].ceiling_height:
            return
        p = self.params
        try:
            layout = make_layout(msg.vertices, msg.ceiling_height, CoarseConfig(p.atlas_size, p.texels_per_m))
        except ProbelessError as exc:
            self.counts["bad_floorplan"] += 1
            self.ctx.log.error("floorplan rejected: %s", exc)
            return
        texmap = texel_map(layout)
        sample = draw_sample(texmap, p.samples, p.seed)
        self.geometry = (msg, layout, texmap, sample)
        self.ctx.log.info("atlas %dx%d at %.1f texels/m: %d of %d core texels sampled", layout.width,
                          layout.height, layout.texels_per_m, len(sample.index), int(texmap.core.sum()))

    def _unmatched(self, name: str, msg, reason: str) -> None:
        self.counts[f"unpaired_{name}:{reason}"] += 1

    def _on_pair(self, msgs: dict) -> None:
        img, pose = msgs["fisheye"], msgs["fisheye_pose"]
        stamp = img.header.stamp_ns
        if not self.params.enabled:
            self._publish(img, np.zeros(3), 0, "disabled")
            return
        needs, self.previous_ns = self.previous_ns, stamp
        if needs is None:
            self._publish(img, np.zeros(3), 0, "first_frame")
            return
        self.pending.append(_Frame(img, pose, needs, self.ctx.now_ns()))
        while len(self.pending) > self.params.max_pending:
            self._resolve(self.pending.popleft())

    def _flush(self) -> None:
        """Measure every waiting frame whose atlas is in, or that waited too long."""
        now, timeout_ns = self.ctx.now_ns(), self.params.atlas_timeout_s * 1e9
        while self.pending:
            frame = self.pending[0]
            fresh = self.atlas is not None and self.atlas.header.stamp_ns >= frame.needs_ns
            if not fresh and now - frame.arrived_ns < timeout_ns:
                return
            self._resolve(self.pending.popleft())

    def _resolve(self, frame: _Frame) -> None:
        """Publish Δ of ``frame`` against the newest atlas (stale if it does not hold the previous frame)."""
        reason = self._problem(frame)
        if reason is not None:
            self._publish(frame.image, np.zeros(3), 0, reason)
            return
        _, layout, texmap, sample = self.geometry
        p, atlas = self.params, self.atlas.data
        try:
            with self.ctx.timed("estimate"):
                delta, used = estimate_delta(
                    atlas[..., :3], atlas[..., 3], texmap, frame.image.data, self.camera,
                    frame.pose.target_from_source, p.fov_deg, layout.floorplan, sample_idx=sample, dark=p.dark,
                    saturated=p.saturated, offset_m=p.occlusion_offset_texels / layout.texels_per_m)
        except ProbelessError as exc:  # GeometryError: the camera is outside the (non-convex) floorplan
            reason = "geometry_error" if isinstance(exc, GeometryError) else f"rejected:{type(exc).__name__}"
            self.once.error(reason, f"frame {frame.image.header.stamp_ns}: {exc}")
            self._publish(frame.image, np.zeros(3), 0, reason)
            return
        if used and not apply_deadband(delta, p.deadband).any() and delta.any():
            self.counts["below_deadband"] += 1
        delta = apply_deadband(delta, p.deadband)
        held = self.atlas.header.stamp_ns
        # "atlas_ahead": the texturer already applied this frame (it gave up waiting for its Δ)
        reason = "stale_atlas" if held < frame.needs_ns else "atlas_ahead" if held >= frame.image.header.stamp_ns \
            else "estimated"
        self._publish(frame.image, delta, used, reason)

    def _problem(self, frame: _Frame) -> str | None:
        """Why ``frame`` cannot be measured (a counter name), or None."""
        if self.atlas is None:
            return "no_atlas"
        if self.geometry is None:
            return "no_floorplan"
        if self.camera is None:
            return "no_camera_info"
        T, data, model = frame.pose.target_from_source, frame.image.data, self.camera
        if T.shape != (4, 4) or not np.isfinite(T).all():
            self.once.error("bad_pose",
                            f"frame {frame.image.header.stamp_ns}: fisheye pose is not a finite 4x4 transform")
            return "bad_pose"
        if data.shape != (model.height, model.width, 3) or data.dtype != np.uint8:
            self.once.error("bad_image", f"fisheye image is {data.shape} {data.dtype}, its camera_info says "
                                         f"({model.height}, {model.width}, 3) uint8")
            return "bad_image"
        return None if self._atlas_fits(self.atlas) else "atlas_shape_mismatch"

    def _atlas_fits(self, atlas: Image) -> bool:
        """True when ``atlas`` has the layout's shape; logs an error naming both shapes (once) when not."""
        layout = self.geometry[1]
        want = (layout.height, layout.width, 4)
        if atlas.data.shape == want and atlas.encoding == "rgba8":
            return True
        self.once.error(f"atlas{atlas.data.shape}", f"atlas is {atlas.data.shape} {atlas.encoding}, but atlas_size="
                        f"{self.params.atlas_size} texels_per_m={self.params.texels_per_m} give a {want} rgba8 layout: "
                        f"give the texturer and the brightness estimator the same params")
        return False

    def _publish(self, img: Image, delta: np.ndarray, used: int, reason: str) -> None:
        self.counts[reason] += 1
        if reason in ("estimated", "stale_atlas", "atlas_ahead") and used == 0:
            self.counts["no_usable_texels"] += 1
        header = Header(img.header.stamp_ns, img.header.frame_id)
        self.ctx.publish("delta", BrightnessDelta(header, np.asarray(delta, np.float32), int(used), used > 0))


    def close(self) -> None:
        if hasattr(self, "counts"):
            self.counts["pending_at_close"] += len(self.pending)
            self.ctx.log.info("brightness estimator: %s", dict(sorted(self.counts.items())))
