"""`probeless bag export --format ros2`: our recording -> a rosbag2 MCAP (CDR) that rosbags reads back with the
right ROS types, and ours -> ROS 2 -> ours is bit-equal for images and within 1e-9 for poses."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("rosbags")

from ros_bags import seven_frames  # noqa: E402

from probeless import wire  # noqa: E402
from probeless.bag.reader import BagReader  # noqa: E402
from probeless.bag.ros_import import import_bag  # noqa: E402
from probeless.bag.writer import BagWriter  # noqa: E402
from probeless.cli import main  # noqa: E402
from probeless.messages import (  # noqa: E402
    CameraInfo,
    Cubemap,
    DepthImage,
    Header,
    Image,
    Imu,
    PointCloud,
    PoseStamped,
)


def _recording(path):
    """A small run: 7-Scenes colour/depth, augmented frames, calibration, poses, the SLAM model, a cubemap."""
    f = seven_frames(2)
    rng = np.random.default_rng(3)
    msgs = []
    for k, fr in enumerate(f):
        t = fr["stamp"]
        msgs += [("rig/rgb", Image(Header(t, "rgbd"), fr["rgb"], "rgb8")),
                 ("rig/depth", DepthImage(Header(t, "rgbd"), fr["depth"], 1000.0)),
                 ("slam/depth_m", DepthImage(Header(t, "rgbd"), fr["depth"].astype(np.float32) / 1000, 1.0)),
                 ("rig/ir", Image(Header(t, "rgbd"), (fr["depth"] * 7)[:, :, None], "mono16")),
                 ("compositor/image", Image(Header(t, "rgbd"), fr["rgb"][:, ::-1].copy(), "rgb8")),
                 ("slam/pose", PoseStamped(Header(t, "world"), "rgbd", fr["pose"])),
                 ("rig/imu", Imu(Header(t + 1000, "imu"), np.array([0.1, -0.2, 0.3, 0.927]), rng.uniform(0, 1, 9),
                                 rng.normal(size=3), rng.uniform(0, 1, 9), rng.normal(size=3), np.full(9, -1.0)))]
    t = f[0]["stamp"]
    K = np.array([[585.0, 0, 320], [0, 585, 240], [0, 0, 1]])
    msgs += [("rig/rgbd/camera_info", CameraInfo(Header(t, "rgbd"), 640, 480, "pinhole", K,
                                                 np.array([0.1, -0.2, 0.001, 0.002, 0.05]))),
             ("rig/fisheye/camera_info", CameraInfo(Header(t, "fisheye"), 1032, 778, "kannala_brandt", K,
                                                    np.array([0.01, -0.002, 0.0003, 0.0]))),
             ("rig/fisheye_from_rgbd", PoseStamped(Header(t, "fisheye"), "rgbd",
                                                   np.linalg.inv(f[1]["pose"]) @ f[0]["pose"])),
             ("slam/model/points", PointCloud(Header(t, "world"), rng.normal(size=(50, 3)).astype(np.float32),
                                              rng.integers(0, 256, (50, 3)).astype(np.uint8))),
             ("envmap/envmaps", Cubemap(Header(t, "world"), "sphere", np.zeros(3), np.zeros((6, 4, 4, 3), np.float16)))]
    with BagWriter(path) as w:
        for i, (topic, m) in enumerate(msgs):
            w.write_frames(wire.encode(topic, m, "test", m.header.stamp_ns, seq=i), log_time_ns=m.header.stamp_ns)
    return msgs


def test_export_types_and_round_trip(tmp_path, capsys):
    msgs = _recording(tmp_path / "run.mcap")
    out = tmp_path / "ros2"
    assert main(["bag", "export", str(tmp_path / "run.mcap"), "--format", "ros2", "-o", str(out),
                 "--no-progress"]) == 0
    text = capsys.readouterr().out
    assert "envmap/envmaps: 1 message(s) not exported: lighting/Cubemap has no ROS equivalent" in text

    from rosbags.highlevel import AnyReader
    with AnyReader([out]) as r:   # rosbags reads it back, with the ROS types
        types = {c.topic: c.msgtype for c in r.connections}
        assert r.connections[0].ext.serialization_format == "cdr"
        cloud = next(r.deserialize(raw, c.msgtype) for c, _, raw in r.messages()
                     if c.topic == "/slam/model/points")
    assert types == {"/rig/rgb": "sensor_msgs/msg/Image", "/rig/depth": "sensor_msgs/msg/Image",
                     "/slam/depth_m": "sensor_msgs/msg/Image", "/rig/ir": "sensor_msgs/msg/Image",
                     "/compositor/image": "sensor_msgs/msg/Image", "/slam/pose": "geometry_msgs/msg/PoseStamped",
                     "/tf": "tf2_msgs/msg/TFMessage", "/tf_static": "tf2_msgs/msg/TFMessage",
                     "/rig/rgbd/camera_info": "sensor_msgs/msg/CameraInfo",
                     "/rig/fisheye/camera_info": "sensor_msgs/msg/CameraInfo",
                     "/rig/fisheye_from_rgbd": "geometry_msgs/msg/PoseStamped",
                     "/slam/model/points": "sensor_msgs/msg/PointCloud2", "/rig/imu": "sensor_msgs/msg/Imu"}
    (mcap_file,) = out.glob("*.mcap")   # what ros2 bag play / Foxglove's ROS 2 decoder expect: profile ros2, cdr +
    with BagReader(mcap_file) as r:    # ros2msg schemas that carry their dependencies
        assert r.profile == "ros2"
        for info in r.topics().values():
            assert (info.message_encoding, info.schema_encoding) == ("cdr", "ros2msg")
        image, _ = next(r.records("/rig/rgb"))
        assert b"MSG: std_msgs/Header" in r.schema_of(image).data
    pts = np.frombuffer(cloud.data.tobytes(), dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("rgb", "<u4")])
    src_cloud = next(m for t, m in msgs if t == "slam/model/points")
    assert np.array_equal(np.stack([pts["x"], pts["y"], pts["z"]], 1), src_cloud.points)
    assert np.array_equal(pts["rgb"] >> 16, src_cloud.colors[:, 0])

    import_bag(out, tmp_path / "back.mcap", preset="probeless")
    back = {}
    with BagReader(tmp_path / "back.mcap") as r:
        for m in r.messages():
            back.setdefault(m.topic, []).append(r.decode(m))
    want = {}
    for topic, m in msgs:
        want.setdefault(topic, []).append(m)
    assert set(back) == set(want) - {"envmap/envmaps", "slam/model/points"}
    for topic, got in back.items():
        for a, b in zip(got, want[topic], strict=True):
            assert a.header.stamp_ns == b.header.stamp_ns and a.header.frame_id == b.header.frame_id
            if isinstance(b, (Image, DepthImage)):
                assert type(a) is type(b) and a.data.dtype == b.data.dtype and np.array_equal(a.data, b.data)
                assert getattr(a, "encoding", None) == getattr(b, "encoding", None)
            elif isinstance(b, PoseStamped):
                assert np.max(np.abs(a.target_from_source - b.target_from_source)) < 1e-9
            elif isinstance(b, Imu):   # float64 in CDR: every field bit-equal
                for name in ("orientation", "orientation_covariance", "angular_velocity",
                             "angular_velocity_covariance", "linear_acceleration", "linear_acceleration_covariance"):
                    assert np.array_equal(getattr(a, name), getattr(b, name)), name
            else:
                assert (a.model, a.width, a.height) == (b.model, b.width, b.height)
                assert np.array_equal(a.K, b.K) and np.array_equal(a.D, b.D)
