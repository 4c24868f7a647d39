"""fisheye_from_rgbd: the LM solver on synthetic correspondences, matching + solving on rendered
images, frame pairing and the ``probeless calibrate extrinsics`` command on a recording."""

from __future__ import annotations

import argparse

import cv2
import numpy as np
import pytest
import yaml

from probeless import wire
from probeless.bag.writer import BagWriter
from probeless.cameras.calibrate_cli import add_calibrate_parser
from probeless.cameras.extrinsics import (
    default_init,
    from_rpy,
    load_extrinsics,
    reprojection_errors,
    rotation_error_deg,
    save_extrinsics,
    solve_fisheye_from_rgbd,
    to_rpy,
)
from probeless.cameras.kannala_brandt import KannalaBrandtModel
from probeless.cameras.matching import match_rgbd_fisheye, perspective_view, view_rays
from probeless.cameras.motion import motion_to_stamp, rgbd_motion
from probeless.cameras.omnidir import OmnidirModel
from probeless.cameras.pinhole import PinholeModel
from probeless.cameras.rig_bag import neighbour_stamp, pair_stamps
from probeless.errors import CalibrationError
from probeless.geom.rotation import rotation_from_rpy
from probeless.messages import CameraInfo, DepthImage, Header, Image

K_RGBD = np.array([[525.0, 0, 319.5], [0, 525.0, 239.5], [0, 0, 1]])
W, H = 640, 480
TRUE = {"translation": [0.012, -0.058, -0.025], "rpy_deg": [-86.0, 2.5, -1.5]}
# the room, a box in the RGB-D frame (y down: the ceiling is at y = -1.3)
LO, HI = np.array([-2.0, -1.3, -1.5]), np.array([2.5, 1.3, 3.0])


def fisheye_model():
    return OmnidirModel.from_fov(1024, 1024, 185.0)


def assert_close_transform(T, T_true, deg=0.5, mm=5.0):
    assert rotation_error_deg(T[:3, :3], T_true[:3, :3]) < deg
    assert np.linalg.norm(T[:3, 3] - T_true[:3, 3]) * 1000 < mm


# -- synthetic correspondences -------------------------------------------------------------------

def shell_matches(fisheye, T_true, rng, noise_px=0.5, outliers=0.1, n=6000):
    """Points on the room's walls seen by both cameras, their noisy fisheye pixels, outlier indices."""
    p = rng.uniform(LO, HI, (n, 3))
    axis, side = rng.integers(0, 3, n), rng.integers(0, 2, n)
    p[np.arange(n), axis] = np.where(side == 0, LO[axis], HI[axis])
    uv_r, ok_r = PinholeModel(W, H, K_RGBD).project(p)
    ok_r &= (p[:, 2] > 0) & PinholeModel(W, H, K_RGBD).in_image(np.nan_to_num(uv_r, nan=-9))
    uv_f, ok_f = fisheye.project(p @ T_true[:3, :3].T + T_true[:3, 3])
    ok_f &= fisheye.in_image(np.nan_to_num(uv_f, nan=-9))
    both = ok_r & ok_f
    P, UV = p[both], uv_f[both] + rng.normal(0, noise_px, (both.sum(), 2))
    bad = rng.choice(len(P), int(outliers * len(P)), replace=False)
    UV[bad] = rng.uniform(0, 1024, (len(bad), 2))
    return P, UV, bad


@pytest.mark.parametrize("model", ["omnidir", "kannala_brandt"])
def test_solver_recovers_known_transform(model):
    fisheye = fisheye_model() if model == "omnidir" else KannalaBrandtModel.from_fov(1024, 1024, 185.0)
    T_true = from_rpy(**TRUE)
    P, UV, bad = shell_matches(fisheye, T_true, np.random.default_rng(1))
    assert len(P) > 200
    T, report = solve_fisheye_from_rgbd(P, UV, fisheye)  # from the coarse default guess
    assert_close_transform(T, T_true)
    # the outliers that are really off (most of them) are rejected, the inliers kept
    far = reprojection_errors(T_true, P[bad], UV[bad], fisheye) > 3 * report.threshold_px
    assert report.inliers <= len(P) - far.sum()
    assert report.inliers >= 0.97 * (len(P) - len(bad))
    assert 0.5 < report.rms_px < 1.0   # 0.5 px noise per axis: about 0.71 px
    assert report.matches == len(P) and report.rounds >= 2 and report.iterations > 0


def test_solver_converges_from_a_distant_guess():
    T_true = from_rpy([0.03, -0.1, 0.02], [-75.0, 8.0, 6.0])  # 18 degrees from the default guess
    fisheye = fisheye_model()
    P, UV, _ = shell_matches(fisheye, T_true, np.random.default_rng(2))
    assert rotation_error_deg(default_init()[:3, :3], T_true[:3, :3]) > 15
    T, _ = solve_fisheye_from_rgbd(P, UV, fisheye)
    assert_close_transform(T, T_true)


def test_solver_errors():
    fisheye = fisheye_model()
    with pytest.raises(CalibrationError, match="need at least"):
        solve_fisheye_from_rgbd(np.ones((4, 3)), np.full((4, 2), 500.0), fisheye)
    with pytest.raises(CalibrationError, match="5 points but 6 pixels"):
        solve_fisheye_from_rgbd(np.ones((5, 3)), np.ones((6, 2)), fisheye)


def test_rpy_convention_matches_the_scene_files(tmp_path):
    rpy = [-86.0, 2.5, -1.5]
    T = from_rpy([0.1, 0.2, 0.3], rpy)
    np.testing.assert_allclose(T[:3, :3], rotation_from_rpy(np.array(rpy)), atol=1e-12)
    # the default guess: the fisheye's optical axis is the RGB-D camera's up (-y)
    np.testing.assert_allclose(default_init()[:3, :3] @ [0, -1, 0], [0, 0, 1], atol=1e-12)
    t, r = to_rpy(T)
    np.testing.assert_allclose(t, [0.1, 0.2, 0.3])
    np.testing.assert_allclose(r, rpy, atol=1e-9)
    save_extrinsics(tmp_path / "x.yaml", T)
    np.testing.assert_allclose(load_extrinsics(tmp_path / "x.yaml"), T, atol=1e-12)
    (tmp_path / "bad.yaml").write_text("fisheye_from_rgbd: {translation: [0, 0]}\n")
    with pytest.raises(CalibrationError, match="fisheye_from_rgbd"):
        load_extrinsics(tmp_path / "bad.yaml")


# -- rendered images ---------------------------------------------------------------------------------

def make_texture(seed=0, size=1024):
    rng = np.random.default_rng(seed)
    tex = np.full((size, size), 128, np.uint8)
    for _ in range(2500):
        c = tuple(int(v) for v in rng.integers(0, size, 2))
        col = int(rng.integers(0, 256))
        if rng.random() < 0.5:
            cv2.circle(tex, c, int(rng.integers(3, 30)), col, -1, cv2.LINE_AA)
        else:
            corner = (c[0] + int(rng.integers(4, 50)), c[1] + int(rng.integers(4, 50)))
            cv2.rectangle(tex, c, corner, col, -1, cv2.LINE_AA)
    return cv2.GaussianBlur(tex, (0, 0), 1.2)


def render_room(rays, origin, tex, texel=0.005):
    """Grey level and hit point of rays (N, 3) from ``origin`` inside the textured box room."""
    with np.errstate(divide="ignore", invalid="ignore"):
        exit_t = np.fmax((LO - origin) / rays, (HI - origin) / rays)
    exit_t = np.where(np.isnan(exit_t), np.inf, exit_t)
    axis = np.argmin(exit_t, axis=1)
    p = origin + rays * exit_t[np.arange(len(rays)), axis][:, None]
    a = np.where(axis == 0, p[:, 1], p[:, 0])
    b = np.where(axis == 2, p[:, 1], p[:, 2])
    face = 2 * axis + (p[np.arange(len(p)), axis] > (LO + HI)[axis] / 2)
    x, y = a / texel + 137.0 * face, b / texel + 311.0 * face
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = x - x0, y - y0
    h, w = tex.shape
    x0, y0 = x0.astype(np.int64) % w, y0.astype(np.int64) % h
    x1, y1 = (x0 + 1) % w, (y0 + 1) % h
    t = tex.astype(np.float64)
    g = (t[y0, x0] * (1 - fx) * (1 - fy) + t[y0, x1] * fx * (1 - fy) + t[y1, x0] * (1 - fx) * fy
         + t[y1, x1] * fx * fy)
    return np.clip(np.rint(g), 0, 255).astype(np.uint8), p


def render_rig(tex, room_from_rgbd, T_true, fisheye, rgbd=True):
    """(grey RGB-D image, depth [m]) and the fisheye image of the rig at ``room_from_rgbd``."""
    R, t = room_from_rgbd[:3, :3], room_from_rgbd[:3, 3]
    grey = depth = None
    if rgbd:
        g, p = render_room(view_rays(K_RGBD, W, H) @ R.T, t, tex)
        grey, depth = g.reshape(H, W), ((p - t) @ R)[:, 2].reshape(H, W).astype(np.float32)
    # the fisheye at twice the resolution, then area-averaged (anti-aliasing)
    K2 = fisheye.K * [[2], [2], [1]] + [[0, 0, 0.5], [0, 0, 0.5], [0, 0, 0]]
    big = OmnidirModel(2048, 2048, K2, fisheye.xi)
    rays, ok = big.unproject(big.pixel_grid())
    ok &= rays[:, 2] >= np.cos(np.radians(92.5))
    room_from_fisheye = room_from_rgbd @ np.linalg.inv(T_true)
    Rf, tf = room_from_fisheye[:3, :3], room_from_fisheye[:3, 3]
    g, _ = render_room(np.where(ok[:, None], rays, [0, 0, 1.0]) @ Rf.T, tf, tex)
    g[~ok] = 0
    return grey, depth, cv2.resize(g.reshape(2048, 2048), (1024, 1024), interpolation=cv2.INTER_AREA)


@pytest.fixture(scope="module")
def rendered():
    """(grey RGB-D image, depth [m], fisheye image, fisheye model, true fisheye_from_rgbd, texture),
    the rig at the room's origin."""
    tex = make_texture()
    T_true = from_rpy(**TRUE)
    fisheye = fisheye_model()
    grey, depth, fish = render_rig(tex, np.eye(4), T_true, fisheye)
    return grey, depth, fish, fisheye, T_true, tex


@pytest.mark.slow
def test_perspective_view_matches_a_direct_rendering(rendered):
    _, _, fish, fisheye, T_true, tex = rendered
    R = default_init()[:3, :3]
    view, mask = perspective_view(fish, fisheye, K_RGBD, (W, H), R)
    # the same view rendered directly: a pinhole at the fisheye centre, rotated by R
    Rt, t = T_true[:3, :3], T_true[:3, 3]
    direct, _ = render_room(view_rays(K_RGBD, W, H) @ R.T @ Rt, -Rt.T @ t, tex)
    inside = cv2.erode(mask, np.ones((9, 9), np.uint8)) > 0
    assert inside.mean() > 0.3    # the upper part of the RGB-D view is seen by the fisheye
    diff = np.abs(view.astype(float) - direct.reshape(H, W))[inside]
    assert np.median(diff) < 8 and diff.mean() < 15   # resampling blur only


@pytest.mark.slow
def test_match_and_solve_on_rendered_images(rendered):
    grey, depth, fish, fisheye, T_true, _ = rendered
    m = match_rgbd_fisheye(grey, depth, K_RGBD, fish, fisheye)
    assert len(m) >= 100
    # every kept match agrees with the true geometry (independent of the solver)
    err = reprojection_errors(T_true, m.points_rgbd, m.pixels_fisheye, fisheye)
    assert np.median(err) < 0.5 and np.percentile(err, 95) < 2.0
    T, report = solve_fisheye_from_rgbd(m.points_rgbd, m.pixels_fisheye, fisheye)
    assert_close_transform(T, T_true)
    assert report.rms_px < 1.0


@pytest.mark.slow
def test_matching_without_overlap_finds_nothing_consistent(rendered):
    grey, depth, fish, fisheye, _, _ = rendered
    # a guess that points the view at the wall behind the RGB-D camera: no consistent matches
    m = match_rgbd_fisheye(grey, depth, K_RGBD, fish, fisheye, from_rpy([0, 0, 0], [90, 0, 0]))
    assert len(m) < 10


# -- pairing and the command -----------------------------------------------------------------------

def test_pair_stamps():
    ms = 1_000_000
    rgb = [0, 33 * ms, 66 * ms, 100 * ms]
    fish = [13 * ms, 80 * ms, 150 * ms]
    assert pair_stamps(fish, rgb, rgb, 20 * ms, 10) == [(13 * ms, 0, 0), (80 * ms, 66 * ms, 66 * ms)]
    assert pair_stamps(fish, rgb, rgb, 10 * ms, 10) == []
    assert pair_stamps(fish, rgb, [], 20 * ms, 10) == []
    many = pair_stamps(list(range(0, 100 * ms, ms)), list(range(0, 100 * ms, ms)), list(range(0, 100 * ms, ms)),
                       0, 5)
    assert [f for f, _, _ in many] == [0, 25 * ms, 50 * ms, 74 * ms, 99 * ms]
    # the RGB frame on the other side of the fisheye frame, for motion compensation
    assert neighbour_stamp(rgb, 0, 13 * ms, 50 * ms) == 33 * ms
    assert neighbour_stamp(rgb, 66 * ms, 60 * ms, 50 * ms) == 33 * ms
    assert neighbour_stamp(rgb, 100 * ms, 110 * ms, 50 * ms) is None   # last frame
    assert neighbour_stamp(rgb, 0, 13 * ms, 20 * ms) is None            # too far


@pytest.mark.slow
def test_motion_compensation_helpers(rendered, moving):
    (t0, g0, d0), (t1, g1, _) = moving[0]
    b_from_a, inliers = rgbd_motion(g0, d0, g1, K_RGBD)
    truth = np.linalg.inv(rig_pose(1 / 30)) @ rig_pose(0.0)
    assert inliers >= 100
    assert rotation_error_deg(b_from_a[:3, :3], truth[:3, :3]) < 0.05
    assert np.linalg.norm(b_from_a[:3, 3] - truth[:3, 3]) < 0.002   # of 31 mm
    half = motion_to_stamp(truth, t0, t1, (t0 + t1) // 2)
    np.testing.assert_allclose(half @ half, truth, atol=2e-4)   # constant velocity: two halves make the whole
    with pytest.raises(CalibrationError, match="RGB-D motion"):
        rgbd_motion(g0, d0, np.zeros_like(g1), K_RGBD)


def cli(argv):
    p = argparse.ArgumentParser(prog="probeless")
    add_calibrate_parser(p.add_subparsers(dest="command", required=True))
    ns = p.parse_args(argv)
    return ns.func(ns)


def rig_pose(t):
    """room_from_rgbd of a rig moving at 0.9 m/s and turning at 30 deg/s."""
    return from_rpy(np.array([0.9, 0.0, 0.3]) * t, [0.0, 30.0 * t, 0.0])


@pytest.fixture(scope="module")
def moving(rendered):
    """RGB-D frames at 0 and 33.3 ms and a fisheye frame at 13 ms of the moving rig."""
    _, _, _, fisheye, T_true, tex = rendered
    g0, d0, _ = render_rig(tex, rig_pose(0.0), T_true, fisheye)
    g1, d1, _ = render_rig(tex, rig_pose(1 / 30), T_true, fisheye)
    _, _, fish = render_rig(tex, rig_pose(0.013), T_true, fisheye, rgbd=False)
    return [(0, g0, d0), (33_333_333, g1, d1)], [(13_000_000, fish), (150_000_000, fish)]


def write_rig_bag(path, fisheye, rgbd_frames, fisheye_frames):
    """A recording with the rig's topics: [(stamp, grey, depth [m])] and [(stamp, fisheye image)]."""
    infos = [("rig/rgbd/camera_info", CameraInfo(Header(0, "rgbd"), W, H, "pinhole", K_RGBD)),
             ("rig/fisheye/camera_info", fisheye.to_camera_info("fisheye"))]
    with BagWriter(path) as w:
        for topic, msg in infos:
            w.write_frames(wire.encode(topic, msg, "rig", 0), log_time_ns=0)
        for t, grey, depth in rgbd_frames:
            rgb = np.repeat(grey[..., None], 3, axis=2)
            w.write_frames(wire.encode("rig/rgb", Image(Header(t, "rgbd"), rgb, "rgb8"), "rig", t), log_time_ns=t)
            mm = DepthImage(Header(t, "rgbd"), np.rint(depth * 1000).astype(np.uint16), 1000.0)
            w.write_frames(wire.encode("rig/depth", mm, "rig", t), log_time_ns=t)
        for t, fish in fisheye_frames:
            bgr = np.repeat(fish[..., None], 3, axis=2)   # bgr8: exercises the conversion
            w.write_frames(wire.encode("rig/fisheye", Image(Header(t, "fisheye"), bgr, "bgr8"), "rig", t),
                           log_time_ns=t)


@pytest.mark.slow
def test_extrinsics_command_on_a_moving_rig(rendered, moving, tmp_path, capsys):
    fisheye, T_true = rendered[3], rendered[4]
    bag = tmp_path / "rig.mcap"
    write_rig_bag(bag, fisheye, *moving)   # the 2nd fisheye frame is 117 ms from any RGB-D frame
    out = tmp_path / "extrinsics.yaml"
    assert cli(["calibrate", "extrinsics", "--bag", str(bag), "-o", str(out), "--no-progress"]) == 0
    text = capsys.readouterr().out
    assert "from 1 pair(s)" in text and "rpy_deg" in text
    # the rig moved 11.7 mm and 0.39 deg between the RGB-D frame and the fisheye frame
    assert "rig moved 11." in text or "rig moved 12." in text
    data = yaml.safe_load(out.read_text())
    T = load_extrinsics(out)
    assert_close_transform(T, T_true)
    np.testing.assert_allclose(np.array(data["fisheye_from_rgbd_matrix"]), T, atol=1e-9)
    assert data["report"]["rms_px"] < 1.0 and data["report"]["inliers"] >= 100
    assert data["source"]["pairs"] == 1 and data["source"]["motion_compensation"] is True
    # without motion compensation the motion leaks into the transform
    out2 = tmp_path / "static.yaml"
    assert cli(["calibrate", "extrinsics", "--bag", str(bag), "-o", str(out2), "--no-progress",
                "--no-motion-compensation"]) == 0
    T2 = load_extrinsics(out2)
    assert np.linalg.norm(T2[:3, 3] - T_true[:3, 3]) > 0.008
    # errors
    with pytest.raises(CalibrationError, match="already exists"):
        cli(["calibrate", "extrinsics", "--bag", str(bag), "-o", str(out)])
    with pytest.raises(CalibrationError, match="within --max-dt"):
        cli(["calibrate", "extrinsics", "--bag", str(bag), "-o", str(tmp_path / "b.yaml"), "--max-dt", "0.001"])
    with pytest.raises(CalibrationError, match="no CameraInfo on topic 'cam/rgbd/camera_info'"):
        cli(["calibrate", "extrinsics", "--bag", str(bag), "-o", str(tmp_path / "c.yaml"), "--node", "cam"])
