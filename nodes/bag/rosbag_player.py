"""ROS bag player node: plays a ROS 1 ``.bag``, a rosbag2 folder or one ``.mcap``/``.db3`` straight into a graph.

The messages are converted as ``probeless bag import`` converts them (:mod:`probeless.bag.ros_source`,
same presets and ``map`` items) and published on the rig's outputs: probeless topic ``rig/X`` -> output
``X`` (``remap`` renames more). Timing, ``rate``, ``loop``, ``lockstep``, ``start_s``/``duration_s``
and the clock output work as in ``bag_player`` (this node is one). The fisheye may come from a second
bag (``fisheye_bag``, preset ``fisheye_preset``) or a video or image folder (``fisheye_video`` with its
``fisheye_calibration`` from ``probeless calibrate fisheye``), moved onto the main bag's clock by
``fisheye_offset_s`` (a video's frame t is stamped at the main bag's start + offset + t). A real room has
no floorplan topic: ``floorplan`` names a YAML file with ``floorplan`` and ``ceiling_height`` (a scene
file's ``room`` works), published once at the start. Without a ground-truth topic, ``initial_pose``
(x y z qx qy qz qw, world_from_rgbd) is published on ``gt/rgbd_pose`` with the first colour frame.
"""

from __future__ import annotations

import heapq
import sys
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Iterator, NamedTuple

import numpy as np
import yaml

from probeless.bag import ros_topics as rt
from probeless.bag.ros_source import RosBag
from probeless.errors import BagError, ParamError
from probeless.geom.floorplan import check_floorplan
from probeless.geom.rotation import matrix_from_quat, transform_from
from probeless.launch.replay import parse_remaps
from probeless.messages.geometry import Floorplan, PoseStamped
from probeless.messages.header import Clock, Header
from probeless.messages.sensor import Image
from probeless.nodes.bag.player import GIL_SWITCH_S, READ_AHEAD, BagPlayer, _remap_problem
from probeless.runtime import param
from probeless.runtime.pacing import Pacer, ReadAhead


class Item(NamedTuple):
    topic: str          # probeless topic (rig/...)
    log_time_ns: int
    msg: Any


def load_floorplan(path: str) -> Floorplan:
    """The Floorplan of a YAML file with ``floorplan`` and ``ceiling_height`` (top level or under ``room``)."""
    doc = yaml.safe_load(Path(path).read_text()) or {}
    room = doc.get("room", doc) if isinstance(doc, dict) else {}
    if "floorplan" not in room or "ceiling_height" not in room:
        raise BagError(f"{path}: needs floorplan: [[x, y], ...] and ceiling_height (top level or under room:)")
    verts = check_floorplan(np.asarray(room["floorplan"], dtype=np.float64), f"{path}: floorplan")
    return Floorplan(Header(0, rt.WORLD_FRAME), verts, float(room["ceiling_height"]))


class RosbagPlayer(BagPlayer):
    """Publishes a ROS bag's messages, converted, on the rig's outputs (see the module docstring)."""

    OUTPUTS = {"*": None, "clock": Clock}

    @dataclass(frozen=True)
    class Params:
        path: str = param(path="any", must_exist=True, doc="ROS bag: .bag file, rosbag2 folder, .mcap or .db3")
        preset: str = param("realsense", choices=rt.PRESET_NAMES, doc="topic names of the bag (bag import --preset)")
        map: tuple[str, ...] = param((), doc="ROS_TOPIC=TOPIC items (bag import --map)")
        topics: tuple[str, ...] = param((), doc="probeless topics to play (rig/rgb, ...); empty = all")
        remap: tuple[str, ...] = param((), check=_remap_problem, doc="extra renames, from:=to (after rig/X -> X)")
        rate: float = param(1.0, min=0.0, max=1000.0, doc="speed factor; 0 = as fast as possible without loss")
        loop: bool = param(False, doc="start again at the end")
        lockstep: bool = param(False, doc="publish each message only after the graph has processed the last")
        start_s: float = param(0.0, min=0.0, doc="skip this much of the bag [s]")
        duration_s: float = param(0.0, min=0.0, doc="play only this much [s]; 0 = to the end")
        max_lag_s: float = param(0.05, min=0.0, doc="lag beyond which the schedule shifts [s]")
        fisheye_bag: str = param("", path="any", must_exist=True, doc="second ROS bag with the fisheye; '' = none")
        fisheye_preset: str = param("usb_cam", choices=rt.PRESET_NAMES, doc="topic names of fisheye_bag")
        fisheye_video: str = param("", path="any", must_exist=True, doc="fisheye video or image folder; '' = none")
        fisheye_calibration: str = param("", path="file", must_exist=True,
                                         doc="fisheye_video's calibration (probeless calibrate fisheye)")
        fisheye_offset_s: float = param(0.0, doc="fisheye clock -> bag clock [s] (video: after the bag's start)")
        floorplan: str = param("", path="file", must_exist=True, doc="YAML with floorplan and ceiling_height")
        initial_pose: tuple[float, ...] = param((), length=(0, 7), finite=True,
                                                doc="x y z qx qy qz qw world_from_rgbd when the bag has no "
                                                    "ground truth; empty = none")

    def setup(self) -> None:
        p = self.params
        sys.setswitchinterval(min(sys.getswitchinterval(), GIL_SWITCH_S))
        if p.fisheye_video and not p.fisheye_calibration:
            raise ParamError("fisheye_video needs fisheye_calibration", node_id=self.ctx.node_id,
                             key="fisheye_calibration")
        self.remap = parse_remaps(p.remap)
        only = set(p.topics) if p.topics else None
        self.bag = RosBag(p.path, p.preset, p.map, only=only)
        for topic, why in sorted(self.bag.skipped.items()):
            self.ctx.log.info("%s: skipping %s (%s)", p.path, topic, why)
        self.fisheye_bag = None
        if p.fisheye_bag:
            self.fisheye_bag = RosBag(p.fisheye_bag, p.fisheye_preset, (), only=[rt.FISHEYE, rt.FISHEYE_INFO],
                                      time_offset_ns=round(p.fisheye_offset_s * 1e9))
        self.video = self._open_video() if p.fisheye_video else None
        self.floorplan = load_floorplan(p.floorplan) if p.floorplan else None
        self.pose0 = None
        if p.initial_pose:
            x, y, z, *q = p.initial_pose
            self.pose0 = transform_from(matrix_from_quat(np.array(q) / np.linalg.norm(q)), np.array([x, y, z]))
        self.lockstep = p.lockstep or p.rate == 0
        self.epoch = self.published = 0
        self.last_clock_ns: int | None = None
        self.timer = self.ctx.create_timer(0.001, self._step, name="play")
        self._restart()

    def _open_video(self) -> Any:
        from probeless.cameras.io import load_calibration
        from probeless.datasets.fisheye import first_frame_size, open_fisheye

        footage = open_fisheye(self.params.fisheye_video)
        w, h = first_frame_size(footage)
        info = load_calibration(self.params.fisheye_calibration, width=w, height=h, frame_id=rt.FISHEYE_FRAME)
        return footage, info

    def _video_items(self, offset_ns: int) -> Iterator[Item]:
        from probeless.datasets.fisheye import fisheye_frames

        footage, info = self.video
        for stamp, data, enc in fisheye_frames(footage):
            t = stamp + offset_ns
            header = Header(t, rt.FISHEYE_FRAME)
            yield Item(rt.FISHEYE_INFO, t, replace(info, header=header))
            yield Item(rt.FISHEYE, t, Image(header, data, enc))

    def _items(self, start: int, end: int | None) -> Iterator[Item]:
        """Every source merged in log-time order, the floorplan first and the initial pose with the first rgb."""
        p = self.params
        external = self.fisheye_bag is not None or self.video is not None   # replaces the bag's own fisheye
        streams = [(Item(*m) for m in self.bag.messages(start, end)
                    if not (external and m[0] in (rt.FISHEYE, rt.FISHEYE_INFO)))]
        if self.fisheye_bag is not None:
            streams.append(Item(*m) for m in self.fisheye_bag.messages(start, end))
        if self.video is not None:
            base = self.bag.start_ns + round(p.fisheye_offset_s * 1e9)
            streams.append(m for m in self._video_items(base)
                           if m.log_time_ns >= start and (end is None or m.log_time_ns < end))
        if self.floorplan is not None:
            yield Item("rig/floorplan", start, replace(self.floorplan, header=Header(start, rt.WORLD_FRAME)))
        posed = self.pose0 is None
        for item in heapq.merge(*streams, key=lambda m: m.log_time_ns):
            if not posed and item.topic == rt.RGB:
                posed = True
                yield Item(rt.GT_POSE, item.log_time_ns, PoseStamped(Header(item.msg.header.stamp_ns, rt.WORLD_FRAME),
                                                                     rt.RIG_FRAME, self.pose0))
            yield item

    def _restart(self) -> None:
        p = self.params
        start = self.bag.start_ns + int(p.start_s * 1e9)
        end = start + int(p.duration_s * 1e9) if p.duration_s else None
        if getattr(self, "ahead", None) is not None:
            self.ahead.stop()
        self.ahead = ReadAhead(lambda: self._items(start, end), size=READ_AHEAD, name="rosbag-read-ahead")
        self.ahead.start()
        self.pending = None
        self.pacer = Pacer(p.rate) if p.rate > 0 else None
        self.first_log_ns = start

    def _output(self, topic: str) -> str:
        out = topic[4:] if topic.startswith("rig/") else topic
        return self.remap.get(topic, self.remap.get(out, out))

    def _publish(self, item: Item) -> None:
        if self.params.topics and item.topic not in self.params.topics:
            return
        if self._clock(item.log_time_ns) and self.lockstep:
            self.ctx.wait_quiescent()
        self.ctx.publish(self._output(item.topic), item.msg)
        self.published += 1
        if self.lockstep:
            self.ctx.wait_quiescent()

    def close(self) -> None:
        super().close()
        for bag in (getattr(self, "bag", None), getattr(self, "fisheye_bag", None)):
            if bag is not None:
                bag.close()
