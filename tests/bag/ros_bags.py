"""ROS bags for tests, written with ``rosbags`` from real frames in ../shared/data.

A realsense-ros-style bag: 7-Scenes Kinect frames (colour, uint16 mm depth as aligned depth, or as raw
depth with its own camera_info and a depth->colour tf), colour camera_info, tf_static with the colour,
depth and fisheye optical frames, a fisheye topic (the real chessboard fisheye images, usb_cam names)
and ground truth on ``/ground_truth/pose`` (geometry_msgs/PoseStamped, the 7-Scenes pose). Writes ROS 1
(``.bag``), rosbag2-sqlite3 and rosbag2-mcap, raw or compressed (jpeg colour, realsense
``compressedDepth`` png depth).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from locations import SHARED_DATA
from rosbags.typesys import Stores, get_typestore

SEVEN = SHARED_DATA / "rgbd" / "sevenscenes_kinect_0000-0399"
FISHEYE = SHARED_DATA / "fisheye" / "chessboards_fisheye1"
K_RGB = np.array([[585.0, 0, 320], [0, 585, 240], [0, 0, 1]])
T0_NS = 1_700_000_000_000_000_000
PERIOD_NS = 33_333_333
# rig frames (realsense-ros names); fisheye looks up: optical axis = colour's -y
COLOUR, DEPTH_FRAME, FISHEYE_FRAME, LINK = ("camera_color_optical_frame", "camera_depth_optical_frame",
                                           "fisheye_optical_frame", "camera_link")
LINK_FROM_COLOUR = np.array([[0, 0, 1, 0.0], [-1, 0, 0, 0.015], [0, -1, 0, 0.0], [0, 0, 0, 1]], float)
COLOUR_FROM_FISHEYE = np.array([[1, 0, 0, 0.02], [0, 0, 1, -0.05], [0, -1, 0, 0.01], [0, 0, 0, 1]], float)
COLOUR_FROM_DEPTH = np.array([[1, 0, 0, -0.015], [0, 1, 0, 0.0], [0, 0, 1, 0.0], [0, 0, 0, 1]], float)


def seven_frames(n: int) -> list[dict]:
    """Frames 0..n-1 of 7-Scenes: colour file bytes and decoded rgb8, depth uint16 mm, camera-to-world pose."""
    out = []
    for k in range(n):
        stem = SEVEN / f"frame-{k:06d}"
        jpg = (stem.parent / (stem.name + ".color.jpg")).read_bytes()
        rgb = cv2.cvtColor(cv2.imdecode(np.frombuffer(jpg, np.uint8), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
        depth = cv2.imread(str(stem.parent / (stem.name + ".depth.png")), cv2.IMREAD_UNCHANGED)
        pose = np.loadtxt(stem.parent / (stem.name + ".pose.txt"))
        U, _, Vt = np.linalg.svd(pose[:3, :3])
        pose[:3, :3] = U @ Vt
        out.append({"jpg": jpg, "rgb": rgb, "depth": depth, "pose": pose, "stamp": T0_NS + k * PERIOD_NS})
    return out


def fisheye_frames(n: int) -> list[dict]:
    """n real fisheye chessboard images (jpeg bytes and rgb8), stamped between the RGB-D frames."""
    out = []
    for k in range(n):
        jpg = (FISHEYE / f"Fisheye1_{k + 1}.jpg").read_bytes()
        rgb = cv2.cvtColor(cv2.imdecode(np.frombuffer(jpg, np.uint8), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
        out.append({"jpg": jpg, "rgb": rgb, "stamp": T0_NS + k * PERIOD_NS + PERIOD_NS // 2})
    return out


class _Builder:
    def __init__(self, ts):
        self.ts, self.T = ts, ts.types

    def header(self, stamp: int, frame: str):
        kw = {"seq": 0} if "seq" in self.T["std_msgs/msg/Header"].__dataclass_fields__ else {}
        return self.T["std_msgs/msg/Header"](stamp=self.T["builtin_interfaces/msg/Time"](
            sec=stamp // 10**9, nanosec=stamp % 10**9), frame_id=frame, **kw)

    def image(self, stamp, frame, data: np.ndarray, enc: str):
        data = np.ascontiguousarray(data)
        h, w = data.shape[:2]
        return self.T["sensor_msgs/msg/Image"](header=self.header(stamp, frame), height=h, width=w, encoding=enc,
                                               is_bigendian=0, step=data.strides[0],
                                               data=data.view(np.uint8).reshape(-1))

    def compressed(self, stamp, frame, data: bytes, fmt: str):
        return self.T["sensor_msgs/msg/CompressedImage"](header=self.header(stamp, frame), format=fmt,
                                                         data=np.frombuffer(data, np.uint8))

    def info(self, stamp, frame, w, h, K, model="plumb_bob", D=(0.0, 0.0, 0.0, 0.0, 0.0)):
        names = self.T["sensor_msgs/msg/CameraInfo"].__dataclass_fields__
        up = "K" in names
        kw = {("D" if up else "d"): np.array(D, float), ("K" if up else "k"): np.asarray(K, float).reshape(-1),
              ("R" if up else "r"): np.eye(3).reshape(-1),
              ("P" if up else "p"): np.hstack([np.asarray(K, float), np.zeros((3, 1))]).reshape(-1)}
        roi = self.T["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0, width=0, do_rectify=False)
        return self.T["sensor_msgs/msg/CameraInfo"](header=self.header(stamp, frame), height=h, width=w,
                                                    distortion_model=model, binning_x=0, binning_y=0, roi=roi, **kw)

    def _quat(self, R):
        from scipy.spatial.transform import Rotation
        x, y, z, w = Rotation.from_matrix(R).as_quat()
        return self.T["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w)

    def tf(self, stamp, pairs):
        ts = []
        for parent, child, T in pairs:
            v = self.T["geometry_msgs/msg/Vector3"](x=T[0, 3], y=T[1, 3], z=T[2, 3])
            ts.append(self.T["geometry_msgs/msg/TransformStamped"](
                header=self.header(stamp, parent), child_frame_id=child,
                transform=self.T["geometry_msgs/msg/Transform"](translation=v, rotation=self._quat(T[:3, :3]))))
        return self.T["tf2_msgs/msg/TFMessage"](transforms=ts)

    def imu(self, stamp, s):
        V = self.T["geometry_msgs/msg/Vector3"]
        q = s["q"]
        return self.T["sensor_msgs/msg/Imu"](
            header=self.header(stamp, "imu"), orientation=self.T["geometry_msgs/msg/Quaternion"](*q),
            orientation_covariance=s["q_cov"], angular_velocity=V(*s["w"]), angular_velocity_covariance=s["w_cov"],
            linear_acceleration=V(*s["a"]), linear_acceleration_covariance=s["a_cov"])

    def pose(self, stamp, frame, T):
        p = self.T["geometry_msgs/msg/Point"](x=T[0, 3], y=T[1, 3], z=T[2, 3])
        return self.T["geometry_msgs/msg/PoseStamped"](header=self.header(stamp, frame), pose=self.T[
            "geometry_msgs/msg/Pose"](position=p, orientation=self._quat(T[:3, :3])))


def imu_sample(stamp: int) -> dict:
    """A deterministic IMU sample for stamp (distinct values per field, so a swapped field shows)."""
    rng = np.random.default_rng(stamp % 2**32)
    q = rng.normal(size=4)
    return {"q": q / np.linalg.norm(q), "q_cov": rng.uniform(0, 1e-3, 9), "w": rng.normal(size=3),
            "w_cov": rng.uniform(0, 1e-4, 9), "a": rng.normal(size=3) + [0, 0, 9.81], "a_cov": np.full(9, -1.0)}


def compressed_depth(depth: np.ndarray) -> bytes:
    """image_transport compressedDepth of uint16 depth: 12-byte config header (format 0 = PNG, 0, 0) + PNG."""
    ok, png = cv2.imencode(".png", depth)
    assert ok
    return np.array([0], "<i4").tobytes() + np.zeros(2, "<f4").tobytes() + png.tobytes()


def write_rig_bag(path: Path, kind: str, *, frames: int = 3, fisheye: int = 2, compressed: bool = False,
                  raw_depth: bool = False) -> dict:
    """A realsense-ros-style bag at ``path``; kind: ros1 | sqlite3 | mcap. Returns what was written."""
    seven, fish = seven_frames(frames), fisheye_frames(fisheye)
    if kind == "ros1":
        from rosbags.rosbag1 import Writer
        from rosbags.typesys import get_types_from_msg
        ts = get_typestore(Stores.ROS1_NOETIC)
        ts.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"))
        writer = Writer(path)
    else:
        from rosbags.rosbag2 import StoragePlugin, Writer
        ts = get_typestore(Stores.ROS2_HUMBLE)
        writer = Writer(path, version=8, storage_plugin=StoragePlugin.MCAP if kind == "mcap" else StoragePlugin.SQLITE3)
    b = _Builder(ts)
    conns = {}
    ser = ts.serialize_ros1 if kind == "ros1" else ts.serialize_cdr
    h, w = seven[0]["depth"].shape
    fh, fw = fish[0]["rgb"].shape[:2]
    K_fish = np.array([[300.0, 0, fw / 2], [0, 300, fh / 2], [0, 0, 1]])
    depth_topic = "/camera/depth/image_rect_raw" if raw_depth else "/camera/aligned_depth_to_color/image_raw"
    with writer:
        def put(topic, msgtype, msg, t):
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, msgtype, typestore=ts)
            writer.write(conns[topic], t, ser(msg, msgtype))

        static = [(LINK, COLOUR, LINK_FROM_COLOUR), (LINK, DEPTH_FRAME, LINK_FROM_COLOUR @ COLOUR_FROM_DEPTH),
                  (LINK, FISHEYE_FRAME, LINK_FROM_COLOUR @ COLOUR_FROM_FISHEYE)]
        put("/tf_static", "tf2_msgs/msg/TFMessage", b.tf(T0_NS, static), T0_NS - 1000)
        events = [(f["stamp"], "rgbd", f) for f in seven] + [(f["stamp"], "fish", f) for f in fish]
        for t, what, f in sorted(events, key=lambda e: e[0]):
            rx = t + 2_000_000   # received 2 ms after the exposure
            if what == "fish":
                if compressed:
                    put("/usb_cam/image_raw/compressed", "sensor_msgs/msg/CompressedImage",
                        b.compressed(t, FISHEYE_FRAME, f["jpg"], "jpeg"), rx)
                else:
                    put("/usb_cam/image_raw", "sensor_msgs/msg/Image", b.image(t, FISHEYE_FRAME, f["rgb"], "rgb8"), rx)
                put("/usb_cam/camera_info", "sensor_msgs/msg/CameraInfo",
                    b.info(t, FISHEYE_FRAME, fw, fh, K_fish, "equidistant", (0.01, -0.002, 0.0, 0.0)), rx)
                continue
            dframe = DEPTH_FRAME if raw_depth else COLOUR
            if compressed:
                put("/camera/color/image_raw/compressed", "sensor_msgs/msg/CompressedImage",
                    b.compressed(t, COLOUR, f["jpg"], "rgb8; jpeg compressed bgr8"), rx)
                put(depth_topic + "/compressedDepth", "sensor_msgs/msg/CompressedImage",
                    b.compressed(t, dframe, compressed_depth(f["depth"]), "16UC1; compressedDepth"), rx)
            else:
                put("/camera/color/image_raw", "sensor_msgs/msg/Image", b.image(t, COLOUR, f["rgb"], "rgb8"), rx)
                put(depth_topic, "sensor_msgs/msg/Image", b.image(t, dframe, f["depth"], "16UC1"), rx)
            put("/camera/color/camera_info", "sensor_msgs/msg/CameraInfo", b.info(t, COLOUR, w, h, K_RGB), rx)
            if raw_depth:
                put("/camera/depth/camera_info", "sensor_msgs/msg/CameraInfo", b.info(t, DEPTH_FRAME, w, h, K_RGB), rx)
            put("/ground_truth/pose", "geometry_msgs/msg/PoseStamped", b.pose(t, "world", f["pose"]), rx)
            put("/camera/imu", "sensor_msgs/msg/Imu", b.imu(t, imu_sample(t)), rx)
            put("/camera/status", "std_msgs/msg/String", ts.types["std_msgs/msg/String"](data="ok"), rx)
    return {"seven": seven, "fisheye": fish, "K_fish": K_fish}
