"""Which ROS topics become which probeless topics: presets for realsense-ros, usb_cam and TUM RGB-D
bags, the RealSense Viewer's own ``.bag`` layout, and ``--map ROS_TOPIC=TOPIC`` overrides.

Probeless topics are the rig outputs of ``launch/sources/recording.yaml`` (``rig/rgb``, ...), so an
imported file replays with ``source:=recording``. Roles starting with ``@`` are used during the
conversion and not written: raw depth (registered to colour), its camera_info, tf and the Viewer's
extrinsics.
"""

from __future__ import annotations

from typing import Iterable

from probeless.errors import BagError

RGB, DEPTH, RGB_INFO = "rig/rgb", "rig/depth", "rig/rgbd/camera_info"
FISHEYE, FISHEYE_INFO = "rig/fisheye", "rig/fisheye/camera_info"
EXTRINSICS, GT_POSE, POSE = "rig/fisheye_from_rgbd", "rig/gt/rgbd_pose", "rig/pose"
IMU, GYRO, ACCEL = "rig/imu", "rig/imu/gyro", "rig/imu/accel"   # kept as recorded; no node consumes them
DEPTH_RAW, DEPTH_INFO, TF, TF_STATIC, VIEWER_TF = "@depth_raw", "@depth_info", "@tf", "@tf_static", "@viewer_tf"
IGNORE = "@ignore"
RIG_FRAME, FISHEYE_FRAME, WORLD_FRAME = "rgbd", "fisheye", "world"

# the frame each probeless topic's header names
FRAME_OF = {RGB: RIG_FRAME, DEPTH: RIG_FRAME, RGB_INFO: RIG_FRAME, FISHEYE: FISHEYE_FRAME,
            FISHEYE_INFO: FISHEYE_FRAME}


def _fisheye(ns: str) -> dict[str, str]:
    return {f"{ns}/image_raw": FISHEYE, f"{ns}/image_raw/compressed": FISHEYE, f"{ns}/camera_info": FISHEYE_INFO}


def _realsense(ns: str) -> dict[str, str]:
    return {f"{ns}/color/image_raw": RGB, f"{ns}/color/image_raw/compressed": RGB,
            f"{ns}/color/camera_info": RGB_INFO,
            f"{ns}/aligned_depth_to_color/image_raw": DEPTH,
            f"{ns}/aligned_depth_to_color/image_raw/compressedDepth": DEPTH,
            f"{ns}/aligned_depth_to_color/camera_info": IGNORE,
            f"{ns}/depth/image_rect_raw": DEPTH_RAW, f"{ns}/depth/image_rect_raw/compressedDepth": DEPTH_RAW,
            f"{ns}/depth/camera_info": DEPTH_INFO,
            f"{ns}/imu": IMU, f"{ns}/gyro/sample": GYRO, f"{ns}/accel/sample": ACCEL}


# RealSense Viewer recordings (ROS 1 bags written by librealsense): sensor_0 = stereo module (depth),
# sensor_1 = RGB camera; tf/0 = the stream's extrinsics to the reference (depth) stream
VIEWER = {"/device_0/sensor_1/Color_0/image/data": RGB, "/device_0/sensor_1/Color_0/info/camera_info": RGB_INFO,
          "/device_0/sensor_0/Depth_0/image/data": DEPTH_RAW,
          "/device_0/sensor_0/Depth_0/info/camera_info": DEPTH_INFO,
          "/device_0/sensor_1/Color_0/tf/0": VIEWER_TF,
          "/device_0/sensor_2/Gyro_0/imu/data": GYRO, "/device_0/sensor_2/Accel_0/imu/data": ACCEL}

PRESETS: dict[str, dict] = {
    "realsense": {"topics": {**_realsense("/camera"), **_realsense("/camera/camera"), **VIEWER,
                             **_fisheye("/fisheye"), **_fisheye("/usb_cam"),
                             "/tf": TF, "/tf_static": TF_STATIC},
                  "world": "map", "ground_truth": False},
    "usb_cam": {"topics": {**_fisheye(""), **_fisheye("/usb_cam"), **_fisheye("/fisheye"),
                           "/tf": TF, "/tf_static": TF_STATIC},
                "world": "map", "ground_truth": False},
    # TUM RGB-D ROS bags: registered depth in metres, ground truth as tf world -> kinect
    "tum": {"topics": {"/camera/rgb/image_color": RGB, "/camera/rgb/camera_info": RGB_INFO,
                       "/camera/depth/image": DEPTH, "/camera/depth_registered/image_raw": DEPTH,
                       "/camera/depth/camera_info": IGNORE, "/imu": IMU, "/tf": TF, "/tf_static": TF_STATIC},
            "world": "world", "ground_truth": True},
    # bags written by `probeless bag export --format ros2`: /TOPIC -> TOPIC, header frames kept
    "probeless": {"topics": {"/tf": IGNORE, "/tf_static": IGNORE}, "world": "world", "ground_truth": False,
                  "identity": True},
}
PRESET_NAMES = tuple(PRESETS)


def parse_maps(maps: Iterable[str]) -> dict[str, str]:
    """``--map ROS_TOPIC=TOPIC`` items -> {ros topic: probeless topic}; BagError for a malformed one."""
    out = {}
    for item in maps or ():
        ros, sep, ours = item.partition("=")
        if not sep or not ros or not ours:
            raise BagError(f"--map {item!r}: expected ROS_TOPIC=TOPIC, e.g. /cam/image_raw=rig/fisheye")
        out[ros] = ours
    return out


def topic_table(preset: str | None, maps: Iterable[str] = ()) -> dict[str, str]:
    """{ros topic: probeless topic or @role} of a preset (None = none) with the --map items on top."""
    if preset is not None and preset not in PRESETS:
        raise BagError(f"unknown preset {preset!r}, expected one of {', '.join(PRESET_NAMES)}")
    table = dict(PRESETS[preset]["topics"]) if preset else {"/tf": TF, "/tf_static": TF_STATIC}
    table.update(parse_maps(maps))
    return table


def normalise_frame(frame: str) -> str:
    """A tf frame name without the leading slash ROS 1 bags often have."""
    return frame.lstrip("/")
