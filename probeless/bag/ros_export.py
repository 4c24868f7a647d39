"""``probeless bag export --format ros2``: a probeless recording -> a rosbag2 folder (MCAP storage, CDR).

Mapping (ROS topic = ``/`` + probeless topic): Image and DepthImage -> sensor_msgs/Image (DepthImage:
16UC1 millimetres when its depth_scale is 1000, else 32FC1 metres), CameraInfo -> sensor_msgs/CameraInfo
(pinhole -> plumb_bob or rational_polynomial, kannala_brandt -> equidistant), PoseStamped ->
geometry_msgs/PoseStamped plus tf2_msgs/TFMessage on ``/tf`` (``/tf_static`` for extrinsics named
``*_from_*``), PointCloud (the SLAM model) -> sensor_msgs/PointCloud2 (x y z float32, rgb packed).
Types with no ROS equivalent (Cubemap, SHCoefficients, ...) are listed as not exported.
"""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from probeless.bag.export import ExportSummary, export_sources, open_readers
from probeless.bag.format import MESSAGE_ENCODING
from probeless.bag.ros_convert import quat_xyzw, ros_stamp
from probeless.bag.ros_source import require_rosbags
from probeless.errors import BagError
from probeless.progress import progress as progress_bar

ROS_ENCODING = {"rgb8": "rgb8", "bgr8": "bgr8", "rgba8": "rgba8", "bgra8": "bgra8", "mono8": "mono8",
                "mono16": "mono16", "rgb16": "rgb16", "monof32": "32FC1", "rgbf32": "32FC3", "rgbaf32": "32FC4",
                "monof16": "32FC1", "rgbf16": "32FC3", "rgbaf16": "32FC4"}
ROS_TYPES = {"sensor/Image": "sensor_msgs/msg/Image", "sensor/DepthImage": "sensor_msgs/msg/Image",
             "sensor/CameraInfo": "sensor_msgs/msg/CameraInfo", "geometry/PoseStamped": "geometry_msgs/msg/PoseStamped",
             "mesh/PointCloud": "sensor_msgs/msg/PointCloud2", "sensor/Imu": "sensor_msgs/msg/Imu"}


class _Ros2:
    """Builders of ROS 2 messages from one typestore."""

    def __init__(self, ts: Any):
        self.ts, self.T = ts, ts.types

    def header(self, h: Any) -> Any:
        sec, nsec = ros_stamp(h.stamp_ns)
        return self.T["std_msgs/msg/Header"](stamp=self.T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec),
                                            frame_id=h.frame_id)

    def image(self, msg: Any, summary: ExportSummary, topic: str) -> Any:
        if hasattr(msg, "depth_scale"):
            if msg.data.dtype == np.uint16 and msg.depth_scale == 1000.0:
                data, enc = msg.data, "16UC1"
            else:
                data, enc = msg.metres(), "32FC1"
                summary.note(f"{topic}: depth exported as 32FC1 metres (depth_scale {msg.depth_scale})")
            data = data[:, :, None]
        else:
            data, enc = msg.data, ROS_ENCODING[msg.encoding]
            if data.dtype == np.float16:
                data = data.astype(np.float32)
                summary.note(f"{topic}: {msg.encoding} widened to {enc} (ROS has no half-float encoding)")
        data = np.ascontiguousarray(data)
        h, w, c = data.shape
        return self.T["sensor_msgs/msg/Image"](
            header=self.header(msg.header), height=h, width=w, encoding=enc, is_bigendian=0,
            step=w * c * data.dtype.itemsize, data=data.view(np.uint8).reshape(-1))

    def camera_info(self, msg: Any, summary: ExportSummary, topic: str) -> Any | None:
        D = np.asarray(msg.D, np.float64)
        if msg.model == "kannala_brandt":
            model, D = "equidistant", np.pad(D, (0, 4 - len(D)))
        elif msg.model == "pinhole" and len(D) in (0, 4, 5):
            model, D = "plumb_bob", np.pad(D, (0, 5 - len(D)))
        elif msg.model == "pinhole" and len(D) == 8:
            model = "rational_polynomial"
        else:
            summary.note(f"{topic}: camera model {msg.model!r} with {len(D)} coefficients has no ROS "
                         "distortion model: not exported")
            return None
        K = np.asarray(msg.K, np.float64)
        P = np.hstack([K, np.zeros((3, 1))])
        Roi = self.T["sensor_msgs/msg/RegionOfInterest"]
        return self.T["sensor_msgs/msg/CameraInfo"](
            header=self.header(msg.header), height=msg.height, width=msg.width, distortion_model=model,
            d=D, k=K.reshape(-1), r=np.eye(3).reshape(-1), p=P.reshape(-1), binning_x=0, binning_y=0,
            roi=Roi(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False))

    def _pose(self, T: np.ndarray) -> tuple[Any, Any]:
        q = quat_xyzw(T)
        return (self.T["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3]),
                T[:3, 3].astype(np.float64))

    def pose(self, msg: Any) -> Any:
        q, t = self._pose(msg.target_from_source)
        p = self.T["geometry_msgs/msg/Point"](x=t[0], y=t[1], z=t[2])
        return self.T["geometry_msgs/msg/PoseStamped"](
            header=self.header(msg.header), pose=self.T["geometry_msgs/msg/Pose"](position=p, orientation=q))

    def tf(self, msg: Any) -> Any:
        q, t = self._pose(msg.target_from_source)
        v = self.T["geometry_msgs/msg/Vector3"](x=t[0], y=t[1], z=t[2])
        ts = self.T["geometry_msgs/msg/TransformStamped"](
            header=self.header(msg.header), child_frame_id=msg.child_frame_id,
            transform=self.T["geometry_msgs/msg/Transform"](translation=v, rotation=q))
        return self.T["tf2_msgs/msg/TFMessage"](transforms=[ts])

    def imu(self, msg: Any) -> Any:
        q, V = msg.orientation, self.T["geometry_msgs/msg/Vector3"]
        return self.T["sensor_msgs/msg/Imu"](
            header=self.header(msg.header),
            orientation=self.T["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3]),
            orientation_covariance=msg.orientation_covariance.copy(),
            angular_velocity=V(*(float(v) for v in msg.angular_velocity)),
            angular_velocity_covariance=msg.angular_velocity_covariance.copy(),
            linear_acceleration=V(*(float(v) for v in msg.linear_acceleration)),
            linear_acceleration_covariance=msg.linear_acceleration_covariance.copy())

    def cloud(self, msg: Any) -> Any:
        n = len(msg.points)
        colors = msg.colors if msg.colors.dtype == np.uint8 else \
            np.clip(np.round(msg.colors * 255), 0, 255).astype(np.uint8)
        rgb = (colors[:, 0].astype(np.uint32) << 16) | (colors[:, 1].astype(np.uint32) << 8) | colors[:, 2]
        rec = np.empty(n, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("rgb", "<u4")])
        rec["x"], rec["y"], rec["z"], rec["rgb"] = msg.points[:, 0], msg.points[:, 1], msg.points[:, 2], rgb
        F = self.T["sensor_msgs/msg/PointField"]
        fields = [F(name=k, offset=4 * i, datatype=7, count=1) for i, k in enumerate("xyz")]
        fields.append(F(name="rgb", offset=12, datatype=7, count=1))   # FLOAT32 holding packed 0x00RRGGBB (PCL)
        return self.T["sensor_msgs/msg/PointCloud2"](
            header=self.header(msg.header), height=1, width=n, fields=fields, is_bigendian=False, point_step=16,
            row_step=16 * n, data=rec.view(np.uint8).reshape(-1), is_dense=True)


def export_ros2(src: str | Path | Sequence[str | Path], out: str | Path, *, force: bool = False,
                topics: Sequence[str] | None = None, progress: bool = False) -> ExportSummary:
    """Write the recording(s) ``src`` as the rosbag2 folder ``out`` (MCAP storage, CDR)."""
    require_rosbags()
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    sources, out = export_sources(src, out, force)
    if out.exists():
        shutil.rmtree(out) if out.is_dir() else out.unlink()
    summary = ExportSummary()
    ros = _Ros2(get_typestore(Stores.ROS2_HUMBLE))
    readers, total = open_readers(sources, topics, summary)
    conns: dict[tuple[str, str], Any] = {}
    try:
        with Writer(out, version=8, storage_plugin=StoragePlugin.MCAP) as w, \
                progress_bar(total, f"export {out.name}/", progress) as tick:
            def put(topic: str, msgtype: str, msg: Any, t: int) -> None:
                if (topic, msgtype) not in conns:
                    conns[(topic, msgtype)] = w.add_connection(topic, msgtype, typestore=ros.ts)
                w.write(conns[(topic, msgtype)], t, ros.ts.serialize_cdr(msg, msgtype))

            for r in readers:
                for ch, rec in r.records(topics=topics, on_corrupt=summary.warnings.append):
                    tick()
                    _one(r, ch, rec, ros, put, summary)
    finally:
        for r in readers:
            r.close()
    return summary


def _one(r: Any, ch: Any, rec: Any, ros: _Ros2, put: Any, summary: ExportSummary) -> None:
    topic = ch.topic
    if ch.message_encoding != MESSAGE_ENCODING:
        summary.skipped[topic] = summary.skipped.get(topic, 0) + 1
        summary.schemas.setdefault(topic, f"not exported: {ch.message_encoding} channel")
        return
    bm = r.message_of(ch, rec)
    rtype = ROS_TYPES.get(bm.type_name)
    if rtype is None:
        summary.skipped[topic] = summary.skipped.get(topic, 0) + 1
        summary.schemas.setdefault(topic, f"not exported: {bm.type_name} has no ROS equivalent")
        return
    msg = r.decode(bm)
    name, t = "/" + topic.lstrip("/"), bm.log_time_ns
    try:
        if bm.type_name in ("sensor/Image", "sensor/DepthImage"):
            put(name, rtype, ros.image(msg, summary, topic), t)
        elif bm.type_name == "sensor/CameraInfo":
            info = ros.camera_info(msg, summary, topic)
            if info is None:
                summary.skipped[topic] = summary.skipped.get(topic, 0) + 1
                summary.schemas.setdefault(topic, f"not exported: camera model {msg.model}")
                return
            put(name, rtype, info, t)
        elif bm.type_name == "geometry/PoseStamped":
            put(name, rtype, ros.pose(msg), t)
            static = "_from_" in topic.rsplit("/", 1)[-1]
            put("/tf_static" if static else "/tf", "tf2_msgs/msg/TFMessage", ros.tf(msg), t)
        elif bm.type_name == "sensor/Imu":
            put(name, rtype, ros.imu(msg), t)
        else:
            put(name, rtype, ros.cloud(msg), t)
    except (KeyError, ValueError, TypeError) as exc:
        raise BagError(f"{r.path}: topic {topic!r}: cannot write as {rtype} ({exc})") from None
    summary.written[topic] = summary.written.get(topic, 0) + 1
    summary.schemas[topic] = rtype + (" + TFMessage" if bm.type_name == "geometry/PoseStamped" else "")
