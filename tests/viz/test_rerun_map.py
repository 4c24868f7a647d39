"""probeless messages -> Rerun archetypes (probeless/viz/rerun_map.py, rerun_logger.py), checked on the archetypes'
own Arrow data: entity paths and archetype per message type, cameras under their poses, the fisheye frustum
against the camera model, the mesh texture against OpenGL's uv convention, ground truth vs estimate."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import rerun as rr
import rerun.blueprint as rrb
from message_examples import EXAMPLES, header

from probeless.cameras import model_from_info
from probeless.color import to_srgb8
from probeless.geom.rotation import matrix_from_quat
from probeless.messages.diagnostics import NodeStatus, StageTiming
from probeless.messages.geometry import Floorplan, PoseStamped
from probeless.messages.lighting import BrightnessDelta, Cubemap
from probeless.messages.mesh import TriangleMesh
from probeless.messages.sensor import CameraInfo, DepthImage, Image
from probeless.viz import rerun_map as m
from probeless.viz.blueprint import default_blueprint
from probeless.viz.rerun_logger import RerunLogger


class FakeStream:
    """Records what a RecordingStream would be given."""

    def __init__(self):
        self.logs: list[tuple[str, object, bool, int]] = []
        self.now = None

    def set_time(self, timeline, *, timestamp):
        assert timeline == "stamp"
        self.now = int(timestamp.astype("datetime64[ns]").astype(np.int64))

    def log(self, path, archetype, static=False):
        self.logs.append((path, archetype, static, self.now))

    def at(self, path: str, kind: type | None = None) -> list:
        return [a for p, a, _, _ in self.logs if p == path and (kind is None or isinstance(a, kind))]


def values(batch) -> np.ndarray:
    arr = batch.as_arrow_array()
    while hasattr(arr, "flatten"):
        arr = arr.flatten()
    return arr.to_numpy(zero_copy_only=False)


def mat3(batch) -> np.ndarray:
    return values(batch).reshape(3, 3).T  # Rerun stores matrices column-major


def pose(topic_frame: str, child: str, T: np.ndarray, stamp: int = 1) -> PoseStamped:
    return PoseStamped(header(topic_frame, stamp), child, T)


def rigid(q, t) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = matrix_from_quat(np.asarray(q, float) / np.linalg.norm(q)), t
    return T


def pinhole_info(w=64, h=48) -> CameraInfo:
    return CameraInfo(header("rgbd"), w, h, "pinhole", np.array([[50.0, 0, 31.5], [0, 55.0, 23.5], [0, 0, 1]]))


EXPECTED = {  # message type -> [(entity path, archetype)] on topic "a/b"
    "diagnostics/NodeStatus": [("/timings/relight/on_input\\:rgb", rr.Scalars), ("/memory/relight", rr.Scalars)],
    "diagnostics/TrackingState": [("/a/b", rr.TextLog)],
    "sensor/Image": [("/a/b", rr.Image)],
    "sensor/DepthImage": [("/a/b", rr.DepthImage)],
    "sensor/CameraInfo": [("/world/camera/fisheye/frustum", rr.LineStrips3D)],
    "geometry/PoseStamped": [("/world/a/b", rr.Transform3D), ("/world/a/b", rr.TransformAxes3D),
                             ("/world/camera/rgbd", rr.Transform3D)],
    "geometry/Floorplan": [("/world/a/b", rr.LineStrips3D)],
    "mesh/PointCloud": [("/world/a/b", rr.Points3D)],
    "mesh/HdrPointCloud": [("/world/a/b", rr.Points3D)],
    "mesh/TriangleMesh": [("/world/a/b", rr.Mesh3D)],
    "lighting/Cubemap": [("/a/b/teapot", rr.Image), ("/world/objects/teapot", rr.Points3D)],
    "lighting/SHCoefficients": [("/a/b/teapot", rr.Tensor), ("/a/b/teapot", rr.Scalars),
                                ("/a/b/teapot", rr.SeriesLines)],
    "lighting/BrightnessDelta": [("/a/b", rr.Scalars), ("/a/b", rr.SeriesLines)],
}


@pytest.mark.parametrize("type_name", sorted(EXPECTED))
def test_archetype_and_path_per_message_type(type_name):
    s = FakeStream()
    logger = RerunLogger(s)
    msg = EXAMPLES[type_name]()
    assert logger.log("a/b", msg)
    got = [(p, type(a)) for p, a, static, _ in s.logs if p != "/world"]
    assert got == EXPECTED[type_name]
    assert all(t == msg.header.stamp_ns for p, _, static, t in s.logs if not static)
    assert logger.logged == {"a/b": 1} and not logger.skipped


def test_world_is_z_up_and_unmapped_types_are_counted():
    s = FakeStream()
    logger = RerunLogger(s)
    assert s.logs[0][:3] == ("/world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, True)
    for _ in range(3):
        assert not logger.log("timer/tick", EXAMPLES["core/Tick"]())
    assert not logger.log("rig/delta", replace(EXAMPLES["lighting/BrightnessDelta"](), sampled=False))
    assert logger.skipped == {"timer/tick": 3, "rig/delta": 1} and not logger.logged
    assert "core/Tick has no Rerun mapping" in logger.summary_line() and len(s.logs) == 1


def test_pinhole_camera_under_its_pose():
    s = FakeStream()
    logger = RerunLogger(s)
    T = rigid([0.3, -0.1, 0.2, 0.9], [1.0, 2.0, 1.2])
    logger.log("rig/rgbd/camera_info", pinhole_info())
    logger.log("slam/pose", pose("world", "rgbd", T))
    rgb = Image(header("rgbd"), np.zeros((48, 64, 3), np.uint8), "rgb8")
    logger.log("rig/rgb", rgb)
    logger.log("rig/depth", DepthImage(header("rgbd"), np.full((48, 64), 1500, np.uint16), 1000.0))
    logger.log("compositor/image", rgb)        # another node's image of the same frame: a 2D view of its own
    logger.log("rig/small", Image(header("rgbd"), np.zeros((24, 32, 3), np.uint8), "rgb8"))  # not the camera's size
    (ph,) = s.at("/world/camera/rgbd/image", rr.Pinhole)
    assert np.allclose(mat3(ph.image_from_camera), pinhole_info().K)
    assert values(ph.resolution).tolist() == [64, 48]
    assert ph.camera_xyz.as_arrow_array() == rr.ViewCoordinates.RDF.as_arrow_array()  # optical: z forward
    (tf,) = s.at("/world/camera/rgbd", rr.Transform3D)
    R, t = mat3(tf.mat3x3), values(tf.translation)
    assert np.allclose(R, T[:3, :3]) and np.allclose(t, T[:3, 3])
    # the principal ray (camera +z, the frustum's axis) points along the pose's third column in the world
    ray = np.linalg.solve(pinhole_info().K, [31.5, 23.5, 1.0])
    assert np.allclose(R @ ray, T[:3, 2])
    assert s.at("/world/camera/rgbd/image/rig/rgb", rr.Image)
    (d,) = s.at("/world/camera/rgbd/image/rig/depth", rr.DepthImage)
    assert values(d.meter).tolist() == [1000.0]
    assert s.at("/compositor/image", rr.Image) and s.at("/rig/small", rr.Image)


def test_image_without_camera_info_is_2d_and_float_goes_through_srgb():
    s = FakeStream()
    logger = RerunLogger(s)
    lin = np.tile(np.array([0.0, 0.5, 1.0], np.float32), (2, 3, 1))
    logger.log("undistort/image", Image(header("fisheye"), lin, "rgbf32"))
    (img,) = s.at("/undistort/image", rr.Image)
    assert values(img.buffer).tolist() == to_srgb8(lin).ravel().tolist() == [0, 188, 255] * 6


@pytest.mark.parametrize("model", ["omnidir", "kannala_brandt"])
def test_fisheye_frustum_rays_pass_through_the_border(model):
    K = np.array([[180.0, 0, 159.5], [0, 180.0, 119.5], [0, 0, 1]])
    extra = {"xi": 0.9, "D": np.array([-0.05, 0.01, 0.0, 0.0])} if model == "omnidir" else {
        "D": np.array([0.02, -0.01, 0.003, -0.001])}
    info = CameraInfo(header("fisheye"), 320, 240, model, K, **extra)
    s = FakeStream()
    RerunLogger(s).log("rig/fisheye/camera_info", info)
    (strips,) = s.at("/world/camera/fisheye/frustum", rr.LineStrips3D)
    pts = [np.asarray(p).reshape(-1, 3) for p in strips.strips.as_arrow_array().to_pylist()]
    loop, rays = pts[0], pts[1:]
    assert len(loop) == 4 * 16 + 1 and np.allclose(loop[0], loop[-1])    # the whole border, closed
    assert len(rays) == 16 and all(np.allclose(r[0], 0) for r in rays)
    ends = np.vstack([loop, [r[1] for r in rays]])
    assert np.allclose(np.linalg.norm(ends, axis=1), m.FRUSTUM_DEPTH, atol=1e-5)
    px, ok = model_from_info(info).project(ends)
    assert ok.all()
    on_edge = np.minimum.reduce([np.abs(px[:, 0] + 0.5), np.abs(px[:, 0] - 319.5),
                                 np.abs(px[:, 1] + 0.5), np.abs(px[:, 1] - 239.5)])
    assert on_edge.max() < 1e-3
    assert np.allclose(px[:-1][: 4 * 16], m.border_pixels(320, 240), atol=1e-3)


def test_textured_mesh_texcoords_hit_the_opengl_texel():
    W, H, r, c = 8, 4, 1, 6
    atlas = np.zeros((H, W, 4), np.uint8)
    atlas[r, c] = (10, 200, 30, 255)
    # OpenGL: v up, texel row r (from the top of the image) spans v in [1 - (r+1)/H, 1 - r/H]
    uv = np.array([(c + 0.5) / W, 1.0 - (r + 0.5) / H], np.float32)
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
    mesh = TriangleMesh(header("world", 100), v, np.array([[0, 1, 2]], np.int32), uvs=np.tile(uv, (3, 1)))
    s = FakeStream()
    logger = RerunLogger(s, texture_period_s=1.0)
    logger.log("texturer/mesh", mesh)                       # no atlas yet: untextured
    for stamp in (200, 600_000_000, 1_300_000_000):
        logger.log("texturer/atlas", Image(header("world", stamp), atlas, "rgba8"))
    meshes = [(a, t) for p, a, _, t in s.logs if p == "/world/texturer/mesh"]
    assert [t for _, t in meshes] == [100, 200, 1_300_000_000]   # re-textured at most once per second of stamps
    assert meshes[0][0].albedo_texture_buffer is None
    last = meshes[-1][0]
    tex = values(last.albedo_texture_buffer).reshape(H, W, 4)
    uv_rerun = values(last.vertex_texcoords).reshape(-1, 2)[0]    # Rerun: origin top-left, v down
    col, row = int(uv_rerun[0] * W), int(uv_rerun[1] * H)
    assert (row, col) == (r, c) and tex[row, col].tolist() == [10, 200, 30, 255]


def test_explicit_mesh_atlas_pair():
    s = FakeStream()
    logger = RerunLogger(s, pairs={"room/prism": "paint/texture"})
    logger.log("paint/texture", Image(header("world"), np.zeros((2, 2, 3), np.uint8), "rgb8"))
    logger.log("room/prism", EXAMPLES["mesh/TriangleMesh"]())
    (mesh,) = s.at("/world/room/prism", rr.Mesh3D)
    assert mesh.albedo_texture_buffer is not None


def test_estimate_wins_over_ground_truth():
    s = FakeStream()
    logger = RerunLogger(s)
    gt1, est, gt2 = (rigid([0, 0, 0, 1], [k, 0, 0]) for k in (1.0, 2.0, 3.0))
    logger.log("rig/gt/rgbd_pose", pose("world", "rgbd", gt1, 10))
    logger.log("slam/pose", pose("world", "rgbd", est, 20))
    logger.log("rig/gt/rgbd_pose", pose("world", "rgbd", gt2, 30))
    logger.log("rig/fisheye_from_rgbd", pose("fisheye", "rgbd", gt1, 30))
    cam = [(values(a.translation)[0], t) for p, a, _, t in s.logs if p == "/world/camera/rgbd"]
    assert cam == [(1.0, 10), (2.0, 20)]           # ground truth only until the first estimate
    assert len(s.at("/world/rig/gt/rgbd_pose", rr.Transform3D)) == 2
    (extr,) = s.at("/rig/fisheye_from_rgbd")
    assert isinstance(extr, rr.AnyValues) and not s.at("/world/camera/fisheye")


def test_cubemap_net_linear_is_tone_mapped():
    faces = np.ones((6, 4, 4, 3), np.float32)    # radiance 1 -> Reinhard 0.5 -> sRGB code 188
    msg = Cubemap(header("world"), "ball", np.array([1.0, 2.0, 0.5]), faces, linear=True)
    s = FakeStream()
    RerunLogger(s).log("envmap/envmaps", msg)
    (net,) = s.at("/envmap/envmaps/ball", rr.Image)
    px = values(net.buffer).reshape(12, 16, 3)
    assert px[4:8, 0:4].min() == px[4:8, 0:4].max() == 188 and px[0:4, 0:4].max() == 0   # a face; an empty tile
    (pos,) = s.at("/world/objects/ball", rr.Points3D)
    assert values(pos.positions).tolist() == [1.0, 2.0, 0.5]
    ldr = replace(msg, faces=np.full((6, 4, 4, 3), 77, np.uint8), linear=False)
    assert set(m.cubemap_net(ldr)[4:8].ravel().tolist()) == {77}


def test_node_status_timings_and_memory():
    st = NodeStatus(header(""), "slam", "running", 3.0, (StageTiming("track", 3, 9, 12.5, 12, 14, 15),
                                                        StageTiming("on_input:rig/rgb", 3, 9, 2.0, 2, 2, 2)),
                    rss_bytes=3 * 2**20)
    s = FakeStream()
    RerunLogger(s).log("slam/diagnostics", st)
    assert values(s.at("/timings/slam/track")[0].scalars).tolist() == [12.5]
    assert s.at(f"/timings/slam/{rr.escape_entity_path_part('on_input:rig/rgb')}")
    assert values(s.at("/memory/slam")[0].scalars).tolist() == [3.0]


def test_diagnostics_on_the_host_clock_sit_beside_scene_time_data():
    """Scene stamps start at 0, NodeStatus carries the host clock: timings go to the latest data stamp."""
    wall = 1_780_000_000 * 10**9                      # 2026, as the diagnostics' header has it
    s = FakeStream()
    log = RerunLogger(s)
    status = NodeStatus(header("", wall), "slam", "running", 3.0, (StageTiming("track", 3, 9, 12.5, 12, 14, 15),))
    log.log("slam/diagnostics", status)               # no data yet: its own stamp
    assert s.logs[-1][3] == wall
    log.log("rig/rgb", Image(header("rgbd", 2_500_000_000), np.zeros((2, 2, 3), np.uint8), "rgb8"))
    log.log("slam/diagnostics", status)
    assert [t for p, _, _, t in s.logs if p == "/timings/slam/track"] == [wall, 2_500_000_000]
    near = NodeStatus(header("", 2_600_000_000), "slam", "running", 3.0)  # same clock (stamps:=wall): kept
    log.log("slam/diagnostics", near)
    assert s.logs[-1][3] == 2_600_000_000


def test_the_first_floorplan_aims_the_3d_view_at_the_room():
    sent = []
    s = FakeStream()
    s.send_blueprint = sent.append
    log = RerunLogger(s, blueprint=lambda eye: eye)
    verts = np.array([[0.0, 0], [6, 0], [6, 3], [3, 3], [3, 5], [0, 5]])
    for _ in range(2):
        log.log("rig/floorplan", Floorplan(header("world"), verts, 2.5))
    assert len(sent) == 1                              # once
    eye = sent[0]
    target = values(eye.look_target)
    position = values(eye.position)
    assert target.tolist() == pytest.approx([3.0, 2.5, 0.75])      # the middle of the room's bounding box
    assert position[2] > 2.5 and position[1] < 0.0                  # above the ceiling, in front of the room


@pytest.mark.parametrize("encoding", ["rgb8", "bgr8", "mono8"])
def test_jpeg_images_decode_to_the_frame(encoding):
    """jpeg_quality > 0: 8-bit colour and grey frames go out as JPEG; OpenCV decodes the blob to the frame."""
    import cv2

    yy, xx = np.mgrid[0:48, 0:64]
    rgb = np.stack([xx * 4, yy * 5, (xx + yy) * 2], axis=2).astype(np.uint8)   # smooth: JPEG keeps it close
    data = {"rgb8": rgb, "bgr8": rgb[..., ::-1], "mono8": rgb[..., :1]}[encoding]
    s = FakeStream()
    RerunLogger(s, jpeg_quality=90).log("cam/image", Image(header("cam"), np.ascontiguousarray(data), encoding))
    (encoded,) = s.at("/cam/image", rr.EncodedImage)
    blob = values(encoded.blob).astype(np.uint8)
    decoded = cv2.imdecode(blob, cv2.IMREAD_UNCHANGED)
    want = rgb[..., 0] if encoding == "mono8" else rgb[..., ::-1]             # OpenCV decodes to BGR
    assert decoded.shape == want.shape and np.abs(decoded.astype(int) - want).mean() < 2.0
    rgba = Image(header("cam"), np.zeros((4, 4, 4), np.uint8), "rgba8")     # alpha: JPEG has none, kept raw
    RerunLogger(s, jpeg_quality=90).log("cam/rgba", rgba)
    assert s.at("/cam/rgba", rr.Image) and not s.at("/cam/rgba", rr.EncodedImage)


def test_brightness_delta_series():
    s = FakeStream()
    logger = RerunLogger(s)
    for k in range(3):
        logger.log("brightness/delta", BrightnessDelta(header("fisheye", k), np.array([k, -k, 0.5], np.float32),
                                                       10, True))
    sc = s.at("/brightness/delta", rr.Scalars)
    assert [values(a.scalars).tolist() for a in sc] == [[0, 0, 0.5], [1, -1, 0.5], [2, -2, 0.5]]
    assert len(s.at("/brightness/delta", rr.SeriesLines)) == 1         # static names, once


def _views(node) -> list:
    if isinstance(node, rrb.View):
        return [node]
    return [v for c in node.contents for v in _views(c)]


def test_default_blueprint_views_name_entities_the_logger_writes():
    views = {type(v).__name__ + " " + str(v.origin) for v in _views(default_blueprint().root_container)}
    assert {"Spatial3DView /world", "Spatial2DView /world/camera/rgbd/image", "Spatial2DView /envmap/envmaps",
            "Spatial2DView /texturer/atlas", "Spatial2DView /undistort/image", "TimeSeriesView /timings"} <= views
    s = FakeStream()
    logger = RerunLogger(s)
    logger.log("rig/rgbd/camera_info", replace(pinhole_info(), header=header("rgbd")))
    logger.log("envmap/envmaps", EXAMPLES["lighting/Cubemap"]())
    logger.log("slam/diagnostics", EXAMPLES["diagnostics/NodeStatus"]())
    paths = {p for p, *_ in s.logs}
    assert {"/world/camera/rgbd/image", "/envmap/envmaps/teapot"} <= paths
    assert any(p.startswith("/timings/") for p in paths)
