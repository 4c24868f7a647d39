"""`probeless bag import`: ROS 1, rosbag2-sqlite3 and rosbag2-mcap bags written by rosbags from real frames
(7-Scenes RGB-D, the fisheye chessboards), raw and compressed, against the files they were written from."""

from __future__ import annotations

import shutil
import sys

import cv2
import numpy as np
import pytest

pytest.importorskip("rosbags")

from ros_bags import (  # noqa: E402
    COLOUR_FROM_DEPTH,
    COLOUR_FROM_FISHEYE,
    K_RGB,
    SEVEN,
    T0_NS,
    imu_sample,
    write_rig_bag,
)

from probeless.bag.reader import BagReader  # noqa: E402
from probeless.bag.ros_import import import_bag  # noqa: E402
from probeless.cli import main  # noqa: E402
from probeless.errors import BagError  # noqa: E402

GT_MAP = ["/ground_truth/pose=rig/gt/rgbd_pose"]


def _bag(tmp_path, kind, **kw):
    path = tmp_path / ("in.bag" if kind == "ros1" else "in")
    return path, write_rig_bag(path, kind, **kw)


def _read(path):
    out = {}
    with BagReader(path) as r:
        for m in r.messages():
            out.setdefault(m.topic, []).append((m.log_time_ns, r.decode(m)))
    return out


@pytest.mark.parametrize("compressed", [False, True], ids=["raw", "compressed"])
@pytest.mark.parametrize("kind", ["ros1", "sqlite3", "mcap"])
def test_import_realsense_bag_matches_the_source_frames(tmp_path, kind, compressed):
    src, wrote = _bag(tmp_path, kind, frames=2, fisheye=1, compressed=compressed)
    summary = import_bag(src, tmp_path / "out.mcap", preset="realsense", maps=GT_MAP)
    assert summary.skipped == {"/camera/status": "std_msgs/msg/String: named by no preset or --map"}
    got = _read(tmp_path / "out.mcap")
    seven, fish = wrote["seven"], wrote["fisheye"]
    for (_, imu), f in zip(got["rig/imu"], seven, strict=True):    # Imu kept as recorded, every field
        want = imu_sample(f["stamp"])
        assert imu.header.stamp_ns == f["stamp"] and imu.header.frame_id == "imu"
        for ours, key in (("orientation", "q"), ("orientation_covariance", "q_cov"), ("angular_velocity", "w"),
                          ("angular_velocity_covariance", "w_cov"), ("linear_acceleration", "a"),
                          ("linear_acceleration_covariance", "a_cov")):
            np.testing.assert_array_equal(getattr(imu, ours), want[key], err_msg=ours)
    assert [m.header.stamp_ns for _, m in got["rig/rgb"]] == [f["stamp"] for f in seven]   # header stamps kept
    for (_, rgb), (_, depth), (_, pose), f in zip(got["rig/rgb"], got["rig/depth"], got["rig/gt/rgbd_pose"], seven):
        assert rgb.encoding == "rgb8" and np.array_equal(rgb.data, f["rgb"])    # jpeg: cv2's decode of the file
        assert depth.depth_scale == 1000.0 and np.array_equal(depth.data, f["depth"])
        np.testing.assert_allclose(pose.target_from_source, f["pose"], atol=1e-9)
    (_, info), = got["rig/rgbd/camera_info"][:1]
    assert info.model == "pinhole" and np.array_equal(info.K, K_RGB) and info.header.frame_id == "rgbd"
    (_, fimg), = got["rig/fisheye"]
    assert np.array_equal(fimg.data, fish[0]["rgb"]) and fimg.header.stamp_ns == fish[0]["stamp"]
    (_, finfo), = got["rig/fisheye/camera_info"]
    assert finfo.model == "kannala_brandt" and np.allclose(finfo.D, [0.01, -0.002, 0, 0])
    (_, ext), = got["rig/fisheye_from_rgbd"]
    np.testing.assert_allclose(ext.target_from_source, np.linalg.inv(COLOUR_FROM_FISHEYE), atol=1e-9)
    # camera_info comes before the first image of its camera (the SLAM and undistort nodes wait for it)
    assert got["rig/rgbd/camera_info"][0][0] <= got["rig/rgb"][0][0]


def test_raw_depth_is_registered_to_colour(tmp_path):
    """Depth camera 1.5 cm to the side of colour (same K): a point at depth z moves fx * tx / z pixels."""
    src, wrote = _bag(tmp_path, "mcap", frames=1, fisheye=1, raw_depth=True)
    import_bag(src, tmp_path / "out.mcap", preset="realsense")
    (_, reg), = _read(tmp_path / "out.mcap")["rig/depth"]
    raw = wrote["seven"][0]["depth"]
    assert reg.data.shape == raw.shape and reg.header.frame_id == "rgbd"
    v, u = np.nonzero(reg.data)
    z = reg.data[v, u].astype(float)
    shift = K_RGB[0, 0] * COLOUR_FROM_DEPTH[0, 3] / (z / 1000.0)   # u_colour = u_depth + shift
    ud = np.round(u - shift).astype(int)
    ok = (ud >= 0) & (ud < raw.shape[1])
    near = np.abs(raw[v[ok], ud[ok]].astype(float) - z[ok]) <= 2
    assert near.mean() > 0.97, near.mean()
    assert len(z) > 0.8 * np.count_nonzero(raw)   # the registration keeps (almost) every measurement


@pytest.mark.parametrize("suffix", [".mcap", ".db3"])
def test_single_rosbag2_file_without_its_metadata(tmp_path, suffix):
    kind = "mcap" if suffix == ".mcap" else "sqlite3"
    src, _ = _bag(tmp_path, kind, frames=1, fisheye=1)
    (one,) = src.glob("*" + suffix)
    lone = tmp_path / ("lone" + suffix)
    shutil.copy(one, lone)
    summary = import_bag(lone, tmp_path / "out.mcap", preset="realsense")
    assert summary.written["rig/rgb"] == 1 and summary.written["rig/depth"] == 1


def test_cli_lists_skipped_topics_and_time_window(tmp_path, capsys):
    src, wrote = _bag(tmp_path, "sqlite3", frames=3, fisheye=1)
    out = tmp_path / "out.mcap"
    # --start skips the first frame (33 ms in), --duration keeps one frame period
    assert main(["bag", "import", str(src), "-o", str(out), "--preset", "realsense", "--start", "0.03",
                 "--duration", "0.033", "--no-progress"]) == 0
    text = capsys.readouterr().out
    assert "skipped /camera/status (std_msgs/msg/String: named by no preset or --map)" in text
    assert "skipped /ground_truth/pose" in text
    rgb = _read(out)["rig/rgb"]
    assert [m.header.stamp_ns for _, m in rgb] == [wrote["seven"][1]["stamp"]]
    assert main(["bag", "info", str(out)]) == 0 and "rig/rgb" in capsys.readouterr().out
    # an existing output is not overwritten
    assert main(["bag", "import", str(src), "-o", str(out), "--preset", "realsense"]) == 2
    assert "exists" in capsys.readouterr().err


def test_bad_input_gets_one_clear_line(tmp_path, capsys):
    garbage = tmp_path / "broken.bag"
    garbage.write_bytes(b"#ROSBAG V2.0\n" + bytes(range(256)) * 4)
    assert main(["bag", "import", str(garbage), "-o", str(tmp_path / "x.mcap")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and "broken.bag" in err and "\n" not in err
    assert not (tmp_path / "x.mcap").exists()
    # an encoding we cannot convert: names topic and encoding, leaves no output behind
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    msg = T["sensor_msgs/msg/Image"](header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](
        sec=1, nanosec=0), frame_id="c"), height=2, width=2, encoding="yuv422", is_bigendian=0, step=4,
        data=np.zeros(8, np.uint8))
    with Writer(tmp_path / "yuv", version=8, storage_plugin=StoragePlugin.MCAP) as w:
        c = w.add_connection("/camera/color/image_raw", msg.__msgtype__, typestore=ts)
        w.write(c, 1, ts.serialize_cdr(msg, msg.__msgtype__))
    assert main(["bag", "import", str(tmp_path / "yuv"), "-o", str(tmp_path / "y.mcap"), "--preset",
                 "realsense"]) == 2
    err = capsys.readouterr().err.strip()
    assert "/camera/color/image_raw" in err and "'yuv422'" in err and "\n" not in err
    assert not (tmp_path / "y.mcap").exists() and not (tmp_path / "y.mcap.partial").exists()
    with pytest.raises(BagError, match="unknown preset 'kinect'"):
        import_bag(tmp_path / "yuv", tmp_path / "z.mcap", preset="kinect")
    with pytest.raises(BagError, match="expected ROS_TOPIC=TOPIC"):
        import_bag(tmp_path / "yuv", tmp_path / "z.mcap", maps=["/a"])


def test_without_rosbags_the_command_says_what_to_install(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "rosbags.highlevel", None)   # import fails as if not installed
    assert main(["bag", "import", str(tmp_path), "-o", str(tmp_path / "x.mcap")]) == 2
    assert "pip install 'probeless[ros]'" in capsys.readouterr().err


def test_empty_bags_and_service_topics(tmp_path):
    """rosbag2's own test bags are not fetched here (no network): empty bags and a bag with a service event
    topic are built with rosbags instead, in both storages and as ROS 1."""
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    for plugin in (StoragePlugin.SQLITE3, StoragePlugin.MCAP):
        empty = tmp_path / f"empty_{plugin.name}"
        with Writer(empty, version=8, storage_plugin=plugin):
            pass
        with pytest.raises(BagError, match="holds no message"):
            import_bag(empty, tmp_path / "e.mcap", preset="realsense")
    with Writer1(tmp_path / "empty.bag"):
        pass
    with pytest.raises(BagError, match="holds no message"):
        import_bag(tmp_path / "empty.bag", tmp_path / "e.mcap", preset="realsense")
    assert not (tmp_path / "e.mcap").exists()

    ts = get_typestore(Stores.ROS2_HUMBLE)
    event = "example_interfaces/msg/AddTwoInts_Event"  # rosbags registers it under msg/
    ts.register(get_types_from_msg("service_msgs/ServiceEventInfo info\nint64[] request\nint64[] response", event))
    ts.register(get_types_from_msg("uint8 event_type\nbuiltin_interfaces/Time stamp\nchar[16] client_gid\n"
                                   "int64 sequence_number", "service_msgs/msg/ServiceEventInfo"))
    T = ts.types
    src = tmp_path / "svc"
    with Writer(src, version=8, storage_plugin=StoragePlugin.MCAP) as w:
        c = w.add_connection("/add_two_ints/_service_event", event, typestore=ts)
        info = T["service_msgs/msg/ServiceEventInfo"](event_type=0, stamp=T["builtin_interfaces/msg/Time"](
            sec=1, nanosec=0), client_gid=np.zeros(16, np.uint8), sequence_number=1)
        w.write(c, T0_NS, ts.serialize_cdr(T[event](info=info, request=np.array([1, 2]), response=np.array([3])),
                                           event))
        img = cv2.imread(str(SEVEN / "frame-000000.color.jpg"))
        m = T["sensor_msgs/msg/Image"](header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](
            sec=1, nanosec=0), frame_id="c"), height=480, width=640, encoding="bgr8", is_bigendian=0, step=1920,
            data=img.reshape(-1))
        c2 = w.add_connection("/usb_cam/image_raw", m.__msgtype__, typestore=ts)
        w.write(c2, T0_NS + 1, ts.serialize_cdr(m, m.__msgtype__))
    summary = import_bag(src, tmp_path / "s.mcap", preset="usb_cam")
    assert summary.skipped == {"/add_two_ints/_service_event": f"{event}: named by no preset or --map"}
    (_, fish), = _read(tmp_path / "s.mcap")["rig/fisheye"]
    assert fish.encoding == "bgr8" and np.array_equal(fish.data, img)


def test_tum_preset_ground_truth_from_tf(tmp_path):
    """A TUM-RGB-D-style ROS 1 bag: 32FC1 depth in metres, ground truth as /tf world -> kinect, and the
    kinect -> optical frame chain on /tf too; rig/gt/rgbd_pose = world_from_optical at each update."""
    from ros_bags import LINK_FROM_COLOUR, _Builder, seven_frames
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC)
    ts.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"))
    b, frames = _Builder(ts), seven_frames(2)
    with Writer(tmp_path / "tum.bag") as w:
        conns = {}

        def put(topic, msgtype, msg, t):
            if topic not in conns:
                conns[topic] = w.add_connection(topic, msgtype, typestore=ts)
            w.write(conns[topic], t, ts.serialize_ros1(msg, msgtype))
        for f in frames:
            t = f["stamp"]
            world_from_kinect = f["pose"] @ np.linalg.inv(LINK_FROM_COLOUR)
            put("/tf", "tf2_msgs/msg/TFMessage", b.tf(t, [("/world", "/kinect", world_from_kinect),
                                                          ("/kinect", "/openni_rgb_optical_frame", LINK_FROM_COLOUR)]),
                t)
            put("/camera/rgb/camera_info", "sensor_msgs/msg/CameraInfo",
                b.info(t, "/openni_rgb_optical_frame", 640, 480, K_RGB), t + 1)
            put("/camera/rgb/image_color", "sensor_msgs/msg/Image",
                b.image(t, "/openni_rgb_optical_frame", f["rgb"][:, :, ::-1], "bgr8"), t + 2)
            put("/camera/depth/image", "sensor_msgs/msg/Image",
                b.image(t, "/openni_rgb_optical_frame", f["depth"].astype(np.float32) / 1000, "32FC1"), t + 3)
    import_bag(tmp_path / "tum.bag", tmp_path / "out.mcap", preset="tum")
    got = _read(tmp_path / "out.mcap")
    assert len(got["rig/gt/rgbd_pose"]) == 2
    for (_, pose), (_, depth), f in zip(got["rig/gt/rgbd_pose"], got["rig/depth"], frames):
        assert pose.header.stamp_ns == f["stamp"]
        np.testing.assert_allclose(pose.target_from_source, f["pose"], atol=1e-9)
        assert depth.depth_scale == 1.0 and np.array_equal(depth.data, f["depth"].astype(np.float32) / 1000)
