"""LUT undistortion against closed forms, the direct per-pixel reference, and the node."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from probeless.cameras import KannalaBrandtModel, OmnidirModel
from probeless.cameras.base import camera_matrix
from probeless.cameras.undistort import LongLat, build_lut, remap, sample_positions, undistort_direct
from probeless.errors import CalibrationError
from probeless.messages.header import Header
from probeless.messages.sensor import Image
from probeless.nodes.sensors.undistort import FisheyeUndistort
from probeless.runtime.testing import run_node

F_SRC = 180.0
SRC = KannalaBrandtModel(640, 480, camera_matrix(F_SRC, F_SRC, 321.3, 238.7))  # equidistant, r = F_SRC theta
DST = OmnidirModel.from_fov(300, 300, 185.0, xi=1.0)                         # r = f tan(theta / 2)


def expected_positions(dst_px):
    """Closed form of KB-equidistant <- ideal xi=1 omnidir: theta = 2 atan(rho / f), source r = F_SRC theta."""
    f, c = DST.K[0, 0], DST.K[:2, 2]
    d = dst_px - c
    rho = np.hypot(d[:, 0], d[:, 1])
    theta = 2 * np.arctan(rho / f)
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.where(rho > 0, F_SRC * theta / rho, F_SRC / f * 2)
    return SRC.K[:2, 2] + d * scale[:, None]


def coordinate_image(width, height):
    """Float32 image whose two channels hold each pixel's own (u, v): bilinear sampling returns the position."""
    u, v = np.meshgrid(np.arange(width, dtype=np.float32), np.arange(height, dtype=np.float32))
    return np.stack([u, v], axis=-1)


def interior(pos, model):
    return ((pos >= 0) & (pos <= np.array([model.width - 1, model.height - 1]))).all(axis=-1)


def test_lut_matches_closed_form_mapping():
    map_x, map_y = build_lut(SRC, DST)
    assert map_x.dtype == np.float32 and map_x.shape == (300, 300)
    grid = DST.pixel_grid()
    want = expected_positions(grid).reshape(300, 300, 2)
    inside = interior(want, SRC)
    assert inside.mean() > 0.5
    got = np.stack([map_x, map_y], axis=-1)
    assert np.abs(got - want)[inside].max() < 1e-3
    theta = np.degrees(2 * np.arctan(np.hypot(*(grid - DST.K[:2, 2]).T) / DST.K[0, 0])).reshape(300, 300)
    outside = ~SRC.in_image(want.reshape(-1, 2)).reshape(300, 300) | (theta > 180)
    assert outside.mean() > 0.05 and (got[outside] < -1).all()  # no source pixel: sampled as black


def test_remapped_positions_equal_direct_within_half_pixel():
    image = coordinate_image(SRC.width, SRC.height)
    want = expected_positions(DST.pixel_grid()).reshape(300, 300, 2)
    inside = interior(want, SRC)
    lut = build_lut(SRC, DST)
    out = remap(image, lut)
    assert out.shape == (300, 300, 2) and out.dtype == np.float32
    assert np.abs(out - want)[inside].max() < 0.02  # cv2.remap samples on a 1/32 px grid
    direct = undistort_direct(image, SRC, DST)
    assert np.abs(direct - want)[inside].max() < 0.02
    assert np.abs(out - direct)[inside].max() < 0.5


def test_longlat_axes_and_closed_form():
    ll = LongLat(720, 360)
    uv, ok = ll.project(np.array([[0, 0, 1.0], [1, 0, 0], [0, -1, 0], [-1, 0, 0]]))
    assert ok.all()
    np.testing.assert_allclose(uv[:3], [[359.5, 179.5], [539.5, 179.5], [359.5, -0.5]], atol=1e-9)
    assert uv[3, 0] == pytest.approx(179.5)  # lon = -90 deg: the camera's left
    rays, _ = ll.unproject(np.array([[100.0, 40.0], [700.0, 300.0]]))
    np.testing.assert_allclose(ll.project(rays)[0], [[100, 40], [700, 300]], atol=1e-9)
    # equator of a fisheye -> longlat LUT: lon = theta, equidistant source r = F_SRC theta
    map_x, map_y = build_lut(SRC, ll)
    lon = np.radians((np.arange(720) + 0.5) / 720 * 360 - 180)
    lat = np.radians(90 - (179 + 0.5) / 360 * 180)
    x, y, z = np.cos(lat) * np.sin(lon), -np.sin(lat), np.cos(lat) * np.cos(lon)
    theta = np.arccos(z)
    r = np.hypot(x, y)
    want_u = SRC.K[0, 2] + F_SRC * theta * x / r
    sel = np.abs(lon) < np.radians(80)
    np.testing.assert_allclose(map_x[179, sel], want_u[sel], atol=1e-3)
    np.testing.assert_allclose(map_y[179, sel], SRC.K[1, 2] + F_SRC * theta[sel] * y / r[sel], atol=1e-3)
    assert (map_x[179, :150] < -1).all()  # lon < -105 deg on the equator: r = 180 theta > 321.8 px, off the image
    assert (map_x[179, 160:200] > -0.5).all()  # lon in [-100, -80] deg: still on the image


def test_remap_keeps_rank_and_dtype():
    lut = build_lut(SRC, DST)
    for data in (np.full((480, 640, 1), 200, np.uint8), np.ones((480, 640, 3), np.float16)):
        out = remap(data, lut)
        assert out.shape == (300, 300, data.shape[2]) and out.dtype == data.dtype
        want = expected_positions(DST.pixel_grid()).reshape(300, 300, 2)
        inside = interior(want, SRC)
        off = ~SRC.in_image(want.reshape(-1, 2)).reshape(300, 300)
        assert inside.mean() > 0.5 and off.mean() > 0.01
        np.testing.assert_array_equal(out[inside], np.broadcast_to(data[0, 0], out[inside].shape))
        assert (out[off] == 0).all()  # no source pixel -> black


# --- node -----------------------------------------------------------------------------------------

def frame(k, width=640, height=480):
    rng = np.random.default_rng(k)
    return Image(Header(1000 + k, "fisheye"), rng.integers(0, 255, (height, width, 3), dtype=np.uint8), "rgb8")


def test_node_drops_until_info_reuses_and_rebuilds_lut(caplog):
    info_a = SRC.to_camera_info("fisheye", 10)
    info_a_restamped = SRC.to_camera_info("fisheye", 20)
    src_b = KannalaBrandtModel(640, 480, camera_matrix(150.0, 150.0, 320.0, 240.0), [0.01, 0, 0, 0])
    info_b = src_b.to_camera_info("fisheye", 30)
    inputs = [("image", frame(0)), ("image", frame(1)), ("camera_info", info_a), ("image", frame(2)),
              ("camera_info", info_a_restamped), ("image", frame(3)), ("camera_info", info_b), ("image", frame(4))]
    params = {"width": 300, "height": 300, "fov_deg": 185.0, "xi": 1.0}
    with caplog.at_level(logging.INFO):
        ctx = run_node(FisheyeUndistort, inputs, params)
    builds = [r for r in caplog.records if "built undistortion LUT" in r.getMessage()]
    assert len(builds) == 2  # once for info_a (re-stamped copy reused), once for info_b
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert sum("dropping images" in w for w in warnings) == 1 and any("dropped 2 image" in w for w in warnings)
    images = ctx.outputs("image")
    assert [m.header.stamp_ns for m in images] == [1002, 1003, 1004]
    np.testing.assert_array_equal(images[0].data, remap(frame(2).data, build_lut(SRC, DST)))
    np.testing.assert_array_equal(images[2].data, remap(frame(4).data, build_lut(src_b, DST)))
    infos = ctx.outputs("camera_info")
    assert [i.header.stamp_ns for i in infos] == [10, 20, 30]
    assert infos[0].model == "omnidir" and infos[0].header.frame_id == "fisheye"
    np.testing.assert_allclose(infos[0].K, DST.K)
    assert infos[0].xi == 1.0 and len(infos[0].D) == 0


def test_node_longlat_target_and_size_mismatch():
    ctx = run_node(FisheyeUndistort, [("camera_info", SRC.to_camera_info("fisheye")), ("image", frame(0))],
                   {"target": "longlat", "width": 360, "height": 180})
    assert ctx.outputs("camera_info") == []  # no CameraInfo model describes an equirectangular image
    (out,) = ctx.outputs("image")
    np.testing.assert_array_equal(out.data, remap(frame(0).data, build_lut(SRC, LongLat(360, 180))))
    with pytest.raises(CalibrationError, match="does not match camera_info"):
        run_node(FisheyeUndistort, [("camera_info", SRC.to_camera_info("fisheye")), ("image", frame(0, 320, 240))])


def test_wide_fov_lut_sees_behind_the_image_plane():
    src = KannalaBrandtModel.from_fov(800, 800, 200.0)
    dst = OmnidirModel.from_fov(400, 400, 200.0, xi=1.0)
    pos = sample_positions(src, dst)
    # closed form: dst pixel at radius rho sees theta = 2 atan(rho / f_dst); src radius = f_src theta
    f_dst, f_src = dst.K[0, 0], src.K[0, 0]
    px = np.array([[0.0, 199.0], [2.0, 150.0], [399.0, 260.0], [100.0, 30.0]])
    d = px - 199.5
    rho = np.hypot(d[:, 0], d[:, 1])
    theta = 2 * np.arctan(rho / f_dst)
    assert np.degrees(theta).max() > 99  # these rays lie behind the image plane (z < 0)
    want = 399.5 + d / rho[:, None] * (f_src * theta)[:, None]
    np.testing.assert_allclose(pos[px[:, 1].astype(int), px[:, 0].astype(int)], want, atol=1e-6)


def test_our_table_equals_opencv_omnidir_for_the_same_mapping():
    """build_lut against cv2.omnidir.initUndistortRectifyMap on the same Mei -> xi = 1 mapping (the bench's
    reference): the same table, so the bench compares equal work."""
    from probeless.bench.undistort import MEI_D, MEI_K, MEI_XI, cv2_stereographic_maps

    src = OmnidirModel(256, 256, MEI_K / 4 + np.diag([0, 0, 0.75]), MEI_XI, MEI_D)
    dst = OmnidirModel.from_fov(256, 256, 185.0, xi=1.0)
    ours, theirs = build_lut(src, dst), cv2_stereographic_maps(src, dst)
    exact = sample_positions(src, dst)
    inside = np.isfinite(exact).all(axis=-1)
    assert inside.mean() > 0.5
    assert np.hypot(ours[0] - theirs[0], ours[1] - theirs[1])[inside].max() < 1e-3
    assert np.hypot(theirs[0] - exact[..., 0], theirs[1] - exact[..., 1])[inside].max() < 1e-3
    with pytest.raises(ValueError, match="xi = 1"):
        cv2_stereographic_maps(src, OmnidirModel.from_fov(256, 256, 185.0, xi=0.8))


@pytest.mark.slow
def test_bench_quick_reports_absolute_costs_and_the_opencv_gate():
    from probeless.bench.undistort import measure

    r = measure(quick=True)
    assert r["max_px_diff"] <= 0.5 and r["max_px_diff_pixels"] > 100_000
    assert r["mean_abs_diff"] < 1.0
    assert r["lut_build_ms"] > r["remap_ms"] > 0  # the one-off build against one frame's remap
    ref = r["reference"]
    assert ref["gate_met"] is True and ref["map_agreement_px"] <= 1e-3 and ref["output_max_abs_diff"] <= 1
    assert ref["output_shapes"]["ours"] == ref["output_shapes"]["cv2"]
