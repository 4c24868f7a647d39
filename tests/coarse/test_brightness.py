"""Brightness change Δ (paper §4.6): analytic shifts, a light switched on, serial reference, sampling, occlusion,
and the brightness_estimator node's pairing, waiting and fallbacks."""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass

import numpy as np
import pytest

from probeless.cameras.omnidir import OmnidirModel
from probeless.coarse.atlas import AtlasLayout, fit_atlas
from probeless.coarse.brightness import (
    draw_sample,
    estimate_delta,
    estimate_delta_serial,
    sampling_error,
)
from probeless.coarse.occlusion import floor_points, texel_visible
from probeless.coarse.project import project_texels, sample_image
from probeless.coarse.texels import TexelMap, texel_map
from probeless.messages.geometry import Floorplan, PoseStamped
from probeless.messages.header import Header
from probeless.messages.sensor import Image
from probeless.nodes.coarse.brightness import BrightnessEstimator
from probeless.runtime.params import load_params
from probeless.runtime.testing import RecordingContext, run_node
from probeless.scene.parse import load_scene
from probeless.scene.rig import FrameEvent, Rig, expose

FOV = 185.0


@dataclass
class Room:
    scene: object
    rig: Rig
    layout: AtlasLayout
    tm: TexelMap

    @property
    def model(self):
        return self.rig.fisheye

    def frame(self, t: float, lights_t: float | None = None):
        """(uint8 image, world_from_fisheye) at time t, lit as at ``lights_t`` (default t)."""
        if lights_t is None:
            return self.rig.render_fisheye(FrameEvent("fisheye", 0, t))
        pose = self.rig.fisheye_pose(t)
        radiance = self.rig.renderer.render_rays(pose, self.rig.rays, self.rig.light_scale(lights_t), 256)
        return expose(radiance, self.scene.fisheye.exposure), pose

    def observe(self, image, pose):
        """(atlas (H, W, 3) float32, observed (H, W)): every valid texel the frame sees, textured from it."""
        return observe(self.tm, self.model, image, pose, self.scene.floorplan, 1.5 / self.layout.texels_per_m)

    def args(self, atlas, observed, image, pose):
        return atlas, observed, self.tm, image, self.model, pose, FOV, self.scene.floorplan


def observe(tm, model, image, pose, floorplan, offset_m):
    pos, nrm = tm.position.reshape(-1, 3), tm.normal.reshape(-1, 3)
    uv, in_view = project_texels(pos, model, pose, FOV)
    seen = tm.valid.ravel() & in_view & texel_visible(pos, nrm, floorplan, pose[:2, 3], offset_m=offset_m)
    atlas = np.zeros((len(pos), 3), np.float32)
    atlas[seen] = sample_image(image, uv[seen])
    return atlas.reshape(tm.core.shape + (3,)), seen.reshape(tm.core.shape)


def _room(name: str) -> Room:
    scene = load_scene(f"launch/scenes/{name}.yaml")
    scene = dataclasses.replace(scene, fisheye=dataclasses.replace(scene.fisheye, width=512, height=512))
    layout = fit_atlas(scene.floorplan, scene.ceiling_height, 256)
    return Room(scene, Rig(scene, envmaps=False, fisheye_cube_size=256), layout, texel_map(layout))


@pytest.fixture(scope="module")
def rooms():
    made = {name: _room(name) for name in ("convex_room", "light_switch", "partition_room")}
    yield made
    for room in made.values():
        room.rig.release()


def _codes(delta):
    return np.asarray(delta, np.float64) * 255.0


@pytest.mark.gl
@pytest.mark.graph
@pytest.mark.slow
def test_constant_shift_is_recovered_and_bad_texels_are_excluded(rooms):
    room = rooms["convex_room"]
    image, pose = room.frame(1.0)
    base = np.clip(image, 20, 230)                 # no clipping after the shift, nothing black or saturated
    atlas, observed = room.observe(base, pose)
    c = np.array([10, -6, 4])
    shifted = (base.astype(np.int16) + c).astype(np.uint8)
    n_core = int((observed & room.tm.core).sum())
    assert n_core > 5000
    delta, used = estimate_delta(*room.args(atlas, observed, shifted, pose))
    np.testing.assert_allclose(_codes(delta), c, atol=1e-3)
    assert used == n_core
    # uint8 atlas and alpha as observed mask (as the node receives them): rounding only
    alpha = observed.astype(np.uint8) * 255
    delta, used8 = estimate_delta(*room.args(np.round(atlas * 255).astype(np.uint8), alpha, shifted, pose))
    np.testing.assert_allclose(_codes(delta), c, atol=0.1)
    assert used8 == used
    # old values black / saturated and never-observed texels (garbage in the atlas) are left out, exactly
    rng = np.random.default_rng(0)
    bad = atlas.copy()
    black, sat = rng.random(observed.shape) < 0.1, rng.random(observed.shape) < 0.1
    bad[black], bad[sat] = 0.0, 1.0
    unseen = rng.random(observed.shape) < 0.2
    obs2 = observed & ~unseen
    bad[~obs2 & ~black & ~sat] = 0.9
    delta, used = estimate_delta(*room.args(bad, obs2, shifted, pose))
    np.testing.assert_allclose(_codes(delta), c, atol=1e-3)
    assert used == int((obs2 & room.tm.core & ~black & ~sat).sum())
    # new values saturated (left half of the frame) or black (bottom right) are left out; texels whose
    # bilinear footprint straddles a spoiled region's edge are usable but off, so compare with the definition
    spoiled = shifted.copy()
    spoiled[:, :256] = 255
    spoiled[256:, 256:] = 0
    delta, used2 = estimate_delta(*room.args(atlas, observed, spoiled, pose))
    core = (observed & room.tm.core).ravel()
    uv, _ = project_texels(room.tm.position.reshape(-1, 3)[core], room.model, pose, FOV)
    new = sample_image(spoiled, uv).astype(np.float64) * 255
    keep = (new.max(axis=1) < 0.98 * 255) & (new.max(axis=1) > 0.01 * 255)
    reference = (new - atlas.reshape(-1, 3)[core] * 255.0)[keep].mean(axis=0)
    assert used2 == keep.sum() and 0.03 * n_core < used2 < 0.5 * n_core
    np.testing.assert_allclose(_codes(delta), reference, atol=1e-3)
    everything = (new - atlas.reshape(-1, 3)[core] * 255.0).mean(axis=0)
    assert np.abs(everything - c).max() > 20, "the spoiled regions must matter if they were not excluded"
    clean = keep & (np.abs(new - atlas.reshape(-1, 3)[core] * 255.0 - c).max(axis=1) < 1e-3)
    assert clean.sum() > 0.85 * keep.sum()            # most used texels are away from the spoiled edges


@pytest.mark.graph
@pytest.mark.slow
@pytest.mark.gl
def test_light_switching_on_gives_the_true_mean_change(rooms):
    room = rooms["light_switch"]
    before, pose_a = room.frame(2.9)                      # light off
    after, pose_b = room.frame(3.1)                       # light on (at t = 3 s)
    unlit, _ = room.frame(3.1, lights_t=2.9)              # same pose as `after`, light still off
    atlas, observed = room.observe(before, pose_a)
    delta, used = estimate_delta(*room.args(atlas, observed, after, pose_b), dark=0.01, saturated=0.98)
    assert used > 5000 and (_codes(delta) > 20).all()
    # reference: the rendered change at the same pose, over texels seen in both frames with usable values
    core = room.tm.core.ravel() & observed.ravel()
    pos = room.tm.position.reshape(-1, 3)[core]
    uv, in_view = project_texels(pos, room.model, pose_b, FOV)
    new, old = sample_image(after, uv[in_view]), sample_image(unlit, uv[in_view])
    prev = atlas.reshape(-1, 3)[core][in_view]

    def ok(v):
        return (v.max(axis=1) < 0.98) & (v.max(axis=1) > 0.01)

    keep = ok(new) & ok(old) & ok(prev)
    reference = _codes((new[keep] - old[keep]).mean(axis=0))
    assert np.abs(_codes(delta) - reference).max() < 2.0, (_codes(delta), reference)
    # and the plain frame means move the same way (a loose sanity bound: different pixel weighting)
    frame_change = (after.astype(np.float64) - before).reshape(-1, 3).mean(axis=0)
    assert (frame_change > 20).all()


@pytest.mark.graph
@pytest.mark.slow
@pytest.mark.gl
def test_serial_loop_equals_vectorised(rooms):
    room = rooms["partition_room"]                        # non-convex: occlusion in both
    image_a, pose_a = room.frame(0.5)
    image_b, pose_b = room.frame(0.8)
    atlas, observed = room.observe(image_a, pose_a)
    sample = draw_sample(room.tm, 4000, seed=1)
    kw = {"sample_idx": sample, "offset_m": 1.5 / room.layout.texels_per_m}
    d_vec, n_vec = estimate_delta(*room.args(atlas, observed, image_b, pose_b), **kw)
    d_ser, n_ser = estimate_delta_serial(*room.args(atlas, observed, image_b, pose_b), **kw)
    assert n_vec == n_ser > 500
    np.testing.assert_allclose(d_ser, d_vec, atol=1e-6)
    atlas8 = np.round(atlas * 255).astype(np.uint8)
    d_vec, n_vec = estimate_delta(*room.args(atlas8, observed, image_b, pose_b), sample_idx=sample.index[:1500])
    d_ser, n_ser = estimate_delta_serial(*room.args(atlas8, observed, image_b, pose_b), sample_idx=sample, limit=1500)
    assert n_vec == n_ser > 100
    np.testing.assert_allclose(d_ser, d_vec, atol=1e-6)


@pytest.mark.gl
@pytest.mark.graph
@pytest.mark.slow
def test_sample_is_fixed_and_close_to_the_all_texel_estimate(rooms):
    room = rooms["light_switch"]
    core = np.flatnonzero(room.tm.core.ravel())
    s1, s2, s3 = (draw_sample(room.tm, 5000, seed) for seed in (7, 7, 8))
    np.testing.assert_array_equal(s1.index, s2.index)
    assert not np.array_equal(s1.index, s3.index)
    assert len(np.unique(s1.index)) == 5000 and np.isin(s1.index, core).all()
    np.testing.assert_array_equal(draw_sample(room.tm, 0).index, core)
    np.testing.assert_array_equal(draw_sample(room.tm, 10 ** 9).index, core)
    np.testing.assert_allclose(s1.position, room.tm.position.reshape(-1, 3)[s1.index])
    before, pose_a = room.frame(2.9)
    after, pose_b = room.frame(3.1)
    atlas, observed = room.observe(before, pose_a)
    args = room.args(atlas, observed, after, pose_b)
    d_all, _ = estimate_delta(*args)
    for seed in (1, 2, 3):
        err, d_s, d_a = sampling_error(draw_sample(room.tm, 8000, seed), *args)
        np.testing.assert_allclose(d_a, d_all)
        assert err.max() < 1.5, err                      # a few standard errors of a ~3000-texel mean
        assert np.abs(_codes(d_s) - _codes(d_all)).max() == pytest.approx(err.max(), abs=1e-6)


def _blocked(viewpoint, q, poly):
    """Brute force: segment viewpoint -> q[k] properly crosses a floorplan edge."""
    a, b = poly[None], np.roll(poly, -1, axis=0)[None]
    p, q = viewpoint[None, None], q[:, None]

    def orient(o, x, y):
        return np.sign((x[..., 0] - o[..., 0]) * (y[..., 1] - o[..., 1])
                       - (x[..., 1] - o[..., 1]) * (y[..., 0] - o[..., 0]))

    return ((orient(p, q, a) * orient(p, q, b) < 0) & (orient(a, b, p) * orient(a, b, q) < 0)).any(axis=1)


@pytest.mark.gl
@pytest.mark.graph
@pytest.mark.slow
def test_texels_behind_the_partition_do_not_count(rooms):
    room = rooms["partition_room"]
    _, pose = room.frame(0.0)                             # left bay, the partition hides much of the right bay
    offset = 1.5 / room.layout.texels_per_m
    pos, nrm = room.tm.position.reshape(-1, 3), room.tm.normal.reshape(-1, 3)
    hidden = _blocked(pose[:2, 3], floor_points(pos, nrm, offset), room.scene.floorplan).reshape(room.tm.core.shape)
    observed = room.tm.core.copy()                        # pretend everything was seen before
    atlas = np.repeat(np.where(hidden, 0.7, 0.3)[..., None], 3, axis=2).astype(np.float32)
    image = np.full((512, 512, 3), 128, np.uint8)
    _, in_view = project_texels(pos, room.model, pose, FOV)
    in_view = in_view.reshape(hidden.shape) & observed
    assert (in_view & hidden).sum() > 2000, "hidden texels must be in the field of view for this to test anything"
    delta, used = estimate_delta(*room.args(atlas, observed, image, pose), offset_m=offset)
    np.testing.assert_allclose(delta, 128 / 255 - 0.3, atol=1e-5)
    assert used == int((in_view & ~hidden).sum())


# --- the brightness_estimator node -------------------------------------------------------------

ROOM = np.array([[0.0, 0.0], [5.0, 0.0], [5.0, 4.0], [0.0, 4.0]])
PARTITION = np.array([[0, 0], [2.95, 0], [2.95, 2.6], [3.05, 2.6], [3.05, 0], [6, 0], [6, 4.5], [0, 4.5]], float)
HEIGHT = 2.6
CAM = OmnidirModel.from_fov(256, 256, FOV)
POSE = np.eye(4)
POSE[:3, 3] = (2.5, 2.0, 1.3)                             # optical axis (camera z) straight up
SHIFT = np.array([6, -4, 3])
MS = 1_000_000
BASE = {"atlas_size": 128, "samples": 0, "atlas_timeout_s": 0.5}


def _pattern(k: int) -> np.ndarray:
    """A smooth colour pattern in 20..230, brightened by k * SHIFT."""
    v, u = np.mgrid[0:256, 0:256].astype(np.float64)
    rgb = np.stack([np.sin(u / 13), np.cos(v / 17), np.sin((u + v) / 23)], axis=2)
    return (125 + 90 * rgb + k * SHIFT).astype(np.uint8)


def _fisheye(stamp, k=0, data=None):
    return Image(Header(stamp, "fisheye"), _pattern(k) if data is None else data, "rgb8")


def _pose(stamp, T=POSE):
    return PoseStamped(Header(stamp, "world"), "fisheye", T)


def _atlas(stamp, k, floorplan=ROOM, size=128):
    """The texturer's rgba8 atlas after seeing pattern k from POSE."""
    layout = fit_atlas(floorplan, HEIGHT, size)
    tm = texel_map(layout)
    rgb, seen = observe(tm, CAM, _pattern(k), POSE, floorplan, 1.5 / layout.texels_per_m)
    rgba = np.concatenate([np.round(rgb * 255), seen[..., None] * 255.0], axis=2).astype(np.uint8)
    return Image(Header(stamp, "world"), rgba, "rgba8")


def _static(floorplan=ROOM):
    return [("camera_info", CAM.to_camera_info("fisheye", 0)),
            ("floorplan", Floorplan(Header(0, "world"), floorplan, HEIGHT))]


def _node(**params):
    ctx = RecordingContext("brightness", BrightnessEstimator)
    node = BrightnessEstimator(ctx, load_params(BrightnessEstimator.Params, {**BASE, **params}, node_id="brightness"))
    node.setup()
    return ctx, node


def _feed(node, *msgs):
    for name, msg in msgs:
        node.on_input(name, msg)


def _tick(ctx, seconds):
    ctx.clock_ns = int(seconds * 1e9)
    for _, callback in ctx.timers:
        callback()


def test_node_waits_for_the_atlas_holding_the_previous_frame():
    ctx, node = _node()
    _feed(node, *_static(), ("fisheye", _fisheye(100 * MS, 0)), ("fisheye_pose", _pose(100 * MS)))
    first, = ctx.outputs("delta")
    assert ((first.header.stamp_ns, first.header.frame_id, first.sampled, first.texels_used)
            == (100 * MS, "fisheye", False, 0))
    _feed(node, ("fisheye_pose", _pose(200 * MS)), ("fisheye", _fisheye(200 * MS, 1)))
    _feed(node, ("atlas", _atlas(50 * MS, 0)))             # older than frame 0: not the one frame 1 needs
    assert len(ctx.outputs("delta")) == 1
    _feed(node, ("atlas", _atlas(100 * MS, 0)))
    d1 = ctx.outputs("delta")[1]
    assert d1.header.stamp_ns == 200 * MS and d1.sampled and d1.texels_used > 1000
    np.testing.assert_allclose(d1.delta * 255, SHIFT, atol=0.6)
    # frame 2 must not be measured against frame 0's atlas (that would give 2 * SHIFT)
    _feed(node, ("fisheye", _fisheye(300 * MS, 2)), ("fisheye_pose", _pose(300 * MS)))
    assert len(ctx.outputs("delta")) == 2
    _feed(node, ("atlas", _atlas(200 * MS, 1)))
    d2 = ctx.outputs("delta")[2]
    assert d2.header.stamp_ns == 300 * MS
    np.testing.assert_allclose(d2.delta * 255, SHIFT, atol=0.6)
    # an atlas that is already there when the frame pairs is used at once
    _feed(node, ("atlas", _atlas(300 * MS, 2)), ("fisheye", _fisheye(400 * MS, 4)), ("fisheye_pose", _pose(400 * MS)))
    np.testing.assert_allclose(ctx.outputs("delta")[3].delta * 255, 2 * SHIFT, atol=0.6)
    assert node.counts["first_frame"] == 1 and node.counts["estimated"] == 3 and not node.counts["stale_atlas"]
    # the texturer gave up waiting and already applied frame 5: measured, but counted as atlas_ahead
    _feed(node, ("atlas", _atlas(500 * MS, 4)), ("fisheye", _fisheye(500 * MS, 4)), ("fisheye_pose", _pose(500 * MS)))
    np.testing.assert_allclose(ctx.outputs("delta")[4].delta * 255, 0, atol=0.6)
    assert node.counts["atlas_ahead"] == 1


def test_node_times_out_to_no_atlas_then_to_the_newest_atlas(caplog):
    ctx, node = _node()
    _feed(node, *_static(), ("fisheye", _fisheye(100 * MS)), ("fisheye_pose", _pose(100 * MS)))
    _feed(node, ("fisheye", _fisheye(200 * MS, 1)), ("fisheye_pose", _pose(200 * MS)))
    _tick(ctx, 0.4)
    assert len(ctx.outputs("delta")) == 1
    _tick(ctx, 0.6)
    late = ctx.outputs("delta")[1]
    assert late.header.stamp_ns == 200 * MS and not late.sampled and node.counts["no_atlas"] == 1
    _feed(node, ("atlas", _atlas(100 * MS, 0)))            # frame 1's atlas, too late for it
    ctx.clock_ns = int(1.0e9)
    _feed(node, ("fisheye", _fisheye(300 * MS, 2)), ("fisheye_pose", _pose(300 * MS)))
    _tick(ctx, 1.3)
    assert len(ctx.outputs("delta")) == 2
    _tick(ctx, 1.6)
    stale = ctx.outputs("delta")[2]
    assert stale.sampled and node.counts["stale_atlas"] == 1
    np.testing.assert_allclose(stale.delta * 255, 2 * SHIFT, atol=0.6)   # against frame 0's atlas
    with caplog.at_level(logging.INFO):
        node.close()
    assert "stale_atlas" in caplog.text and "no_atlas" in caplog.text
    # more than max_pending frames waiting: the oldest is settled at once
    ctx, node = _node(max_pending=1)
    _feed(node, *_static(), *[m for k in range(4) for m in (("fisheye", _fisheye((k + 1) * 100 * MS)),
                                                            ("fisheye_pose", _pose((k + 1) * 100 * MS)))])
    assert [d.header.stamp_ns for d in ctx.outputs("delta")] == [100 * MS, 200 * MS, 300 * MS]
    assert node.counts["no_atlas"] == 2 and len(node.pending) == 1


def test_node_survives_bad_input(caplog):
    ctx, node = _node()
    _feed(node, *_static(), ("fisheye", _fisheye(100 * MS)), ("fisheye_pose", _pose(100 * MS)),
          ("atlas", _atlas(100 * MS, 0)))
    nan_pose = _pose(200 * MS)
    object.__setattr__(nan_pose, "target_from_source", np.full((4, 4), np.nan))   # bypasses message validation
    _feed(node, ("fisheye", _fisheye(200 * MS, 1)), ("fisheye_pose", nan_pose))
    _feed(node, ("atlas", _atlas(200 * MS, 1)))
    _feed(node, ("fisheye", _fisheye(300 * MS, data=np.zeros((100, 120, 3), np.uint8))),
          ("fisheye_pose", _pose(300 * MS)))
    _feed(node, ("atlas", _atlas(300 * MS, 2)))
    _feed(node, ("fisheye", _fisheye(400 * MS, 3)), ("fisheye_pose", _pose(400 * MS)))   # good again
    out = ctx.outputs("delta")
    assert [d.sampled for d in out] == [False, False, False, True]
    assert all(not d.delta.any() for d in out[:3])
    assert node.counts["bad_pose"] == 1 and node.counts["bad_image"] == 1
    # an atlas of another layout is rejected with both shapes named; the frame then times out without one
    ctx, node = _node()
    with caplog.at_level(logging.ERROR):
        _feed(node, *_static(), ("atlas", _atlas(50 * MS, 0, size=64)))
    assert "(64, 64, 4)" in caplog.text and "(128, 128, 4)" in caplog.text and node.counts["atlas_rejected"] == 1
    _feed(node, ("fisheye", _fisheye(100 * MS)), ("fisheye_pose", _pose(100 * MS)),
          ("fisheye", _fisheye(200 * MS)), ("fisheye_pose", _pose(200 * MS)))
    _tick(ctx, 1.0)
    assert [d.sampled for d in ctx.outputs("delta")] == [False, False] and node.counts["no_atlas"] == 1


def test_node_camera_outside_a_non_convex_room():
    ctx, node = _node()
    _feed(node, *_static(PARTITION), ("fisheye", _fisheye(100 * MS)), ("fisheye_pose", _pose(100 * MS)),
          ("atlas", _atlas(100 * MS, 0, floorplan=PARTITION)))
    outside = POSE.copy()
    outside[:2, 3] = (10.0, 10.0)
    _feed(node, ("fisheye", _fisheye(200 * MS, 1)), ("fisheye_pose", _pose(200 * MS, outside)))
    _feed(node, ("atlas", _atlas(200 * MS, 1, floorplan=PARTITION)))
    inside = POSE.copy()
    inside[:2, 3] = (1.5, 2.0)
    _feed(node, ("fisheye", _fisheye(300 * MS, 2)), ("fisheye_pose", _pose(300 * MS, inside)))
    out = ctx.outputs("delta")
    assert [d.sampled for d in out] == [False, False, True]
    assert node.counts["geometry_error"] == 1


def test_node_first_frame_and_disabled_with_run_node():
    frames = [m for k in range(3) for m in (("fisheye", _fisheye((k + 1) * 100 * MS, k)),
                                            ("fisheye_pose", _pose((k + 1) * 100 * MS)))]
    ctx = run_node(BrightnessEstimator, _static() + frames, {**BASE, "enabled": False})
    out = ctx.outputs("delta")
    assert [d.header.stamp_ns for d in out] == [100 * MS, 200 * MS, 300 * MS]
    assert all(not d.sampled and d.texels_used == 0 and not d.delta.any() for d in out)
    ctx = run_node(BrightnessEstimator, _static() + frames[:2], BASE)
    first, = ctx.outputs("delta")
    assert not first.sampled and first.header.stamp_ns == 100 * MS
