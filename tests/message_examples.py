"""One valid, deterministic example instance per registered message type, for tests.

``EXAMPLES`` maps type name -> zero-argument factory; :func:`examples` builds them all. Every
registered type must have an entry (tests/test_messages.py checks), so new types cannot be
forgotten. Arrays with more than one element are used wherever a field has any, so layout and
dtype tests have something to bite on.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from probeless.geom.rotation import matrix_from_quat
from probeless.messages import (
    BrightnessDelta,
    CameraInfo,
    Clock,
    Cubemap,
    CubemapLevel,
    DepthImage,
    Floorplan,
    HdrPointCloud,
    Header,
    Image,
    Imu,
    InputCounters,
    Message,
    NodeStatus,
    PointCloud,
    PoseStamped,
    SHCoefficients,
    StageTiming,
    Tick,
    TriangleMesh,
)
from probeless.messages.diagnostics import TrackingState


def _rng() -> np.random.Generator:
    return np.random.default_rng(1234)


def header(frame_id: str = "world", stamp_ns: int = 1_700_000_000_000_000_000, seq: int = 7) -> Header:
    return Header(stamp_ns=stamp_ns, frame_id=frame_id, seq=seq)


def image() -> Image:
    return Image(header("rgbd"), _rng().integers(0, 256, (4, 6, 3), dtype=np.uint8), "rgb8")


def depth_image() -> DepthImage:
    return DepthImage(header("rgbd"), _rng().integers(0, 5000, (4, 6), dtype=np.uint16), 1000.0)


def camera_info() -> CameraInfo:
    K = np.array([[500.0, 0.0, 320.0], [0.0, 500.0, 240.0], [0.0, 0.0, 1.0]])
    return CameraInfo(header("fisheye"), 640, 480, "omnidir", K, D=np.array([-0.1, 0.01, 0.001, -0.002]), xi=0.9)


def imu() -> Imu:
    rng = _rng()
    q = rng.normal(size=4)
    return Imu(header("imu"), q / np.linalg.norm(q), np.diag([1e-3, 2e-3, 3e-3]).ravel(), rng.normal(size=3),
               np.full(9, 1e-4), rng.normal(size=3) + [0.0, 0.0, 9.81], np.zeros(9))


def pose_stamped() -> PoseStamped:
    R = matrix_from_quat(np.array([0.1, -0.2, 0.3, 0.9]))
    return PoseStamped.from_rt(header("world"), "rgbd", R, np.array([1.0, 2.0, 1.5]))


def floorplan() -> Floorplan:
    return Floorplan(header("world"), np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 3.0], [0.0, 3.0]]), 2.6)


def point_cloud() -> PointCloud:
    rng = _rng()
    return PointCloud(header("rgbd"), rng.random((5, 3), dtype=np.float32),
                      rng.integers(0, 256, (5, 3), dtype=np.uint8),
                      normals=np.tile(np.array([0, 0, 1], np.float32), (5, 1)))


def hdr_point_cloud() -> HdrPointCloud:
    rng = _rng()
    return HdrPointCloud(header("world"), rng.random((5, 3), dtype=np.float32),
                         np.array([[0.1, 0.2, 0.3], [1.0, 1.0, 1.0], [12.5, 9.0, 4.0], [0, 0, 0], [300, 250, 200]],
                                  np.float32),
                         normals=np.tile(np.array([0, 0, 1], np.float32), (5, 1)),
                         ldr_colors=np.array([[0.1, 0.2, 0.3], [1, 1, 1], [1, 1, 1], [0, 0, 0], [1, 1, 1]],
                                             np.float32))


def triangle_mesh() -> TriangleMesh:
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
    return TriangleMesh(header("world"), v, np.array([[0, 1, 2], [0, 2, 3]], np.int32),
                        vertex_colors=np.full((4, 3), 0.5, np.float32),
                        vertex_normals=np.tile(np.array([0, 0, 1], np.float32), (4, 1)),
                        uvs=v[:, :2].copy())


def cubemap() -> Cubemap:
    rng = _rng()
    mips = (CubemapLevel(0.5, rng.random((6, 2, 2, 3)).astype(np.float16)),
            CubemapLevel(1.0, rng.random((6, 1, 1, 3)).astype(np.float16)))
    return Cubemap(header("world"), "teapot", np.array([0.5, 1.0, 0.8]),
                   rng.random((6, 4, 4, 3)).astype(np.float16), mips=mips, linear=True)


def sh_coefficients() -> SHCoefficients:
    return SHCoefficients(header("world"), "teapot", 3, _rng().standard_normal((9, 3)).astype(np.float32))


def brightness_delta() -> BrightnessDelta:
    return BrightnessDelta(header("fisheye"), np.array([0.01, -0.02, 0.005], np.float32), 1234, True)


def tick() -> Tick:
    return Tick(header(""), period_ns=33_333_333, missed=1)


def clock() -> Clock:
    return Clock(header(""), rate=2.0, epoch=1)


def node_status() -> NodeStatus:
    timing = StageTiming("on_input:rgb", 30, 9000, 1.5, 1.2, 4.0, 6.5)
    counters = InputCounters("rgb", "camera/rgb", "latest", 1, 0, 9000, 12, 3, 0)
    return NodeStatus(header(""), "relight", "running", 300.0, (timing,), (counters,), ("probe=9000",))


def tracking_state() -> TrackingState:
    return TrackingState(header("rgbd"), "lost", "fitness 0.12 < 0.3", frames_tracked=420, frames_lost=3,
                         frames_invalid=1, frames_skipped=2, frames_dropped=57, consecutive_failures=2,
                         last_good_stamp_ns=1_699_999_999_933_333_333, fitness=0.12, step_ms=48.5)


EXAMPLES: dict[str, Callable[[], Message]] = {
    "core/Tick": tick,
    "core/Clock": clock,
    "diagnostics/NodeStatus": node_status,
    "diagnostics/TrackingState": tracking_state,
    "sensor/Image": image,
    "sensor/DepthImage": depth_image,
    "sensor/CameraInfo": camera_info,
    "sensor/Imu": imu,
    "geometry/PoseStamped": pose_stamped,
    "geometry/Floorplan": floorplan,
    "mesh/PointCloud": point_cloud,
    "mesh/HdrPointCloud": hdr_point_cloud,
    "mesh/TriangleMesh": triangle_mesh,
    "lighting/Cubemap": cubemap,
    "lighting/SHCoefficients": sh_coefficients,
    "lighting/BrightnessDelta": brightness_delta,
}


def examples() -> dict[str, Message]:
    """One valid instance per registered type name."""
    return {name: factory() for name, factory in EXAMPLES.items()}
