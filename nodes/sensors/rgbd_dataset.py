"""RGB-D dataset player: plays a TUM, Redwood/Open3D or 7-Scenes folder as the rgbd camera of the rig.

Outputs (same names as the synthetic rig): ``rgb`` (Image rgb8), ``depth`` (DepthImage uint16, the
dataset's depth scale: TUM 5000, others 1000), ``rgbd/camera_info`` (pinhole, published with every
frame just before it) and ``gt/rgbd_pose`` (world_from_camera, only for frames with a pose).
Stamps are the dataset's (TUM) or frame / fps
(``stamps: wall``: the node clock when published). ``rate`` scales the recorded timing; ``rate: 0``
plays in lockstep, as fast as the graph consumes. At the end the node stops unless ``loop``
(each pass's stamps continue after the previous pass's). ``preload`` decodes every selected frame
in ``setup`` (before the graph starts) and plays from memory, so decoding does not compete with the
rest of the graph for the CPU (benchmarks; mind the memory: ~1.5 MB per 640x480 frame).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from probeless.datasets.detect import detect_format, open_rgbd, select
from probeless.datasets.playback import STAMPS, Playback
from probeless.datasets.stream import loop_period_ns, rgbd_groups
from probeless.datasets.textfiles import IntrinsicsOverride
from probeless.errors import DatasetError
from probeless.messages.geometry import PoseStamped
from probeless.messages.header import shift_stamp
from probeless.messages.sensor import CameraInfo, DepthImage, Image
from probeless.runtime import Node, param


def preloaded(groups: list, offset_ns: int):
    """The decoded ``groups`` again, stamps moved by ``offset_ns`` (a later pass of a loop)."""
    for stamp, msgs in groups:
        yield stamp + offset_ns, [(name, shift_stamp(m, offset_ns) if offset_ns else m) for name, m in msgs]


INTRINSICS = ("fx", "fy", "cx", "cy")


def _trajectory_problem(trajectory: str, p) -> str | None:
    """The trajectory param's rule (a param check): a Redwood dataset's .log, relative to the dataset folder."""
    if not trajectory:
        return None
    try:
        fmt = detect_format(p.path) if p.format == "auto" else p.format
    except DatasetError:
        return None  # the folder itself is reported (missing) or fails at start (unknown layout)
    path = Path(trajectory) if Path(trajectory).is_absolute() else Path(p.path) / trajectory
    if fmt == "redwood" and not path.is_file():
        return f"{path}: trajectory log is missing"
    return None


def _intrinsics_problem(key: str):
    """A param check of fx/fy/cx/cy: all four or none (reported once, on the first one given)."""
    def check(value, p) -> str | None:
        given = [k for k in INTRINSICS if getattr(p, k) is not None]
        if given and len(given) < 4 and given[0] == key:
            return ("intrinsics override needs all of fx, fy, cx, cy; "
                    f"missing {[k for k in INTRINSICS if k not in given]}")
        return None
    return check


class RgbdDatasetPlayer(Node):
    """Publishes the frames of an RGB-D dataset folder with their timing (see the module docstring)."""

    OUTPUTS = {"rgb": Image, "depth": DepthImage, "rgbd/camera_info": CameraInfo, "gt/rgbd_pose": PoseStamped}

    @dataclass(frozen=True)
    class Params:
        path: str = param(path="dir", must_exist=True, doc="dataset folder")
        format: str = param("auto", choices=("auto", "tum", "redwood", "7scenes"), doc="folder layout")
        rate: float = param(1.0, min=0.0, max=1000.0, doc="speed factor of the recorded timing; 0 = lockstep")
        loop: bool = param(False, doc="start again at the end")
        start: int = param(0, min=0, doc="first frame to play (index into the sequence)")
        max_frames: int = param(0, min=0, doc="frames to play; 0 = all")
        max_dt_s: float = param(0.02, min=0.0, doc="TUM: largest colour-depth stamp difference to pair [s]")
        fps: float = param(30.0, min=0.001, doc="frame rate of formats without stamps [Hz]")
        frame_id: str = param("rgbd", doc="frame_id of the images, child frame of the pose")
        stamps: str = param("dataset", choices=STAMPS,
                            doc="dataset = the recorded stamps; wall = the node clock at publishing (like live)")
        depth_scale: float = param(0.0, min=0.0, doc="depth units per metre; 0 = the format's")
        trajectory: str = param("", check=_trajectory_problem, doc="Redwood: .log file of poses (relative to the "
                                "dataset folder); empty = auto (groundtruth*.log preferred)")
        fx: float | None = param(None, check=_intrinsics_problem("fx"),
                                 doc="focal length override [px] (with fy, cx, cy)")
        fy: float | None = param(None, check=_intrinsics_problem("fy"), doc="focal length override [px]")
        cx: float | None = param(None, check=_intrinsics_problem("cx"), doc="principal point override [px]")
        cy: float | None = param(None, check=_intrinsics_problem("cy"), doc="principal point override [px]")
        preload: bool = param(False, doc="decode every frame before the graph starts and play from memory")

    def setup(self) -> None:
        p = self.params
        seq = open_rgbd(p.path, p.format, max_dt_s=p.max_dt_s, fps=p.fps,
                        intrinsics=IntrinsicsOverride(p.fx, p.fy, p.cx, p.cy), depth_scale=p.depth_scale,
                        trajectory=p.trajectory or None)
        self.seq = select(seq, p.start, p.max_frames)
        for note in self.seq.notes:
            self.ctx.log.warning("%s: %s", p.path, note)
        period = loop_period_ns([f.stamp_ns for f in self.seq.frames], self.seq.rate_hz)
        self.ctx.log.info("%s: %s, %d frames, intrinsics from %s", p.path, self.seq.format,
                          len(self.seq.frames), self.seq.intrinsics_source)
        groups = lambda k: rgbd_groups(self.seq, p.frame_id, k * period)  # noqa: E731
        if p.preload:
            cache = list(rgbd_groups(self.seq, p.frame_id, 0))
            groups = lambda k: preloaded(cache, k * period)  # noqa: E731
        self.playback = Playback(self.ctx, groups, rate=p.rate, loop=p.loop, what="RGB-D frames", stamps=p.stamps)

    def close(self) -> None:
        if getattr(self, "playback", None) is not None:
            self.playback.close()
