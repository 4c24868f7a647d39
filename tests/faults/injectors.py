"""Test nodes of the fault-injection suite (imported by node processes via PYTHONPATH=tests/faults).

- ``JumpyRig``: RGB-D poses and fisheye frames stamped by a host clock that jumps at given frames.
- ``BadCamera``: an RGB-D camera (rgb, depth, camera_info) that sends faulty frames at given indices.
- ``StallSource``: sends ``count`` frames, then stops producing without ending (a stalled driver).
- ``StampLog``: records what arrives (stamps, pose translations, image shapes) and writes JSON at close.
- ``IgnoresSigterm``: a node that ignores SIGTERM (for the launcher's bounded shutdown).
"""

from __future__ import annotations

import json
import signal
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from probeless.messages import Header, Image, Tick
from probeless.messages.diagnostics import TrackingState
from probeless.messages.geometry import PoseStamped
from probeless.messages.sensor import CameraInfo, DepthImage
from probeless.runtime import Node, param

VEL = np.array([0.3, -0.1, 0.05])      # m/s, as tests/faults/test_clock_jumps.py
OMEGA = np.array([0.0, 0.0, 0.4])      # rad/s about z


def motion(t_s: float) -> np.ndarray:
    """world_from_rgbd of the constant-velocity motion at true time ``t_s``."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(OMEGA * t_s).as_matrix()
    T[:3, 3] = VEL * t_s
    return T


def rgbd_frame(w: int, h: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(K, rgb (h, w, 3) uint8, depth (h, w) uint16 [mm]) of a textured wall 1.6-2.1 m away with two bumps
    and a fold (3D structure that constrains ICP in every direction)."""
    K = np.array([[w * 0.8, 0, w / 2], [0, w * 0.8, h / 2], [0, 0, 1.0]])
    y, x = np.mgrid[0:h, 0:w] / np.array([h, w])[:, None, None]
    bumps = (0.3 * np.exp(-((x - 0.3) ** 2 + (y - 0.4) ** 2) / 0.02)
             + 0.25 * np.exp(-((x - 0.7) ** 2 + (y - 0.65) ** 2) / 0.015))
    depth = 2.1 - bumps - 0.4 * np.abs(x - 0.5) + 0.15 * y
    v, u = np.mgrid[0:h, 0:w]
    rgb = np.stack([(u * 4) % 256, (v * 5) % 256, ((u + v) * 3) % 256], -1).astype(np.uint8)
    return K, rgb, np.round(depth * 1000).astype(np.uint16)


class JumpyRig(Node):
    """Per tick: ``pose`` (stamp = host clock) then ``fisheye`` 13 ms later; the host clock jumps by
    ``jump_s[i]`` before frame ``jump_at[i]``. Writes {fisheye stamp: true time} to ``truth_out``."""

    INPUTS = {"tick": Tick}
    OUTPUTS = {"pose": PoseStamped, "fisheye": Image}

    @dataclass(frozen=True)
    class Params:
        count: int = param(60, min=1)
        jump_at: tuple[int, ...] = param(())
        jump_s: tuple[float, ...] = param(())
        truth_out: str = param("")

    def setup(self):
        self.k, self.offset_ns, self.t0 = 0, 0, None
        self.truth: list[tuple[int, float]] = []
        self.img = np.zeros((2, 2, 3), np.uint8)

    def on_input(self, name, msg):
        now = self.ctx.now_ns()
        self.t0 = now if self.t0 is None else self.t0
        if self.k in self.params.jump_at:
            self.offset_ns += round(self.params.jump_s[self.params.jump_at.index(self.k)] * 1e9)
        t_true = (now - self.t0) / 1e9
        stamp = now + self.offset_ns
        self.ctx.publish("pose", PoseStamped(Header(stamp, "world"), "rgbd", motion(t_true)))
        self.ctx.publish("fisheye", Image(Header(stamp + 13_000_000, "fisheye"), self.img, "rgb8"))
        self.truth.append((stamp + 13_000_000, t_true + 0.013))
        self.k += 1
        if self.k >= self.params.count:
            self.ctx.stop()

    def close(self):
        if self.params.truth_out:
            Path(self.params.truth_out).write_text(json.dumps(self.truth))


class BadCamera(Node):
    """An RGB-D camera (``rgb``, ``depth`` in metres, ``camera_info``; ``fisheye``: the rgb frame again) of a
    static wall (depth uint16 mm), frame k stamped k * ``period_ms``; frame k is faulty when k is in a fault list:
    ``wrong_size`` (rgb, depth and fisheye at half size; camera_info unchanged), ``wrong_encoding`` (rgb as a
    4-channel float image, rgbaf32), ``nan_depth`` (all NaN), ``zero_depth`` (all 0).
    """

    INPUTS = {"tick": Tick}
    OUTPUTS = {"rgb": Image, "depth": DepthImage, "camera_info": CameraInfo, "fisheye": Image}

    @dataclass(frozen=True)
    class Params:
        count: int = param(40, min=1)
        width: int = param(160, min=8)
        height: int = param(120, min=8)
        wrong_size: tuple[int, ...] = param(())
        wrong_encoding: tuple[int, ...] = param(())
        nan_depth: tuple[int, ...] = param(())
        zero_depth: tuple[int, ...] = param(())
        period_ms: float = param(33.333, min=1.0)

    def setup(self):
        self.k = 0
        p = self.params
        self.K = rgbd_frame(p.width, p.height)[0]

    def on_input(self, name, msg):
        p, k = self.params, self.k
        header = Header(round(k * p.period_ms * 1e6), "rgbd")
        w, h = (p.width // 2, p.height // 2) if k in p.wrong_size else (p.width, p.height)
        _, rgb, depth = rgbd_frame(w, h)
        if k in p.nan_depth:
            depth = np.full(depth.shape, np.nan, np.float32)  # float depth in the same units (mm)
        if k in p.zero_depth:
            depth[:] = 0
        self.ctx.publish("camera_info", CameraInfo(header, p.width, p.height, "pinhole", self.K))
        if k in p.wrong_encoding:
            self.ctx.publish("rgb", Image(header, np.zeros((h, w, 4), np.float32), "rgbaf32"))
        else:
            self.ctx.publish("rgb", Image(header, rgb, "rgb8"))
        self.ctx.publish("depth", DepthImage(header, depth, 1000.0))
        self.ctx.publish("fisheye", Image(header, rgb, "rgb8"))
        self.k += 1
        if self.k >= p.count:
            self.ctx.stop()


class StallSource(Node):
    """Publishes ``count`` 4x4 frames, then nothing more and never ends (a driver that hangs)."""

    INPUTS = {"tick": Tick}
    OUTPUTS = {"image": Image}

    @dataclass(frozen=True)
    class Params:
        count: int = param(5, min=0)

    def setup(self):
        self.n = 0

    def on_input(self, name, msg):
        if self.n < self.params.count:
            self.ctx.publish("image", Image(Header(msg.header.stamp_ns, "cam"), np.zeros((4, 4, 1), np.uint8),
                                            "mono8"))
        self.n += 1


class StampLog(Node):
    """Records per input: [stamp, translation] for poses, [stamp, h, w, encoding] for images, [stamp, state,
    reason] for tracking states, else the stamp."""

    INPUTS = {"*": None}

    @dataclass(frozen=True)
    class Params:
        out: str = param()

    def setup(self):
        self.got: dict[str, list] = {}
        self.started = time.monotonic()

    def on_input(self, name, msg):
        if isinstance(msg, PoseStamped):
            item = [msg.header.stamp_ns, msg.translation.tolist()]
        elif isinstance(msg, Image):
            item = [msg.header.stamp_ns, *msg.data.shape[:2], msg.encoding]
        elif isinstance(msg, TrackingState):
            item = [msg.header.stamp_ns, msg.state, msg.reason]
        else:
            item = msg.header.stamp_ns
        self.got.setdefault(name, []).append(item)

    def close(self):
        Path(self.params.out).write_text(json.dumps(self.got))


class IgnoresSigterm(Node):
    """Ignores SIGTERM and SIGINT from setup on: only SIGKILL ends it. Starts a ``sleep`` child process that
    ignores SIGTERM too; writes "node_pid child_pid" to ``pid_file``."""

    INPUTS = {"tick": Tick}

    @dataclass(frozen=True)
    class Params:
        pid_file: str = param("")

    def setup(self):
        import os
        import subprocess

        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        self.child = subprocess.Popen(["sleep", "300"])  # inherits SIG_IGN for SIGTERM
        if self.params.pid_file:
            Path(self.params.pid_file).write_text(f"{os.getpid()} {self.child.pid}")

    def on_input(self, name, msg):
        time.sleep(0.01)
