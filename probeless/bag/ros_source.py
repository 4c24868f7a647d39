"""Read a ROS bag (ROS 1 ``.bag``, a rosbag2 folder, or one ``.mcap``/``.db3``) as probeless messages.

:class:`RosBag` opens the bag with ``rosbags`` (an optional extra: ``pip install 'probeless[ros]'``),
names every topic's role from a preset and ``--map`` items (:mod:`probeless.bag.ros_topics`), reads
the static calibration first (tf_static, the Viewer's extrinsics, the first camera_info of each
camera) and then yields ``(topic, log_time_ns, message)`` in the bag's order: the header stamps are
kept, log times are the bag's receive times. Raw depth is registered to colour when the bag has no
aligned depth; ``rig/fisheye_from_rgbd`` comes from tf when both camera frames are in the tree.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Iterator

import numpy as np

from probeless.bag import ros_topics as rt
from probeless.bag.ros_convert import (
    RosConvertError,
    camera_info_from_ros,
    compressed_from_ros,
    image_from_ros,
    imu_from_ros,
    pose_from_ros,
    register_depth,
    stamp_ns,
    transform_of,
)
from probeless.bag.ros_reader import open_any_reader
from probeless.errors import BagError
from probeless.geom.rotation import invert_transform
from probeless.messages.geometry import PoseStamped
from probeless.messages.header import Header, shift_stamp

INSTALL_HINT = "reading and writing ROS bags needs the rosbags package: pip install 'probeless[ros]'"
IMAGE_TYPES = {"sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage"}
POSE_TYPES = {"geometry_msgs/msg/PoseStamped", "nav_msgs/msg/Odometry"}
TF_TYPE = "tf2_msgs/msg/TFMessage"
IMU_TYPE = "sensor_msgs/msg/Imu"
CONVERTED = IMAGE_TYPES | POSE_TYPES | {TF_TYPE, IMU_TYPE, "sensor_msgs/msg/CameraInfo"}


def require_rosbags() -> Any:
    """The ``rosbags`` package, or BagError saying what to install."""
    try:
        import rosbags.highlevel  # noqa: F401
        import rosbags.typesys
    except ImportError:
        raise BagError(INSTALL_HINT) from None
    return rosbags


class TfTree:
    """Latest transforms by (parent, child); chains resolved through any path of the tree."""

    def __init__(self) -> None:
        self.edges: dict[tuple[str, str], np.ndarray] = {}   # (parent, child) -> parent_from_child

    def add(self, msg: Any) -> list[tuple[str, str, int]]:
        """Add a TFMessage; the (parent, child, stamp) of its transforms."""
        out = []
        for t in msg.transforms:
            parent, child = rt.normalise_frame(t.header.frame_id), rt.normalise_frame(t.child_frame_id)
            self.edges[(parent, child)] = transform_of(t.transform)
            out.append((parent, child, stamp_ns(t.header)))
        return out

    def lookup(self, target: str, source: str) -> np.ndarray | None:
        """target_from_source, None when the frames are not connected."""
        target, source = rt.normalise_frame(target), rt.normalise_frame(source)
        adj: dict[str, list[tuple[str, np.ndarray]]] = {}   # frame f -> [(g, g_from_f)]
        for (p, c), T in self.edges.items():
            adj.setdefault(c, []).append((p, T))
            adj.setdefault(p, []).append((c, invert_transform(T)))
        seen, todo = {source: np.eye(4)}, [source]   # frame -> frame_from_source
        while todo:
            f = todo.pop()
            for g, g_from_f in adj.get(f, ()):
                if g not in seen:
                    seen[g] = g_from_f @ seen[f]
                    todo.append(g)
        return seen.get(target)


@dataclass
class Calibration:
    """What the pre-pass found: camera infos (ROS messages) and the static tf tree."""

    infos: dict[str, Any] = field(default_factory=dict)        # role -> first ROS CameraInfo
    tree: TfTree = field(default_factory=TfTree)
    viewer_depth_from_colour: np.ndarray | None = None


class RosBag:
    """One ROS bag read as probeless messages (see the module docstring)."""

    def __init__(self, path: str | Path, preset: str | None = None, maps: Iterable[str] = (), *,
                 time_offset_ns: int = 0, only: Iterable[str] | None = None):
        require_rosbags()
        from rosbags.typesys import Stores, get_typestore

        self.path = Path(path)
        if not self.path.exists():
            raise BagError(f"{self.path}: no such file or folder")
        self.preset = preset
        self.table = rt.topic_table(preset, maps)
        self.world = rt.PRESETS[preset]["world"] if preset else "map"
        self.ground_truth = bool(preset and rt.PRESETS[preset]["ground_truth"])
        self.identity = bool(preset and rt.PRESETS[preset].get("identity"))
        self.offset = int(time_offset_ns)
        self.reader, unparsed = open_any_reader(self.path, get_typestore(Stores.ROS2_HUMBLE))
        self.roles: dict[str, str] = {}        # ros topic -> probeless topic or @role
        self.skipped: dict[str, str] = {}      # ros topic -> why
        only = None if only is None else set(only)
        for c in self.reader.connections:
            role = self.table.get(c.topic)
            if role is None and self.identity:
                role = c.topic.lstrip("/")
            if c.msgtype in unparsed:
                self.skipped[c.topic] = f"{c.msgtype}: {unparsed[c.msgtype]}"
            elif role is None or role == rt.IGNORE:
                self.skipped[c.topic] = f"{c.msgtype}: named by no preset or --map" if role is None else \
                    f"{c.msgtype}: not needed"
            elif c.msgtype not in CONVERTED and role != rt.VIEWER_TF:
                self.skipped[c.topic] = f"{c.msgtype}: no probeless message type for it"
            elif only is not None and not role.startswith("@") and role not in only:
                self.skipped[c.topic] = f"{c.msgtype}: not selected"
            else:
                self.roles[c.topic] = role
        self.has_aligned_depth = rt.DEPTH in self.roles.values()
        for topic, role in list(self.roles.items()):
            if role == rt.DEPTH_RAW and self.has_aligned_depth:
                self.skipped[topic] = "raw depth: the bag has aligned depth"
                del self.roles[topic]
        self.calibration = self._pre_pass()
        self.fisheye_from_rgbd = self._extrinsics()
        self.colour_from_depth = self._depth_extrinsics()

    # -- calibration -----------------------------------------------------------------------

    def _connections(self, roles: set[str]) -> list[Any]:
        return [c for c in self.reader.connections if self.roles.get(c.topic) in roles]

    def _deserialize(self, raw: bytes, conn: Any) -> Any:
        try:
            return self.reader.deserialize(raw, conn.msgtype)
        except Exception as exc:
            raise BagError(f"{self.path}: topic {conn.topic}: cannot decode {conn.msgtype} "
                           f"({type(exc).__name__}: {exc})") from None

    def _pre_pass(self) -> Calibration:
        cal = Calibration()
        conns = self._connections({rt.TF_STATIC, rt.RGB_INFO, rt.DEPTH_INFO, rt.FISHEYE_INFO, rt.VIEWER_TF})
        if not conns:
            return cal
        for conn, _, raw in self._read(conns):
            role = self.roles[conn.topic]
            msg = self._deserialize(raw, conn)
            if role == rt.TF_STATIC:
                cal.tree.add(msg)
            elif role == rt.VIEWER_TF:
                cal.viewer_depth_from_colour = transform_of(msg)
            else:
                cal.infos.setdefault(role, msg)
        return cal

    def _read(self, conns: list[Any], start: int | None = None, stop: int | None = None) -> Iterator:
        try:
            yield from self.reader.messages(connections=conns, start=start, stop=stop)
        except BagError:
            raise
        except Exception as exc:
            raise BagError(f"{self.path}: the bag is corrupt ({type(exc).__name__}: {exc})") from None

    def _frame(self, role: str) -> str | None:
        info = self.calibration.infos.get(role)
        return rt.normalise_frame(info.header.frame_id) if info is not None and info.header.frame_id else None

    def _extrinsics(self) -> np.ndarray | None:
        rgb, fish = self._frame(rt.RGB_INFO), self._frame(rt.FISHEYE_INFO)
        if rgb is None or fish is None:
            return None
        return self.calibration.tree.lookup(fish, rgb)

    def _depth_extrinsics(self) -> np.ndarray | None:
        if rt.DEPTH_RAW not in self.roles.values():
            return None
        cal = self.calibration
        missing = [name for role, name in ((rt.DEPTH_INFO, "depth camera_info"), (rt.RGB_INFO, "colour camera_info"))
                   if role not in cal.infos]
        if missing:
            raise BagError(f"{self.path}: raw depth without aligned depth needs {' and '.join(missing)} to be "
                           "registered to colour; the bag has none")
        if cal.viewer_depth_from_colour is not None:
            return invert_transform(cal.viewer_depth_from_colour)
        T = cal.tree.lookup(self._frame(rt.RGB_INFO) or "", self._frame(rt.DEPTH_INFO) or "")
        if T is None:
            raise BagError(f"{self.path}: raw depth needs the depth->colour extrinsics: no tf_static chain from "
                           f"{self._frame(rt.DEPTH_INFO)!r} to {self._frame(rt.RGB_INFO)!r}")
        return T

    # -- messages --------------------------------------------------------------------------

    @property
    def start_ns(self) -> int:
        """Receive time of the first message of the bag, the clock offset applied [ns]."""
        return int(self.reader.start_time) + self.offset

    @property
    def end_ns(self) -> int:
        """Receive time of the last message, the clock offset applied [ns]."""
        return int(self.reader.end_time) + self.offset

    @property
    def message_count(self) -> int:
        """Messages on the topics that are converted (what a progress bar counts)."""
        return sum(c.msgcount for c in self.reader.connections if c.topic in self.roles)

    def _convert(self, conn: Any, msg: Any) -> list[tuple[str, Any]]:
        role, topic, t = self.roles[conn.topic], conn.topic, conn.msgtype
        if t in IMAGE_TYPES:
            frame = self._frame_of(role, msg)
            out = (compressed_from_ros if t.endswith("CompressedImage") else image_from_ros)(msg, topic, frame)
            if role == rt.DEPTH_RAW:
                return [(rt.DEPTH, self._register(out, topic))]
            return [(role, out)]
        if t == "sensor_msgs/msg/CameraInfo":
            if role.startswith("@"):
                return []
            return [(role, camera_info_from_ros(msg, topic, self._frame_of(role, msg)))]
        if t == TF_TYPE:
            return self._tf(msg, role)
        if t in POSE_TYPES:
            world = msg.header.frame_id if self.identity else rt.WORLD_FRAME
            child = getattr(msg, "child_frame_id", "") or rt.RIG_FRAME
            pose = pose_from_ros(msg, topic, world, child)
            return [(rt.POSE if role.startswith("@") else role, pose)]
        if t == IMU_TYPE:
            return [(role, imu_from_ros(msg, topic, rt.normalise_frame(msg.header.frame_id) or "imu"))]
        raise RosConvertError(f"{topic}: message type {t} cannot be converted (supported: Image, CompressedImage, "
                              "CameraInfo, TFMessage, PoseStamped, Odometry, Imu)")

    def _frame_of(self, role: str, msg: Any) -> str:
        """Our frame of a camera topic: the rig's names (rgbd, fisheye), the header's with preset probeless."""
        if self.identity:
            return msg.header.frame_id
        return rt.FRAME_OF.get(role, rt.RIG_FRAME if role == rt.DEPTH_RAW else role.rsplit("/", 1)[-1])

    def _register(self, depth: Any, topic: str) -> Any:
        cal = self.calibration
        return register_depth(depth, camera_info_from_ros(cal.infos[rt.DEPTH_INFO], topic, rt.RIG_FRAME),
                              camera_info_from_ros(cal.infos[rt.RGB_INFO], topic, rt.RIG_FRAME),
                              self.colour_from_depth)

    def _tf(self, msg: Any, role: str) -> list[tuple[str, Any]]:
        tree = self.calibration.tree
        stamps = tree.add(msg)
        rgb = self._frame(rt.RGB_INFO)
        if role != rt.TF or not self.ground_truth or rgb is None or not stamps:
            return []
        T = tree.lookup(self.world, rgb)
        if T is None:
            return []
        return [(rt.GT_POSE, PoseStamped(Header(max(s for _, _, s in stamps), rt.WORLD_FRAME), rt.RIG_FRAME, T))]

    def first_infos(self) -> list[tuple[str, Any]]:
        """(topic, CameraInfo) of the first camera_info of each camera, for a player to publish before the
        images (a bag may hold an image before its first camera_info)."""
        out = []
        for role in (rt.RGB_INFO, rt.FISHEYE_INFO):
            msg = self.calibration.infos.get(role)
            if msg is not None and role in self.roles.values():
                info = camera_info_from_ros(msg, role, self._frame_of(role, msg))
                out.append((role, shift_stamp(info, self.offset) if self.offset else info))
        return out

    def messages(self, start_ns: int | None = None, end_ns: int | None = None) -> Iterator[tuple[str, int, Any]]:
        """``(probeless topic, log time [ns], message)`` in receive order, times in ``[start_ns, end_ns)``
        (the clock offset applied); ``rig/fisheye_from_rgbd`` first when tf gives it."""
        first = True
        conns = [c for c in self.reader.connections if c.topic in self.roles
                 and self.roles[c.topic] not in (rt.TF_STATIC, rt.VIEWER_TF, rt.DEPTH_INFO)]
        start = None if start_ns is None else start_ns - self.offset
        stop = None if end_ns is None else end_ns - self.offset
        sent: set[tuple[str, int]] = set()
        for conn, t, raw in self._read(conns, start, stop):
            t += self.offset
            if first:
                if self.fisheye_from_rgbd is not None:
                    yield rt.EXTRINSICS, t, PoseStamped(Header(t, rt.FISHEYE_FRAME), rt.RIG_FRAME,
                                                        self.fisheye_from_rgbd)
                for topic, info in self.first_infos():   # calibration before the first image: consumers wait for it
                    sent.add((topic, info.header.stamp_ns))
                    yield topic, t, info
            first = False
            for topic, msg in self._convert(conn, self._deserialize(raw, conn)):
                if sent and (topic, getattr(msg.header, "stamp_ns", None)) in sent:
                    sent.discard((topic, msg.header.stamp_ns))
                    continue
                if self.offset:
                    msg = shift_stamp(msg, self.offset)
                yield topic, t, msg

    def close(self) -> None:
        """Close the bag."""
        try:
            self.reader.close()
        except Exception:
            pass

    def __enter__(self) -> RosBag:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
