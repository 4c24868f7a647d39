"""Dataset readers (7-Scenes, Redwood, TUM), TUM conversion, the dataset CLI and the RGB-D player node,
checked against the files themselves read independently (numpy/OpenCV/scipy)."""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
from locations import SHARED_DATA
from scipy.spatial.transform import Rotation, Slerp

from probeless.datasets.cli import add_dataset_parser
from probeless.datasets.convert import convert_to_tum
from probeless.datasets.detect import detect_format, open_rgbd, select
from probeless.datasets.playback import drain
from probeless.datasets.stream import rgbd_groups
from probeless.datasets.textfiles import IntrinsicsOverride
from probeless.datasets.tum import pose_at
from probeless.errors import DatasetError
from probeless.nodes.sensors.rgbd_dataset import RgbdDatasetPlayer
from probeless.runtime.params import load_params
from probeless.runtime.testing import RecordingContext

DATA = SHARED_DATA / "rgbd"
SEVEN = DATA / "sevenscenes_kinect_0000-0399"
ICL = DATA / "icl_livingroom1_micro"


def ref_depth_7scenes(n: int) -> np.ndarray:
    d = cv2.imread(str(SEVEN / f"frame-{n:06d}.depth.png"), cv2.IMREAD_UNCHANGED)
    d[d == 65535] = 0  # 7-Scenes marks missing depth with 65535 as well as 0
    return d


def ref_log(path: Path) -> dict[int, np.ndarray]:
    """Independent Redwood .log reader: blocks of 5 lines."""
    rows = [ln.split() for ln in path.read_text().splitlines() if ln.strip()]
    return {int(rows[k][0]): np.array(rows[k + 1:k + 5], dtype=float) for k in range(0, len(rows), 5)}


def make_node(params: dict, ctx: RecordingContext | None = None):
    ctx = ctx or RecordingContext("cam", RgbdDatasetPlayer)
    node = RgbdDatasetPlayer(ctx, load_params(RgbdDatasetPlayer.Params, params, node_id="cam"))
    node.setup()
    return node, ctx


def play(params: dict, ctx: RecordingContext | None = None) -> RecordingContext:
    node, ctx = make_node(params, ctx)
    try:
        drain(ctx.timers[0][1], ctx)
    finally:
        node.close()
    return ctx


def play_until(params: dict, n_rgb: int) -> RecordingContext:
    """Step the player's timer until it has sent ``n_rgb`` rgb frames (for looping players), then close it."""
    node, ctx = make_node(params)
    try:
        while len(ctx.outputs("rgb")) < n_rgb:
            ctx.timers[0][1]()
    finally:
        node.close()
    return ctx


# --- 7-Scenes ---------------------------------------------------------------------------------

def test_sevenscenes_frames_intrinsics_and_poses():
    assert detect_format(SEVEN) == "7scenes"
    seq = open_rgbd(SEVEN)
    assert len(seq.frames) == 400
    assert seq.frames[0].rgb_path.name == "frame-000000.color.jpg"
    assert seq.frames[-1].depth_path.name == "frame-000399.depth.png"
    assert seq.frames[-1].stamp_ns == round(399 / 30 * 1e9)
    K = np.loadtxt(SEVEN / "camera-intrinsics.txt")
    i = seq.intrinsics
    assert (i.fx, i.fy, i.cx, i.cy) == (K[0, 0], K[1, 1], K[0, 2], K[1, 2]) == (585, 585, 320, 240)
    assert (i.width, i.height) == (640, 480)
    assert seq.depth_scale == 1000.0
    for f in seq.frames:
        R = f.pose[:3, :3]
        assert np.abs(R.T @ R - np.eye(3)).max() < 1e-12 and np.linalg.det(R) == pytest.approx(1.0, abs=1e-12)
        raw = np.loadtxt(SEVEN / f"frame-{f.index:06d}.pose.txt")
        assert np.abs(f.pose - raw).max() < 1e-3
        # the SVD projection is the nearest rotation: scipy's chordal-mean of one matrix agrees
        nearest = Rotation.from_matrix(raw[:3, :3]).as_matrix()
        assert np.abs(R - nearest).max() < 1e-6


def test_sevenscenes_messages_match_the_files():
    full = open_rgbd(SEVEN)
    first, last = select(full, 0, 1), select(full, 396)
    frames = first.frames + last.frames
    groups = list(rgbd_groups(first, "rgbd")) + list(rgbd_groups(last, "rgbd"))
    assert len(groups) == 5 and [f.index for f in frames] == [0, 396, 397, 398, 399]
    for f, (stamp, msgs) in zip(frames, groups):
        out = dict(msgs)
        assert [o for o, _ in msgs] == ["rgbd/camera_info", "rgb", "depth", "gt/rgbd_pose"]
        bgr = cv2.imread(str(f.rgb_path))
        np.testing.assert_array_equal(out["rgb"].data, bgr[:, :, ::-1])
        np.testing.assert_array_equal(out["depth"].data, ref_depth_7scenes(f.index))
        assert out["depth"].data.dtype == np.uint16 and out["depth"].depth_scale == 1000.0
        assert out["rgbd/camera_info"].K[0, 0] == 585 and out["rgbd/camera_info"].model == "pinhole"
        pose = out["gt/rgbd_pose"]
        assert pose.header.frame_id == "world" and pose.child_frame_id == "rgbd"
        assert np.abs(pose.target_from_source - np.loadtxt(SEVEN / f"frame-{f.index:06d}.pose.txt")).max() < 1e-3
        assert stamp == out["rgb"].header.stamp_ns == out["depth"].header.stamp_ns == round(f.index * 1e9 / 30)


# --- Redwood ----------------------------------------------------------------------------------

def test_redwood_icl_sparse_ground_truth_and_intrinsics():
    assert detect_format(ICL) == "redwood"
    seq = open_rgbd(ICL)
    assert len(seq.frames) == 211 and seq.depth_scale == 1000.0
    i = seq.intrinsics
    assert (i.fx, i.fy, i.cx, i.cy) == (525.0, 525.0, 319.5, 239.5)
    assert seq.pose_source.endswith("groundtruth_sparse_official.log")
    gt = ref_log(ICL / "groundtruth_sparse_official.log")
    assert sorted(gt) == [0, 1, 2, 3, 4, 50, 100, 150, 200]
    assert [f.index for f in seq.frames if f.pose is not None] == sorted(gt)
    for k, T in gt.items():
        assert np.abs(seq.frames[k].pose - T).max() < 1e-6
    d = cv2.imread(str(ICL / "depth" / "00150.png"), cv2.IMREAD_UNCHANGED)
    _, msgs = next(rgbd_groups(select(seq, 150, 1)))
    np.testing.assert_array_equal(dict(msgs)["depth"].data, d)


def test_redwood_reconstructed_trajectory_agrees_with_ground_truth():
    seq = open_rgbd(ICL, trajectory="open3d_reconstructed_trajectory.log")
    assert all(f.pose is not None for f in seq.frames)
    gt = ref_log(ICL / "groundtruth_sparse_official.log")
    # Open3D's reconstruction starts at identity; align on frame 0 (README: 1-23 mm apart)
    align = gt[0] @ np.linalg.inv(seq.frames[0].pose)
    errors = [np.linalg.norm((align @ seq.frames[k].pose)[:3, 3] - T[:3, 3]) for k, T in gt.items()]
    assert max(errors) < 0.03 and errors[0] < 1e-9


# --- TUM ----------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def tum_dir(tmp_path_factory) -> Path:
    dst = tmp_path_factory.mktemp("tum") / "seq"
    summary = convert_to_tum(select(open_rgbd(SEVEN), 0, 40), dst)
    assert summary["frames"] == 40 and summary["poses"] == 40
    return dst


@pytest.mark.slow
def test_tum_roundtrip_of_converted_7scenes(tum_dir):
    assert detect_format(tum_dir) == "tum"
    tum, src = open_rgbd(tum_dir), select(open_rgbd(SEVEN), 0, 40)
    assert len(tum.frames) == 40 and tum.depth_scale == 5000.0 and tum.intrinsics == src.intrinsics
    gt_rows = np.loadtxt(tum_dir / "groundtruth.txt")
    for a, b, row in zip(tum.frames, src.frames, gt_rows):
        assert a.rgb_path.read_bytes() == b.rgb_path.read_bytes()
        d_tum = cv2.imread(str(a.depth_path), cv2.IMREAD_UNCHANGED).astype(np.int64)
        np.testing.assert_array_equal(d_tum, ref_depth_7scenes(b.index).astype(np.int64) * 5)
        assert abs(a.stamp_ns - b.stamp_ns) <= 500  # microsecond stamps
        R = Rotation.from_quat(row[4:8]).as_matrix()  # scipy: [x, y, z, w]
        assert np.abs(R - b.pose[:3, :3]).max() < 1e-7 and np.abs(row[1:4] - b.pose[:3, 3]).max() < 1e-8
        assert np.abs(a.pose - b.pose).max() < 1e-7


def _brute_force_association(rgb: list[float], depth: list[float], max_dt: float) -> list[tuple[int, int]]:
    claims: dict[int, tuple[float, int]] = {}
    for i, r in enumerate(rgb):
        dts = [abs(d - r) for d in depth]
        j = min(range(len(depth)), key=lambda k: (dts[k], k))
        if dts[j] <= max_dt + 1e-12 and (j not in claims or dts[j] < claims[j][0]):
            claims[j] = (dts[j], i)
    return sorted((i, j) for j, (_, i) in claims.items())


@pytest.mark.slow
def test_tum_association_with_jittered_stamps(tum_dir, tmp_path):
    rng = np.random.default_rng(7)
    rgb_lines = [ln.split() for ln in (tum_dir / "rgb.txt").read_text().splitlines() if not ln.startswith("#")]
    dep_lines = [ln.split() for ln in (tum_dir / "depth.txt").read_text().splitlines() if not ln.startswith("#")]
    rgb_t = [float(s) + 1305031102.0 for s, _ in rgb_lines]
    depth_t = [t + rng.uniform(-0.03, 0.03) for t in rgb_t]  # beyond 0.02 s some are rejected
    depth_t = [t for t in depth_t[:-3]]  # fewer depth than colour frames
    for name in ("rgb", "depth", "intrinsics.json"):
        (tmp_path / name).symlink_to(tum_dir / name)
    (tmp_path / "rgb.txt").write_text("".join(f"{t:.6f} {f}\n" for t, (_, f) in zip(rgb_t, rgb_lines)))
    (tmp_path / "depth.txt").write_text("# depth\n" + "".join(f"{t:.6f} {f}\n" for t, (_, f) in
                                                           sorted(zip(depth_t, dep_lines), key=lambda x: x[0])))
    rgb_r = [round(t, 6) for t in rgb_t]
    depth_sorted = sorted(depth_t)
    depth_r = [round(t, 6) for t in depth_sorted]
    expected = _brute_force_association(rgb_r, depth_r, 0.02)
    seq = open_rgbd(tmp_path, max_dt_s=0.02)
    got = [(f.index, depth_r.index(round(f.depth_stamp_ns / 1e9, 6))) for f in seq.frames]
    assert got == expected and 0 < len(expected) < len(rgb_t)
    assert seq.notes and "dropped" in seq.notes[0]
    for f in seq.frames:
        assert abs(f.stamp_ns - f.depth_stamp_ns) <= 20_000_000
    assert len(open_rgbd(tmp_path, max_dt_s=0.04).frames) > len(seq.frames)


def test_tum_groundtruth_interpolation_matches_scipy_slerp():
    rng = np.random.default_rng(3)
    gt_s = np.arange(0, 1.0, 0.01) + 100.0
    rots = Rotation.from_rotvec(np.cumsum(rng.normal(0, 0.02, (len(gt_s), 3)), axis=0))
    trans = np.cumsum(rng.normal(0, 0.01, (len(gt_s), 3)), axis=0)
    poses = np.tile(np.eye(4), (len(gt_s), 1, 1))
    poses[:, :3, :3], poses[:, :3, 3] = rots.as_matrix(), trans
    gt_ns = np.round(gt_s * 1e9).astype(np.int64)
    slerp = Slerp(gt_s, rots)
    for t in rng.uniform(gt_s[0], gt_s[-1], 50):
        T = pose_at(round(t * 1e9), gt_ns, poses, 20_000_000)
        t_ref = round(t * 1e9) / 1e9
        assert np.abs(T[:3, :3] - slerp([t_ref]).as_matrix()[0]).max() < 1e-9
        ref_t = [np.interp(t_ref, gt_s, trans[:, k]) for k in range(3)]
        assert np.abs(T[:3, 3] - ref_t).max() < 1e-9
    assert pose_at(gt_ns[0] - 1, gt_ns, poses, 20_000_000) is None
    gap = np.delete(gt_ns, range(40, 50)), np.delete(poses, range(40, 50), axis=0)
    assert pose_at(gt_ns[45], *gap, 20_000_000) is None  # the samples around it are 55 ms apart


# --- bad input ----------------------------------------------------------------------------------

def _mini_7scenes(tmp_path: Path, n: int = 2) -> Path:
    for k in range(n):
        for kind in ("color.jpg", "depth.png", "pose.txt"):
            shutil.copy(SEVEN / f"frame-{k:06d}.{kind}", tmp_path)
    shutil.copy(SEVEN / "camera-intrinsics.txt", tmp_path)
    return tmp_path


def test_bad_folders_raise_dataset_errors_naming_the_file(tmp_path):
    with pytest.raises(DatasetError, match="no such dataset folder"):
        open_rgbd(tmp_path / "missing")
    with pytest.raises(DatasetError, match=r"unknown dataset format.*rgb\.txt.*frame-NNNNNN.*depth/"):
        open_rgbd(tmp_path)
    (tmp_path / "s").mkdir()
    d = _mini_7scenes(tmp_path / "s", 2)
    (d / "frame-000001.color.jpg").write_bytes(b"not a jpeg")
    with pytest.raises(DatasetError, match="frame-000001.color.jpg: cannot decode"):
        list(rgbd_groups(open_rgbd(d)))
    (d / "frame-000001.pose.txt").write_text("nan 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n")
    with pytest.raises(DatasetError, match=r"frame-000001.pose.txt:1: NaN"):
        open_rgbd(d)
    (d / "frame-000001.pose.txt").unlink()
    with pytest.raises(DatasetError, match=r"frame-000001.pose.txt is missing"):
        open_rgbd(d)
    (d / "frame-000001.depth.png").unlink()
    with pytest.raises(DatasetError, match=r"frame-000001.depth.png is missing"):
        open_rgbd(d)


@pytest.mark.slow
def test_bad_tum_and_redwood_files(tum_dir, tmp_path):
    t = tmp_path / "t"
    shutil.copytree(tum_dir, t)
    lines = (t / "rgb.txt").read_text().splitlines()
    lines[4] = "0.066666"  # no filename on line 5
    (t / "rgb.txt").write_text("\n".join(lines))
    with pytest.raises(DatasetError, match=r"rgb\.txt:5: expected 'timestamp filename'"):
        open_rgbd(t)
    shutil.copy(tum_dir / "rgb.txt", t / "rgb.txt")
    (t / "groundtruth.txt").write_text("0.0 1 2 3 0 0 0 1\n0.1 1 2 x 0 0 0 1\n")
    with pytest.raises(DatasetError, match=r"groundtruth\.txt:2: unparsable"):
        open_rgbd(t)
    (t / "groundtruth.txt").unlink()
    (t / "intrinsics.json").unlink()
    with pytest.raises(DatasetError, match="pass fx, fy, cx, cy"):
        open_rgbd(t)
    seq = open_rgbd(t, intrinsics=IntrinsicsOverride(500.0, 501.0, 320.0, 240.0))
    assert seq.intrinsics.fy == 501.0 and not seq.has_poses
    r = tmp_path / "r"
    (r / "image").mkdir(parents=True)
    (r / "depth").mkdir()
    for k in range(3):
        shutil.copy(ICL / "image" / f"{k:05d}.jpg", r / "image")
    for k in range(2):
        shutil.copy(ICL / "depth" / f"{k:05d}.png", r / "depth")
    with pytest.raises(DatasetError, match=r"image/ has 3 image\(s\) and depth/ has 2"):
        open_rgbd(r)


# --- CLI ----------------------------------------------------------------------------------------

def run_cli(argv: list[str]) -> int:
    parser = argparse.ArgumentParser()
    add_dataset_parser(parser.add_subparsers(dest="command", required=True))
    ns = parser.parse_args(argv)
    return ns.func(ns)


def test_cli_info_and_convert(tmp_path, capsys):
    assert run_cli(["dataset", "info", str(SEVEN), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["format"] == "7scenes" and info["frames"] == 400 and info["has_ground_truth"]
    assert (info["fx"], info["fy"], info["rate_hz"]) == (585.0, 585.0, 30.0)
    dst = tmp_path / "tum"
    assert run_cli(["dataset", "convert", str(ICL), str(dst), "--format", "tum", "--max-frames", "6"]) == 0
    assert "wrote 6 frame(s), 5 pose(s)" in capsys.readouterr().out
    gt = np.loadtxt(dst / "groundtruth.txt")
    assert gt.shape == (5, 8)
    assert run_cli(["dataset", "info", str(dst)]) == 0
    out = capsys.readouterr().out
    assert "format:        tum" in out and "6 (0.17 s at 30 Hz)" in out
    assert run_cli(["dataset", "convert", str(ICL), str(dst)]) == 2
    assert "not empty" in capsys.readouterr().err
    assert run_cli(["dataset", "info", str(tmp_path / "nope")]) == 2


# --- the player node ----------------------------------------------------------------------------

class QuiescenceLog(RecordingContext):
    def __init__(self, *a, **k):
        super().__init__(*a, **k)
        self.events: list[str] = []

    def wait_quiescent(self) -> bool:
        self.events.append("quiesce")
        return True

    def publish(self, output, msg):
        super().publish(output, msg)
        self.events.append(output)


def test_player_lockstep_waits_before_each_frame_and_stops():
    ctx = play({"path": str(SEVEN), "rate": 0, "start": 10, "max_frames": 3},
               QuiescenceLog("cam", RgbdDatasetPlayer))
    frame = ["quiesce", "rgbd/camera_info", "rgb", "depth", "gt/rgbd_pose"]
    assert ctx.events == frame * 3 and ctx.stopped
    assert [m.header.stamp_ns for m in ctx.outputs("rgb")] == [round(k * 1e9 / 30) for k in (10, 11, 12)]


def test_player_recorded_timing_at_30hz():
    ctx = play({"path": str(SEVEN), "max_frames": 10, "rate": 1.0}, RecordingContext("cam", RgbdDatasetPlayer))
    t = np.array(ctx.times("rgb")) - ctx.times("rgb")[0]  # frame 0 goes out when the schedule starts
    expected = np.arange(10) / 30
    assert len(t) == 10 and ctx.stopped
    assert np.all(t >= expected - 0.001), t  # never early (lateness only from CPU load)
    assert t[-1] < expected[-1] + 0.3, t


def test_player_loop_keeps_stamps_increasing():
    ctx = play_until({"path": str(SEVEN), "rate": 0, "max_frames": 3, "loop": True}, 8)
    stamps = [m.header.stamp_ns for m in ctx.outputs("rgb")]
    assert not ctx.stopped and np.all(np.diff(stamps) > 0)
    assert abs(stamps[3] - stamps[2] - 1e9 / 30) < 2  # the next pass follows one frame interval later
    np.testing.assert_array_equal(ctx.outputs("rgb")[3].data, ctx.outputs("rgb")[0].data)


def test_player_preload_plays_the_same_messages_from_memory_across_loops():
    params = {"path": str(SEVEN), "rate": 0, "max_frames": 3, "loop": True}
    outs = [play_until({**params, "preload": preload}, 7) for preload in (False, True)]
    for name in ("rgb", "depth", "gt/rgbd_pose", "rgbd/camera_info"):
        a, b = outs[0].outputs(name)[:7], outs[1].outputs(name)[:7]
        assert [m.header.stamp_ns for m in a] == [m.header.stamp_ns for m in b]
    for m, n in zip(outs[0].outputs("depth")[:7], outs[1].outputs("depth")[:7]):
        np.testing.assert_array_equal(m.data, n.data)


@pytest.mark.slow
def test_player_wall_stamps_follow_the_node_clock(tum_dir, tmp_path):
    # a TUM copy whose depth is 7 ms after the colour: the offset must survive re-stamping
    for name in ("rgb", "depth", "intrinsics.json", "rgb.txt", "groundtruth.txt"):
        (tmp_path / name).symlink_to(tum_dir / name)
    rows = [ln.split() for ln in (tum_dir / "depth.txt").read_text().splitlines() if not ln.startswith("#")]
    (tmp_path / "depth.txt").write_text("".join(f"{float(s) + 0.007:.6f} {f}\n" for s, f in rows))
    ctx = RecordingContext("cam", RgbdDatasetPlayer, clock_ns=1_700_000_000_000_000_000)
    ctx = play({"path": str(tmp_path), "rate": 0, "max_frames": 2, "stamps": "wall"}, ctx)
    for rgb, depth, info in zip(ctx.outputs("rgb"), ctx.outputs("depth"), ctx.outputs("rgbd/camera_info")):
        assert rgb.header.stamp_ns == info.header.stamp_ns == ctx.clock_ns
        assert depth.header.stamp_ns - rgb.header.stamp_ns == 7_000_000
    assert len(ctx.outputs("gt/rgbd_pose")) == 2
