"""``probeless calibrate fisheye|extrinsics|response|vignetting``: parsers and commands (response and vignetting:
probeless.cameras.radiometry_cli).

Errors are raised as CalibrationError (or BagError) and printed by probeless.cli, which exits 2.
"""

from __future__ import annotations

import argparse
import glob
import re
from pathlib import Path
from typing import Any

import numpy as np

from probeless.errors import CalibrationError
from probeless.progress import progress as progress_bar


def add_calibrate_parser(sub: Any) -> argparse.ArgumentParser:
    """Add ``calibrate`` (with ``fisheye`` and ``extrinsics``) to the subparsers of ``probeless``."""
    from probeless.cameras.calibrate import FISHEYE_MODELS

    p = sub.add_parser("calibrate", help="calibrate the fisheye (chessboard), the RGB-D-to-fisheye transform "
                                            "and the camera's radiometry (response, vignetting, white balance)")
    cs = p.add_subparsers(dest="calibrate_command", required=True)
    f = cs.add_parser("fisheye", help="fisheye intrinsics from chessboard images")
    f.add_argument("--images", required=True, metavar="GLOB", help="quoted glob of the images, e.g. 'dir/*.jpg'")
    f.add_argument("--board", required=True, metavar="COLSxROWS",
                   help="squares between the inner corners, as OCamCalib/Bouguet count them "
                        "(inner corners = squares + 1), e.g. 5x7 for a 6x8-corner board")
    f.add_argument("--square", required=True, type=float, metavar="M", help="side of one square [m]")
    f.add_argument("--model", choices=FISHEYE_MODELS, default="omnidir", help="default: omnidir")
    f.add_argument("-o", "--output", required=True, metavar="OUT.yaml")
    f.add_argument("--overlay-dir", metavar="DIR", help="detected vs reprojected corners per image "
                                                        "(default: <OUT stem>_overlays next to OUT)")
    f.add_argument("--no-overlays", action="store_true", help="write no overlay images")
    f.add_argument("--frame-id", default="fisheye", help="frame id of the calibration (default: fisheye)")
    f.add_argument("--force", action="store_true", help="overwrite OUT")
    f.add_argument("--no-progress", action="store_true", help="no progress bar")
    f.set_defaults(func=cmd_fisheye)

    e = cs.add_parser("extrinsics", help="fisheye_from_rgbd from point matches in a rig recording (LM)")
    e.add_argument("--bag", required=True, metavar="RIG.mcap")
    e.add_argument("--node", default="rig", help="rig node id: default topics are NODE/rgb, ... (default: rig)")
    for name, output in (("rgb", "rgb"), ("depth", "depth"), ("fisheye", "fisheye"),
                         ("rgbd-info", "rgbd/camera_info"), ("fisheye-info", "fisheye/camera_info")):
        e.add_argument(f"--{name}-topic", metavar="TOPIC", help=f"default: NODE/{output}")
    e.add_argument("--fisheye-calib", metavar="FISHEYE.yaml", help="fisheye calibration file (instead of the "
                                                                   "recorded fisheye camera_info)")
    e.add_argument("--pairs", type=int, default=10, help="frame pairs to pool matches over (default: 10)")
    e.add_argument("--max-dt", type=float, default=0.02, metavar="S",
                   help="largest |fisheye - RGB-D| stamp difference of a pair [s] (default: 0.02)")
    e.add_argument("--init-rpy", type=float, nargs=3, default=[-90.0, 0.0, 0.0], metavar=("R", "P", "Y"),
                   help="initial guess rotation [deg] (default: -90 0 0, the fisheye looking up)")
    e.add_argument("--init-translation", type=float, nargs=3, default=[0.0, 0.0, 0.0], metavar=("X", "Y", "Z"),
                   help="initial guess translation [m] (default: 0 0 0)")
    e.add_argument("--no-motion-compensation", action="store_true",
                   help="pool the matches as if the rig did not move between the RGB-D and fisheye stamps "
                        "(default: move the RGB-D points to the fisheye stamp by the RGB-D camera's motion, "
                        "estimated against the neighbouring RGB-D frame)")
    e.add_argument("--max-gap", type=float, default=0.1, metavar="S",
                   help="largest gap to the neighbouring RGB-D frame for motion compensation [s] (default: 0.1)")
    e.add_argument("--min-matches", type=int, default=30, help="fewest pooled matches to solve from (default: 30)")
    e.add_argument("--outlier-px", type=float, default=3.0, help="smallest outlier threshold [px] (default: 3)")
    e.add_argument("-o", "--output", required=True, metavar="OUT.yaml")
    e.add_argument("--force", action="store_true", help="overwrite OUT")
    e.add_argument("--no-progress", action="store_true", help="no progress bar")
    e.set_defaults(func=cmd_extrinsics)

    from probeless.cameras.radiometry_cli import add_radiometry_parsers

    add_radiometry_parsers(cs)
    return p


def _check_output(path: str, force: bool) -> Path:
    out = Path(path)
    if out.exists() and not force:
        raise CalibrationError(f"{out} already exists; pass --force to overwrite it")
    return out


def _natural_key(path: str) -> list:
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", path)]


def _fmt(values) -> str:
    return "[" + ", ".join(f"{v:.6g}" for v in np.ravel(values)) + "]"


def cmd_fisheye(ns: argparse.Namespace) -> int:
    """Detect the board in every image, calibrate, print the RMS, write the YAML and the overlays."""
    import cv2

    from probeless.cameras.calibrate import calibrate_fisheye
    from probeless.cameras.chessboard import detect_images, draw_overlay, parse_board
    from probeless.cameras.io import save_calibration

    out = _check_output(ns.output, ns.force)
    inner = parse_board(ns.board)
    if not ns.square > 0:
        raise CalibrationError(f"--square must be a positive length in metres, got {ns.square}")
    paths = sorted(glob.glob(ns.images), key=_natural_key)
    if not paths:
        raise CalibrationError(f"--images {ns.images!r} matches no file")
    with progress_bar(len(paths), "detecting corners", not ns.no_progress, transient=True) as tick:
        detections = detect_images(paths, inner, on_image=lambda d: tick())
    result = calibrate_fisheye(detections, ns.square, ns.model, ns.frame_id)
    for d in detections:
        if d.name in result.per_image_rms_px:
            print(f"  {d.name}: {len(d.corners)} corners, RMS {result.per_image_rms_px[d.name]:.3f} px")
    for name, why in result.skipped.items():
        print(f"  skipped {name}: {why}")
    for note in result.notes:
        print(f"  note: {note}")
    info = result.info
    print(f"{info.model}: {len(result.per_image_rms_px)} of {len(paths)} image(s) used, RMS {result.rms_px:.3f} px "
          f"(OpenCV reports {result.opencv_rms_px:.3f} px)")
    print(f"  K = {_fmt(info.K)}\n  D = {_fmt(info.D)}")
    if info.model == "omnidir":
        print(f"  xi = {info.xi:.6g}")
    extra = {"rms_px": result.rms_px, "opencv_rms_px": result.opencv_rms_px,
             "per_image_rms_px": dict(result.per_image_rms_px), "images_used": list(result.per_image_rms_px),
             "images_skipped": dict(result.skipped), "board_squares": ns.board, "square_m": float(ns.square),
             "notes": list(result.notes)}
    save_calibration(out, info, extra)
    where = ""
    if not ns.no_overlays:
        odir = Path(ns.overlay_dir) if ns.overlay_dir else out.with_name(out.stem + "_overlays")
        odir.mkdir(parents=True, exist_ok=True)
        for path, d in zip(paths, detections):
            if d.name in result.reprojected:
                label = f"{d.name}: RMS {result.per_image_rms_px[d.name]:.2f} px"
                img = draw_overlay(cv2.imread(path, cv2.IMREAD_COLOR), d.corners, result.reprojected[d.name], label)
                cv2.imwrite(str(odir / (Path(d.name).with_suffix("").as_posix().replace("/", "_") + ".png")), img)
        where = f", overlays in {odir}/"
    print(f"wrote {out}{where}")
    return 0


def cmd_extrinsics(ns: argparse.Namespace) -> int:
    """Match the RGB-D and fisheye frames of a recording, solve fisheye_from_rgbd, write the YAML."""
    from probeless.cameras import model_from_info
    from probeless.cameras.extrinsics import from_rpy, save_extrinsics, solve_fisheye_from_rgbd, to_rpy
    from probeless.cameras.io import load_calibration
    from probeless.cameras.rig_bag import RigRecording, RigTopics

    out = _check_output(ns.output, ns.force)
    if ns.pairs < 1 or not ns.max_dt >= 0:
        raise CalibrationError(f"--pairs must be >= 1 and --max-dt >= 0, got {ns.pairs} and {ns.max_dt}")
    d = RigTopics.of_node(ns.node)
    topics = RigTopics(ns.rgb_topic or d.rgb, ns.depth_topic or d.depth, ns.fisheye_topic or d.fisheye,
                       ns.rgbd_info_topic or d.rgbd_info, ns.fisheye_info_topic or d.fisheye_info)
    rec = RigRecording(ns.bag, topics)
    rgbd_info = rec.camera_info(topics.rgbd_info)
    if rgbd_info.model != "pinhole" or np.any(rgbd_info.D):
        raise CalibrationError(f"{ns.bag}: topic {topics.rgbd_info!r}: the RGB-D camera must be an undistorted "
                               f"pinhole, got model {rgbd_info.model!r} with D = {_fmt(rgbd_info.D)}")
    fisheye_info = (load_calibration(ns.fisheye_calib) if ns.fisheye_calib
                    else rec.camera_info(topics.fisheye_info))
    init = from_rpy(ns.init_translation, ns.init_rpy)
    compensate = not ns.no_motion_compensation
    pairs = rec.pairs(ns.max_dt, ns.pairs, ns.max_gap if compensate else None)
    points, pixels, used = _pool_matches(pairs, rgbd_info, fisheye_info, init, compensate, not ns.no_progress)
    if len(points) < ns.min_matches:
        raise CalibrationError(f"{ns.bag}: {len(points)} matches from {used} of {len(pairs)} pair(s), need at least "
                               f"{ns.min_matches}: the region both cameras see needs texture (SIFT features), "
                               f"or try more --pairs")
    T, report = solve_fisheye_from_rgbd(points, pixels, model_from_info(fisheye_info), init,
                                        outlier_px=ns.outlier_px)
    translation, rpy = to_rpy(T)
    print(f"fisheye_from_rgbd: {report.inliers} of {report.matches} matches from {used} pair(s), "
          f"RMS {report.rms_px:.3f} px (median {report.median_px:.3f} px, {report.rounds} round(s))")
    print(f"  translation: {_fmt(translation)} m\n  rpy_deg: {_fmt(rpy)}")
    save_extrinsics(out, T, report, {"source": {
        "bag": str(ns.bag), "pairs": used, "max_dt_s": float(ns.max_dt), "motion_compensation": compensate,
        "fisheye_calibration": str(ns.fisheye_calib) if ns.fisheye_calib else topics.fisheye_info,
        "init": {"translation": [float(v) for v in ns.init_translation],
                 "rpy_deg": [float(v) for v in ns.init_rpy]}}})
    print(f"wrote {out}")
    return 0


def _pool_matches(pairs, rgbd_info, fisheye_info, init, compensate: bool, progress: bool):
    """(N, 3) points and (N, 2) fisheye pixels pooled over the pairs, and how many pairs gave matches;
    a pair whose matching or motion estimate fails is reported and skipped."""
    from scipy.spatial.transform import Rotation

    from probeless.cameras import model_from_info
    from probeless.cameras.rig_bag import pair_matches

    fisheye = model_from_info(fisheye_info)
    points, pixels, used = [np.zeros((0, 3))], [np.zeros((0, 2))], 0
    with progress_bar(len(pairs), "matching", progress, transient=True) as tick:
        for pair in pairs:
            _check_sizes(pair, rgbd_info, fisheye_info)
            where = f"  pair fisheye {pair.fisheye_stamp_ns} / rgbd {pair.rgb_stamp_ns} (dt {pair.dt_s * 1e3:+.1f} ms)"
            try:
                m = pair_matches(pair, rgbd_info.K, fisheye, init, compensate)
            except CalibrationError as exc:
                print(f"{where}: skipped: {exc}")
                continue
            finally:
                tick()
            points.append(m.points_rgbd)
            pixels.append(m.pixels_fisheye)
            used += 1
            moved = "" if m.motion is None else (
                f", rig moved {np.linalg.norm(m.motion[:3, 3]) * 1e3:.1f} mm "
                f"{Rotation.from_matrix(m.motion[:3, :3]).magnitude() * 180 / np.pi:.2f} deg")
            print(f"{where}: {len(m.points_rgbd)} matches ({m.candidates} before RANSAC){moved}")
    return np.concatenate(points), np.concatenate(pixels), used


def _check_sizes(pair, rgbd_info, fisheye_info) -> None:
    for what, img, info, stamp in (("rgb", pair.rgb, rgbd_info, pair.rgb_stamp_ns),
                                   ("depth", pair.depth_m, rgbd_info, pair.rgb_stamp_ns),
                                   ("fisheye", pair.fisheye, fisheye_info, pair.fisheye_stamp_ns)):
        if img.shape[:2] != (info.height, info.width):
            raise CalibrationError(f"{what} frame at {stamp} is {img.shape[1]}x{img.shape[0]}, "
                                   f"its camera info says {info.width}x{info.height}")
