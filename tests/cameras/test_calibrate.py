"""Chessboard calibration on the real fisheye images of ../shared/data/fisheye/chessboards_fisheye1/
(15 images, 1032x778; the board is 5x7 in OCamCalib's count, i.e. 6x8 inner corners, of 32.5 mm), and the
``probeless calibrate fisheye`` command."""

from __future__ import annotations

import argparse
import glob
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
from locations import SHARED_DATA

from probeless.cameras import model_from_info
from probeless.cameras.calibrate import calibrate_fisheye, calibrate_kannala_brandt
from probeless.cameras.calibrate_cli import add_calibrate_parser
from probeless.cameras.chessboard import BoardDetection, board_points, detect_images, parse_board
from probeless.cameras.io import load_calibration, load_calibration_extra
from probeless.errors import CalibrationError

DATA = SHARED_DATA / "fisheye" / "chessboards_fisheye1"
SQUARE = 0.0325
PATHS = sorted(glob.glob(str(DATA / "*.jpg")))


@pytest.fixture(scope="module")
def detections():
    assert len(PATHS) == 15, f"expected the 15 chessboard images in {DATA}"
    return detect_images(PATHS, parse_board("5x7"))


def test_parse_board():
    assert parse_board("5x7") == (6, 8)
    assert parse_board("7X9") == (8, 10)
    for bad in ("5by7", "0x7", "7", ""):
        with pytest.raises(CalibrationError, match="--board"):
            parse_board(bad)


@pytest.mark.slow
def test_board_found_in_every_image(detections):
    assert [d.reason for d in detections] == [""] * 15
    for d in detections:
        assert d.corners.shape == (48, 2) and sorted(d.grid) == [6, 8] and d.size == (1032, 778)
        assert np.all((d.corners > 0) & (d.corners < [1032, 778]))
        # neighbours along a row are one square apart on the image, not across the board
        steps = np.linalg.norm(np.diff(d.corners.reshape(d.grid[1], d.grid[0], 2), axis=1), axis=2)
        assert steps.max() < 4 * np.median(steps)


def model_rms(result, detections):
    """RMS of the detected corners reprojected by our camera model (not OpenCV's) with the board poses."""
    model = model_from_info(result.info)
    by_name = {d.name: d for d in detections}
    errors = []
    for name, (rvec, tvec) in result.poses.items():
        d = by_name[name]
        px, valid = model.project(board_points(d.grid, SQUARE) @ cv2.Rodrigues(rvec)[0].T + tvec)
        assert valid.all()
        np.testing.assert_allclose(px, result.reprojected[name], atol=1e-6)
        errors.append(px - d.corners)
    e = np.concatenate(errors)
    return float(np.sqrt(np.mean(np.sum(e * e, axis=1))))


@pytest.mark.slow
def test_omnidir_calibration_rms_below_1px(detections):
    result = calibrate_fisheye(detections, SQUARE, "omnidir")
    assert result.rms_px < 1.0
    assert len(result.per_image_rms_px) >= 13 and max(result.per_image_rms_px.values()) < 1.0
    assert result.rms_px == pytest.approx(result.opencv_rms_px, rel=0.02)
    info = result.info
    assert info.model == "omnidir" and (info.width, info.height) == (1032, 778)
    assert abs(info.K[0, 2] - 516) < 60 and abs(info.K[1, 2] - 389) < 60
    assert info.K[0, 0] == pytest.approx(info.K[1, 1], rel=0.01) and info.xi > 0.5
    assert model_rms(result, detections) < 1.0


@pytest.mark.slow
def test_kannala_brandt_calibration_rms_below_1px(detections):
    result = calibrate_fisheye(detections, SQUARE, "kannala_brandt")
    omni = calibrate_fisheye(detections, SQUARE, "omnidir").info
    assert result.rms_px < 1.0 and len(result.per_image_rms_px) >= 13
    assert result.rms_px == pytest.approx(result.opencv_rms_px, rel=0.02)
    K = result.info.K
    # both models describe one lens: same principal point, same focal slope at the centre
    assert abs(K[0, 2] - omni.K[0, 2]) < 5 and abs(K[1, 2] - omni.K[1, 2]) < 5
    assert K[0, 0] == pytest.approx(omni.K[0, 0] / (1 + omni.xi), rel=0.03)
    assert model_rms(result, detections) < 1.0


@pytest.mark.slow
def test_kannala_brandt_drops_an_ill_conditioned_view(detections, monkeypatch):
    real, calls = cv2.fisheye.calibrate, []

    def fake(obj, img, *args, **kwargs):
        calls.append(len(obj))
        if len(calls) == 1:
            raise cv2.error("CALIB_CHECK_COND - Ill-conditioned matrix for input array 3 in CalibrateExtrinsics")
        return real(obj, img, *args, **kwargs)

    monkeypatch.setattr(cv2.fisheye, "calibrate", fake)
    result = calibrate_fisheye(detections, SQUARE, "kannala_brandt")
    assert calls == [15, 14]
    assert "ill-conditioned" in result.skipped[detections[3].name]
    assert detections[3].name not in result.per_image_rms_px and len(result.per_image_rms_px) == 14
    assert result.rms_px < 1.0


@pytest.mark.slow
def test_kannala_brandt_gives_up_with_too_few_views(detections):
    obj = [board_points(d.grid, SQUARE) for d in detections[:3]]
    bad = [np.tile([[516.0, 389.0]], (48, 1)) + np.random.default_rng(k).normal(0, 0.01, (48, 2)) for k in range(3)]
    with pytest.raises(CalibrationError, match="cv2.fisheye.calibrate"):
        calibrate_kannala_brandt(obj, bad, (1032, 778), np.array([[337.0, 0, 516], [0, 337, 389], [0, 0, 1]]))


@pytest.mark.slow
def test_a_wrong_detection_is_dropped_as_an_outlier_view(detections):
    good = detections[:6]
    rng = np.random.default_rng(0)
    wrong = BoardDetection("wrong.jpg", good[0].corners + rng.normal(0, 15, (48, 2)), good[0].grid, size=(1032, 778))
    result = calibrate_fisheye([*good, wrong], SQUARE, "omnidir")
    assert "outlier" in result.skipped["wrong.jpg"] or "rejected" in result.skipped["wrong.jpg"]
    assert set(result.per_image_rms_px) == {d.name for d in good} and result.rms_px < 1.0


@pytest.mark.slow
def test_wrong_board_size_is_reported():
    dets = detect_images(PATHS[:4], parse_board("3x5"))   # smaller than the real 5x7 board
    with pytest.raises(CalibrationError, match="try --board 5x7"):
        calibrate_fisheye(dets, SQUARE, "omnidir")


# -- the command -------------------------------------------------------------------------------

def cli(argv):
    p = argparse.ArgumentParser(prog="probeless")
    add_calibrate_parser(p.add_subparsers(dest="command", required=True))
    ns = p.parse_args(argv)
    return ns.func(ns)


def image_dir(tmp_path, n_real, blank=True):
    d = tmp_path / "images"
    d.mkdir()
    for p in PATHS[:n_real]:
        shutil.copy(p, d)
    if blank:
        cv2.imwrite(str(d / "blank.jpg"), np.full((778, 1032, 3), 200, np.uint8))
    return d


@pytest.mark.slow
def test_fisheye_command(tmp_path, capsys):
    d = image_dir(tmp_path, 5)
    out = tmp_path / "fisheye.yaml"
    args = ["calibrate", "fisheye", "--images", str(d / "*.jpg"), "--board", "5x7", "--square", str(SQUARE),
            "--model", "omnidir", "-o", str(out), "--no-progress"]
    assert cli(args) == 0
    text = capsys.readouterr().out
    assert "skipped blank.jpg: board not found" in text and "RMS" in text
    info = load_calibration(out)
    extra = load_calibration_extra(out)
    assert info.model == "omnidir" and (info.width, info.height) == (1032, 778)
    assert extra["rms_px"] < 1.0 and extra["images_skipped"] == {"blank.jpg": "board not found"}
    assert sorted(extra["images_used"]) == sorted(Path(p).name for p in PATHS[:5])
    overlays = sorted((tmp_path / "fisheye_overlays").glob("*.png"))
    assert [p.stem for p in overlays] == sorted(Path(p).stem for p in PATHS[:5])
    # detected corners are circled in green, reprojected ones crossed in red (the photo itself is grey)
    dets = detect_images([PATHS[0]], parse_board("5x7"))
    img = cv2.imread(str(tmp_path / "fisheye_overlays" / (Path(PATHS[0]).stem + ".png"))).astype(int)
    assert img.shape == (778, 1032, 3)
    b, g, r = img[..., 0], img[..., 1], img[..., 2]
    for mask in (g - np.maximum(r, b) > 80, r - np.maximum(g, b) > 80):
        mask[:52, :420] = False   # the label
        ys, xs = np.nonzero(mask)
        assert all(np.min(np.hypot(xs - u, ys - v)) < 8 for u, v in dets[0].corners)
        near = np.min(np.hypot(xs[:, None] - dets[0].corners[:, 0], ys[:, None] - dets[0].corners[:, 1]), axis=1)
        assert np.all(near < 10)   # nothing drawn elsewhere
    # -o exists: refused without --force, unchanged
    before = out.read_text()
    with pytest.raises(CalibrationError, match="already exists; pass --force"):
        cli(args)
    assert out.read_text() == before


@pytest.mark.slow
def test_fisheye_command_errors(tmp_path):
    base = ["calibrate", "fisheye", "--board", "5x7", "--square", str(SQUARE), "--no-progress"]
    with pytest.raises(CalibrationError, match="matches no file"):
        cli(base + ["--images", str(tmp_path / "nothing" / "*.jpg"), "-o", str(tmp_path / "a.yaml")])
    d = image_dir(tmp_path, 2)
    with pytest.raises(CalibrationError, match="board found in 2 of 3 image"):
        cli(base + ["--images", str(d / "*.jpg"), "-o", str(tmp_path / "b.yaml")])
    assert not (tmp_path / "b.yaml").exists()
    with pytest.raises(CalibrationError, match="--square"):
        cli(["calibrate", "fisheye", "--board", "5x7", "--square", "0", "--images", str(d / "*.jpg"),
             "-o", str(tmp_path / "c.yaml")])
