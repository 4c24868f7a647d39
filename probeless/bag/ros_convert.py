"""ROS messages (as deserialized by ``rosbags``, ROS 1 or ROS 2) -> probeless messages, and back.

Only field access: no ROS install and no ``rosbags`` import here. ROS 1 and ROS 2 spell some fields
differently (``K``/``k``, ``D``/``d``); :func:`_field` reads either. Every conversion that cannot be done
raises :class:`RosConvertError` naming the topic and the encoding or model at fault.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np

from probeless.errors import BagError
from probeless.geom.rotation import matrix_from_quat, quat_from_matrix, transform_from
from probeless.messages.geometry import PoseStamped
from probeless.messages.header import Header
from probeless.messages.sensor import CameraInfo, DepthImage, Image, Imu

# ROS image encodings -> (numpy dtype, channels, our Image encoding); 16UC1/32FC1 are depth
COLOUR_ENCODINGS = {"rgb8": ("uint8", 3, "rgb8"), "bgr8": ("uint8", 3, "bgr8"), "rgba8": ("uint8", 4, "rgba8"),
                    "bgra8": ("uint8", 4, "bgra8"), "mono8": ("uint8", 1, "mono8"), "8UC1": ("uint8", 1, "mono8"),
                    "mono16": ("uint16", 1, "mono16"), "8UC3": ("uint8", 3, "bgr8")}
DEPTH_ENCODINGS = {"16UC1": ("uint16", 1000.0), "32FC1": ("float32", 1.0)}
# ROS distortion_model -> (our CameraInfo.model, coefficient counts kept)
DISTORTION_MODELS = {"plumb_bob": "pinhole", "rational_polynomial": "pinhole", "equidistant": "kannala_brandt",
                     "": "pinhole"}


class RosConvertError(BagError):
    """A ROS message that cannot become a probeless one (the message names topic and encoding/model)."""


def _field(msg: Any, *names: str) -> Any:
    for n in names:
        if hasattr(msg, n):
            return getattr(msg, n)
    raise AttributeError(f"{type(msg).__name__} has none of {names}")


def stamp_ns(header: Any) -> int:
    """Nanoseconds of a ROS header's stamp (ROS 1 or 2)."""
    st = header.stamp
    return int(_field(st, "sec", "secs")) * 1_000_000_000 + int(_field(st, "nanosec", "nsecs"))


def ros_stamp(ns: int) -> tuple[int, int]:
    """(sec, nanosec) of a stamp [ns]."""
    return int(ns) // 1_000_000_000, int(ns) % 1_000_000_000


def _pixels(msg: Any, topic: str, dtype: str, channels: int) -> np.ndarray:
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    dt = np.dtype(dtype).newbyteorder(">" if msg.is_bigendian else "<")
    row = w * channels * dt.itemsize
    data = np.frombuffer(memoryview(msg.data), dtype=np.uint8)
    if step < row or data.size < step * h:
        raise RosConvertError(f"{topic}: {msg.encoding} image {w}x{h} holds {data.size} bytes with step {step}, "
                              f"needs {row} per row")
    rows = data[:step * h].reshape(h, step)[:, :row]
    out = np.ascontiguousarray(rows).view(dt).reshape(h, w, channels)
    return out.astype(dt.newbyteorder("="), copy=False)


def image_from_ros(msg: Any, topic: str, frame_id: str) -> Image | DepthImage:
    """A sensor_msgs/Image: colour/mono encodings -> Image; 16UC1 (mm) and 32FC1 (m) -> DepthImage."""
    header = Header(stamp_ns(msg.header), frame_id)
    enc = msg.encoding
    if enc in DEPTH_ENCODINGS:
        dtype, scale = DEPTH_ENCODINGS[enc]
        return DepthImage(header, _pixels(msg, topic, dtype, 1)[:, :, 0].copy(), scale)
    if enc not in COLOUR_ENCODINGS:
        raise RosConvertError(f"{topic}: image encoding {enc!r} cannot be converted "
                              f"(supported: {', '.join(sorted(COLOUR_ENCODINGS) + sorted(DEPTH_ENCODINGS))})")
    dtype, channels, ours = COLOUR_ENCODINGS[enc]
    return Image(header, _pixels(msg, topic, dtype, channels), ours)


def _compressed_depth(msg: Any, topic: str, header: Header) -> DepthImage:
    """image_transport's compressedDepth: a 12-byte config header (format, depth quantisation a, b),
    then a PNG: uint16 depth as is, or 32FC1 as inverse depth ``q = a / (z - b)``."""
    fmt = msg.format.replace(" ", "")
    raw = bytes(msg.data)
    png = cv2.imdecode(np.frombuffer(raw[12:], np.uint8), cv2.IMREAD_UNCHANGED)
    if png is None:   # some writers leave the config header out
        png = cv2.imdecode(np.frombuffer(raw, np.uint8), cv2.IMREAD_UNCHANGED)
    if png is None or png.dtype != np.uint16 or png.ndim != 2:
        raise RosConvertError(f"{topic}: compressed depth ({msg.format!r}) does not decode to a 16-bit PNG")
    if fmt.startswith("32FC1"):
        a, b = np.frombuffer(raw[4:12], "<f4")
        q = png.astype(np.float32)
        with np.errstate(divide="ignore"):
            z = np.where(q > 0, a / (q - b), 0.0).astype(np.float32)
        return DepthImage(header, z, 1.0)
    return DepthImage(header, png, 1000.0)


def compressed_from_ros(msg: Any, topic: str, frame_id: str) -> Image | DepthImage:
    """A sensor_msgs/CompressedImage: jpeg/png colour or mono -> Image (rgb8, mono8 or mono16);
    realsense/image_transport ``compressedDepth`` -> DepthImage."""
    header = Header(stamp_ns(msg.header), frame_id)
    fmt = (msg.format or "").lower()
    if "compresseddepth" in fmt:
        return _compressed_depth(msg, topic, header)
    if not any(k in fmt for k in ("jpeg", "jpg", "png")) and fmt:
        raise RosConvertError(f"{topic}: compressed image format {msg.format!r} cannot be converted "
                              "(supported: jpeg, png, compressedDepth)")
    img = cv2.imdecode(np.frombuffer(bytes(msg.data), np.uint8), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise RosConvertError(f"{topic}: compressed image ({msg.format!r}) does not decode")
    if img.ndim == 2:
        enc = "mono16" if img.dtype == np.uint16 else "mono8"
        return Image(header, img[:, :, None], enc)
    if img.dtype != np.uint8:
        raise RosConvertError(f"{topic}: compressed {img.dtype} colour ({msg.format!r}) cannot be converted")
    code = cv2.COLOR_BGRA2RGBA if img.shape[2] == 4 else cv2.COLOR_BGR2RGB
    return Image(header, cv2.cvtColor(img, code), "rgba8" if img.shape[2] == 4 else "rgb8")


def camera_info_from_ros(msg: Any, topic: str, frame_id: str) -> CameraInfo:
    """A sensor_msgs/CameraInfo -> CameraInfo: plumb_bob (k1 k2 p1 p2 k3) and rational_polynomial
    (k1 k2 p1 p2 k3 k4 k5 k6) -> pinhole, equidistant (k1..k4) -> kannala_brandt."""
    model = msg.distortion_model
    if model not in DISTORTION_MODELS:
        raise RosConvertError(f"{topic}: distortion model {model!r} cannot be converted "
                              f"(supported: {', '.join(m for m in DISTORTION_MODELS if m)})")
    K = np.asarray(_field(msg, "k", "K"), dtype=np.float64).reshape(3, 3)
    D = np.asarray(_field(msg, "d", "D"), dtype=np.float64)
    ours = DISTORTION_MODELS[model]
    if ours == "kannala_brandt":
        D = D[:4] if len(D) >= 4 else np.zeros(0)
    elif len(D) not in (0, 4, 5, 8, 12, 14):
        D = D[:8] if len(D) > 8 else D[:5] if len(D) > 5 else np.pad(D, (0, 5 - len(D)))
    if not np.any(D):
        D = np.zeros(0)
    return CameraInfo(Header(stamp_ns(msg.header), frame_id), int(msg.width), int(msg.height), ours, K, D)


def transform_of(tr: Any) -> np.ndarray:
    """4x4 of a geometry_msgs/Transform or Pose (translation/position + rotation/orientation)."""
    t = _field(tr, "translation", "position")
    q = _field(tr, "rotation", "orientation")
    quat = np.array([q.x, q.y, q.z, q.w], dtype=np.float64)
    n = np.linalg.norm(quat)
    if not np.isfinite(n) or n < 1e-9:
        raise RosConvertError(f"invalid quaternion {quat.tolist()}")
    return transform_from(matrix_from_quat(quat / n), np.array([t.x, t.y, t.z], dtype=np.float64))


def pose_from_ros(msg: Any, topic: str, world: str, child: str) -> PoseStamped:
    """geometry_msgs/PoseStamped or nav_msgs/Odometry -> PoseStamped world_from_child."""
    pose = msg.pose.pose if hasattr(msg.pose, "pose") else msg.pose
    try:
        T = transform_of(pose)
    except RosConvertError as exc:
        raise RosConvertError(f"{topic}: {exc}") from None
    return PoseStamped(Header(stamp_ns(msg.header), world), child, T)


def _vec(v: Any) -> np.ndarray:
    return np.array([v.x, v.y, v.z], dtype=np.float64)


def imu_from_ros(msg: Any, topic: str, frame_id: str) -> Imu:
    """sensor_msgs/Imu -> Imu, every field kept as recorded (covariances row-major, -1 = not measured)."""
    q = msg.orientation
    try:
        return Imu(Header(stamp_ns(msg.header), frame_id), np.array([q.x, q.y, q.z, q.w], dtype=np.float64),
                   np.asarray(msg.orientation_covariance, dtype=np.float64).reshape(9), _vec(msg.angular_velocity),
                   np.asarray(msg.angular_velocity_covariance, dtype=np.float64).reshape(9),
                   _vec(msg.linear_acceleration),
                   np.asarray(msg.linear_acceleration_covariance, dtype=np.float64).reshape(9))
    except (ValueError, BagError) as exc:
        raise RosConvertError(f"{topic}: cannot convert sensor_msgs/Imu ({exc})") from None


def quat_xyzw(T: np.ndarray) -> np.ndarray:
    """[x, y, z, w] of the rotation of a 4x4."""
    return quat_from_matrix(T[:3, :3])


def register_depth(depth: DepthImage, depth_info: CameraInfo, colour_info: CameraInfo,
                   colour_from_depth: np.ndarray) -> DepthImage:
    """Depth re-projected into the colour camera (nearest surface wins), in colour's size and frame.

    Pinhole models without distortion on both sides (realsense depth streams have none; colour
    distortion, a few pixels at the edges of realsense colour, is not applied)."""
    z = depth.metres()
    v, u = np.nonzero(z > 0)
    zz = z[v, u].astype(np.float64)
    Kd, Kc = depth_info.K, colour_info.K
    pts = np.stack([(u - Kd[0, 2]) / Kd[0, 0] * zz, (v - Kd[1, 2]) / Kd[1, 1] * zz, zz])
    pc = colour_from_depth[:3, :3] @ pts + colour_from_depth[:3, 3:4]
    zc = pc[2]
    ok = zc > 1e-6
    uc = np.round(Kc[0, 0] * pc[0, ok] / zc[ok] + Kc[0, 2]).astype(np.int64)
    vc = np.round(Kc[1, 1] * pc[1, ok] / zc[ok] + Kc[1, 2]).astype(np.int64)
    zc = zc[ok]
    w, h = colour_info.width, colour_info.height
    inside = (uc >= 0) & (uc < w) & (vc >= 0) & (vc < h)
    uc, vc, zc = uc[inside], vc[inside], zc[inside]
    order = np.argsort(-zc)   # far first: nearer points overwrite them
    out = np.zeros((h, w), np.float64)
    out[vc[order], uc[order]] = zc[order]
    header = Header(depth.header.stamp_ns, colour_info.header.frame_id)
    if depth.data.dtype == np.uint16:
        mm = np.clip(np.round(out * depth.depth_scale), 0, 65535).astype(np.uint16)
        return DepthImage(header, mm, depth.depth_scale)
    return DepthImage(header, out.astype(np.float32), 1.0)
