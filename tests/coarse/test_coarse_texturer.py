"""The GPU texturer against the CPU projection, the GPU occlusion mask against the brute-force
visibility reference, and the coarse_texturer node's pairing, Δ waiting and bad-input handling."""

from __future__ import annotations

import numpy as np
import pytest

from probeless.cameras.omnidir import OmnidirModel
from probeless.coarse.atlas import fit_atlas
from probeless.coarse.gpu import AtlasTexturer
from probeless.coarse.model import CoarseConfig, CoarseModel
from probeless.coarse.project import project_texels, sample_image
from probeless.coarse.texels import texel_map
from probeless.coarse.visibility import visible_from
from probeless.errors import CalibrationError
from probeless.messages.geometry import Floorplan, PoseStamped
from probeless.messages.header import Header
from probeless.messages.lighting import BrightnessDelta
from probeless.messages.sensor import Image
from probeless.nodes.coarse.texturer import CoarseTexturer
from probeless.runtime.params import load_params
from probeless.runtime.testing import RecordingContext
from probeless.scene.parse import load_scene
from probeless.scene.rig import Rig, frame_schedule

pytestmark = [pytest.mark.gl]

SCENES = "launch/scenes"


@pytest.fixture(scope="module")
def partition():
    """The partition room, a 256^2 atlas, and two rendered fisheye frames with their true poses."""
    scene = load_scene(f"{SCENES}/partition_room.yaml")
    rig = Rig(scene, envmaps=False, fisheye_cube_size=256)
    events = [e for e in frame_schedule(scene, 1.0) if e.kind == "fisheye"]
    frames = [rig.render_fisheye(e) + (e,) for e in (events[0], events[-1])]
    layout = fit_atlas(scene.floorplan, scene.ceiling_height, 256)
    yield scene, rig, layout, texel_map(layout), frames
    rig.renderer.release()


@pytest.mark.graph
def test_texture_update_matches_cpu_projection(partition):
    scene, rig, layout, texmap, frames = partition
    image, pose, _ = frames[0]
    fov = scene.fisheye.fov_deg - 2
    tex = AtlasTexturer(layout, texmap, fov_deg=fov, ctx=rig.renderer.ctx)
    tex.occlusion(pose[:2, 3])
    tex.update(image, rig.fisheye, pose, (0.0, 0.0, 0.0), 0.5)
    rgb, seen = tex.read_atlas()
    occ = tex.read_occlusion()
    valid = texmap.valid
    uv, in_view = project_texels(texmap.position[valid], rig.fisheye, pose, fov)
    expect_seen = in_view & occ[valid]
    gpu_seen = seen[valid] == np.float32(0.5)
    # float32 on the GPU vs float64 here: only texels exactly on the field-of-view edge may differ
    assert np.mean(gpu_seen != expect_seen) < 1e-3
    both = gpu_seen & expect_seen
    ref = sample_image(image, uv[both])
    err = np.abs(rgb[valid][both] - ref) * 255
    assert err.mean() < 0.3 and err.max() <= 1.5  # 8-bit texture filtering on the GPU vs float bilinear
    assert np.all(seen[valid][~gpu_seen] == -1.0)
    tex.release()


@pytest.mark.graph
@pytest.mark.slow
def test_gpu_occlusion_matches_brute_force_visibility(partition):
    scene, rig, layout, texmap, frames = partition
    tex = AtlasTexturer(layout, texmap, ctx=rig.renderer.ctx)
    for _, pose, _ in frames:
        tex.occlusion(pose[:2, 3])
        occ = tex.read_occlusion()
        core = texmap.core
        pts = texmap.position[core][:, :2] + texmap.normal[core][:, :2] * (1.5 / layout.texels_per_m)
        ref = visible_from(scene.floorplan, pose[:2, 3], pts.astype(np.float64))
        agree = occ[core] == ref
        assert (~ref).sum() > 1000  # the partition hides a real part of the room from this viewpoint
        assert agree.mean() > 0.995  # disagreement only on the mask's rasterised edges
    tex.release()


@pytest.mark.graph
def test_delta_applies_to_texels_out_of_view(partition):
    scene, rig, layout, texmap, frames = partition
    tex = AtlasTexturer(layout, texmap, fov_deg=scene.fisheye.fov_deg - 2, ctx=rig.renderer.ctx)
    image, pose, _ = frames[0]
    tex.occlusion(pose[:2, 3])
    tex.update(image, rig.fisheye, pose, (0, 0, 0), 0.0)
    before, seen0 = tex.read_atlas()
    tex.update(np.zeros_like(image), rig.fisheye, pose, (0.1, -0.05, 0.2), 1.0)
    after, seen1 = tex.read_atlas()
    out = texmap.valid & (seen1 != np.float32(1.0))
    np.testing.assert_allclose(after[out] - before[out], np.tile([0.1, -0.05, 0.2], (out.sum(), 1)), atol=1e-6)
    inside = seen1 == np.float32(1.0)
    assert np.all(after[inside] == 0)  # texels in view took the (black) frame
    assert np.all(seen1[out] == seen0[out])
    tex.release()


@pytest.mark.graph
def test_texturer_rejects_a_distorted_model(partition):
    scene, rig, layout, texmap, frames = partition
    tex = AtlasTexturer(layout, texmap, ctx=rig.renderer.ctx)
    m = rig.fisheye
    distorted = OmnidirModel(m.width, m.height, m.K, m.xi, np.array([0.1, 0, 0, 0]))
    with pytest.raises(CalibrationError, match="undistorted runtime model"):
        tex.update(frames[0][0], distorted, frames[0][1])
    tex.release()


def _node(params=None):
    ctx = RecordingContext("tex", CoarseTexturer)
    node = CoarseTexturer(ctx, load_params(CoarseTexturer.Params, {"atlas_size": 128, "inpaint": False,
                                                                    "mask_every": 1, **(params or {})}, node_id="tex"))
    node.setup()
    return ctx, node


def _inputs(scene, rig, frames):
    header = Header(0, "world")
    info = rig.fisheye.to_camera_info("fisheye", 0)
    yield "floorplan", Floorplan(header, scene.floorplan, scene.ceiling_height)
    yield "camera_info", info
    for image, pose, event in frames:
        stamp = event.stamp_ns
        yield "fisheye", Image(Header(stamp, "fisheye"), image, "rgb8")
        yield "fisheye_pose", PoseStamped(Header(stamp, "world"), "fisheye", pose)


@pytest.mark.graph
def test_node_matches_offline_model_and_waits_for_delta(partition):
    scene, rig, layout, texmap, frames = partition
    ctx, node = _node()
    for name, msg in _inputs(scene, rig, frames):
        node.on_input(name, msg)
    assert len(ctx.outputs("mesh")) == 1
    assert ctx.outputs("atlas") == []  # both frames wait for their delta
    stamps = [e.stamp_ns for _, _, e in frames]
    node.on_input("delta", BrightnessDelta(Header(stamps[1], "fisheye"), np.zeros(3, np.float32), 10, True))
    assert ctx.outputs("atlas") == []  # the first frame still waits: frames are applied in order
    node.on_input("delta", BrightnessDelta(Header(stamps[0], "fisheye"), np.zeros(3, np.float32), 0, False))
    atlases = ctx.outputs("atlas")
    assert [a.header.stamp_ns for a in atlases] == stamps
    offline = CoarseModel(scene.floorplan, scene.ceiling_height, CoarseConfig(atlas_size=128, inpaint=False),
                          ctx=node.model.gpu.ctx)
    for image, pose, event in frames:
        offline.step(image, rig.fisheye, pose, (0, 0, 0), (event.stamp_ns - stamps[0]) * 1e-9)
    np.testing.assert_array_equal(atlases[-1].data, offline.gpu.read_packed())
    assert ctx.outputs("observed")[-1].data.max() == 255 and ctx.outputs("occlusion")[-1].data.shape == (128, 128, 1)
    offline.release()
    node.close()


@pytest.mark.graph
def test_node_delta_timeout_and_bad_pose(partition):
    scene, rig, layout, texmap, frames = partition
    ctx, node = _node({"delta_timeout_s": 0.5})
    msgs = list(_inputs(scene, rig, frames[:1]))
    bad = frames[0][1].copy()
    bad[0, 3] = 100.0  # far outside the room (NaN poses never get here: PoseStamped rejects them)
    stamp2 = frames[0][2].stamp_ns + 10
    msgs += [("fisheye", Image(Header(stamp2, "fisheye"), frames[0][0], "rgb8")),
             ("fisheye_pose", PoseStamped(Header(stamp2, "world"), "fisheye", bad))]
    for name, msg in msgs:
        node.on_input(name, msg)
    assert ctx.outputs("atlas") == []
    ctx.clock_ns += 600_000_000
    for _, timer in ctx.timers:
        timer()
    assert len(ctx.outputs("atlas")) == 1  # the frame posed outside the room is skipped, not applied
    assert node.counts["delta_timeout"] == 2
    assert node.counts["skipped:GeometryError"] == 1
    node.close()
