"""Synthetic rig node: renders a scene file's RGB-D and fisheye cameras and ground truth (see probeless.scene.rig).

At the start it publishes ``floorplan`` and ``fisheye_from_rgbd`` (both as the scene's ``given`` block
tells the pipeline), and live (``rate`` > 0) again every ``static_period_s`` of wall time, so a node restarted
after a crash gets them too (their consumers ignore an unchanged repeat). ``seed`` seeds the base depth
noise, the scene's ``sensor_effects.seed`` its effects."""

from __future__ import annotations

import time
from dataclasses import dataclass

from probeless.messages.geometry import Floorplan, PoseStamped
from probeless.messages.header import shift_stamp
from probeless.messages.lighting import Cubemap
from probeless.messages.sensor import CameraInfo, DepthImage, Image
from probeless.runtime import Node, param
from probeless.runtime.pacing import Pacer
from probeless.scene.parse import load_scene
from probeless.scene.rig import RGBD_FRAME, Rig, frame_schedule


class SyntheticRig(Node):
    """Publishes each frame when its scene time is due (scaled by ``rate``); ``rate: 0`` = lockstep.

    When rendering is slower than real time the schedule shifts (both cameras slow down together,
    frames are never dropped or reordered). With ``loop`` the sequence restarts and stamps keep
    increasing (each pass is offset by the sequence length plus one RGB-D frame period).
    """

    OUTPUTS = {
        "rgb": Image, "depth": DepthImage, "fisheye": Image, "floorplan": Floorplan,
        "rgbd/camera_info": CameraInfo, "fisheye/camera_info": CameraInfo,
        "gt/rgbd_pose": PoseStamped, "gt/fisheye_pose": PoseStamped, "fisheye_from_rgbd": PoseStamped,
        "gt/fisheye_exposure": Image, "gt/envmap/*": Cubemap, "gt/envmap_ldr/*": Cubemap,
    }

    @dataclass(frozen=True)
    class Params:
        scene: str = param(path="file", must_exist=True,
                           doc="scene file (.yaml), relative to the working folder; use $(dirname) for paths "
                               "relative to the graph")
        rate: float = param(1.0, min=0.0, max=100.0,
                            doc="speed factor against scene time; 0 = lockstep, as fast as the graph consumes")
        duration_s: float = param(0.0, min=0.0, doc="render this much scene time [s]; 0 = the whole trajectory")
        loop: bool = param(False, doc="start again at the end")
        envmaps: bool = param(True, doc="publish ground-truth cubemaps for every virtual object and fisheye frame")
        fisheye: bool = param(True, doc="render and publish the fisheye camera (with its ground truth); false: "
                                        "RGB-D only, for graphs that use no fisheye (it is most of the rig's cost)")
        envmap_size: int = param(64, min=4, max=2048, doc="ground-truth cubemap face size [texels]")
        fisheye_cube_size: int = param(512, min=16, max=4096,
                                       doc="cubemap resolution behind the fisheye image [texels]")
        seed: int = param(0, min=0, doc="depth-noise seed (also mixed into the scene's sensor_effects streams)")
        stamps: str = param("scene", choices=("scene", "wall"),
                            doc="scene = scene time from 0 (reproducible); wall = the node clock when the frame is "
                                "rendered, like a live camera's host stamps")
        static_period_s: float = param(1.0, min=0.0, doc="live: republish floorplan and fisheye_from_rgbd this "
                                                         "often [s, wall], for restarted nodes; 0 = once")
        max_lag_s: float = param(0.05, min=0.0, doc="lag beyond which the schedule shifts [s]")

    def setup(self) -> None:
        p = self.params
        self.scene = load_scene(p.scene)
        self.rig = Rig(self.scene, envmap_size=p.envmap_size, fisheye_cube_size=p.fisheye_cube_size,
                       seed=p.seed, envmaps=p.envmaps)
        self.events = [e for e in frame_schedule(self.scene, p.duration_s or None) if p.fisheye or e.kind == RGBD_FRAME]
        self.period_s = (p.duration_s or self.scene.duration) + 1.0 / self.scene.rgbd.fps
        self.lockstep = p.rate == 0
        self.passes, self.next = 0, 0
        self.pacer = None if self.lockstep else Pacer(p.rate)
        self.static_due: float | None = 0.0  # monotonic time [s] the static messages are due; None = never again
        self.timer = self.ctx.create_timer(0.002, self._step, name="render")

    def _step(self) -> None:
        # from the first timer tick: after the readiness barrier, so no subscriber misses it
        if self.static_due is not None and time.monotonic() >= self.static_due:
            self._publish_static()
        if self.next >= len(self.events):
            self._at_end()
            return
        event = self.events[self.next]
        offset_s = self.passes * self.period_s
        if not self.lockstep and self.pacer.wait(offset_s + event.t) is None:
            return
        capture_ns = self.ctx.now_ns()
        with self.ctx.timed("render"):
            messages = list(self.rig.messages(event))
        if self.params.stamps == "wall":
            offset_ns = capture_ns - event.stamp_ns
        else:
            offset_ns = int(round(offset_s * 1e9))
        for output, msg in messages:
            self.ctx.publish(output, shift_stamp(msg, offset_ns) if offset_ns else msg)
        self.next += 1
        if self.lockstep:
            self.ctx.wait_quiescent()
        elif (lag := time.monotonic() - self.pacer.due(offset_s + event.t)) > self.params.max_lag_s:
            self.pacer.shift(lag)  # fell behind: both cameras slow down together

    def _publish_static(self) -> None:
        """floorplan and fisheye_from_rgbd, stamped at the first publication; schedules the next repeat."""
        if self.static_due == 0.0:
            self.static_origin_ns = self.ctx.now_ns() if self.params.stamps == "wall" else 0
        self.ctx.publish("floorplan", shift_stamp(self.rig.floorplan(), self.static_origin_ns))
        self.ctx.publish("fisheye_from_rgbd", shift_stamp(self.rig.fisheye_from_rgbd_message(), self.static_origin_ns))
        period = self.params.static_period_s
        self.static_due = None if self.lockstep or period <= 0 else time.monotonic() + period

    def _at_end(self) -> None:
        if not self.params.loop:
            self.timer.cancel()
            self.ctx.log.info("rendered %d frame(s) of %s", len(self.events), self.scene.name)
            self.ctx.stop()
            return
        self.passes += 1
        self.next = 0

    def close(self) -> None:
        if getattr(self, "rig", None) is not None:
            self.rig.release()

