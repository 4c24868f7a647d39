"""build_lut calls OpenCV's map functions where OpenCV has the same pair of models, and its table equals the one
our own models give (float64 positions, then float32) to within TOL_PX, with the same pixels marked outside."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from probeless.cameras import KannalaBrandtModel, OcamModel, OmnidirModel, PinholeModel
from probeless.cameras.base import camera_matrix
from probeless.cameras.undistort import OUTSIDE, LongLat, build_lut, maps_from_positions, sample_positions
from probeless.cameras.undistort_cv2 import opencv_lut

TOL_PX = 1e-3  # float32 tables; both paths evaluate the same model in float64
MEI = OmnidirModel(320, 300, camera_matrix(105.0, 106.0, 161.2, 149.3), 1.1, [-0.25, 0.07, 2e-4, -1e-4])
KB = KannalaBrandtModel(320, 300, camera_matrix(80.0, 81.0, 159.1, 151.7), [0.05, -0.01, 0.002, -3e-4])
PLUMB = PinholeModel(320, 240, camera_matrix(250.0, 252.0, 160.5, 121.0), [-0.28, 0.09, 1e-3, -5e-4, -0.01])
RATIONAL = PinholeModel(320, 240, camera_matrix(250.0, 252.0, 160.5, 121.0),
                        [-0.28, 0.09, 1e-3, -5e-4, -0.01, 0.02, 0.001, 5e-4])
STEREO = OmnidirModel.from_fov(256, 240, 185.0, xi=1.0)
PINHOLE = PinholeModel(256, 200, camera_matrix(120.0, 121.0, 127.5, 99.5))

PAIRS = {
    "mei->omnidir xi=1": (MEI, STEREO),
    "mei->pinhole": (MEI, PINHOLE),
    "mei xi=0.8->omnidir xi=1": (OmnidirModel(320, 300, MEI.K, 0.8, MEI.D), STEREO),
    "mei->longlat 180x180": (MEI, LongLat(200, 100, 180.0, 180.0)),
    "mei->longlat 200x150": (MEI, LongLat(240, 120, 200.0, 150.0)),
    "kannala_brandt->pinhole": (KB, PINHOLE),
    "plumb_bob->pinhole": (PLUMB, PINHOLE),
    "rational->pinhole": (RATIONAL, PINHOLE),
}


def own_table(src, dst):
    return maps_from_positions(sample_positions(src, dst))


@pytest.mark.parametrize("name", sorted(PAIRS))
def test_opencv_table_equals_our_models(name):
    src, dst = PAIRS[name]
    got, want = opencv_lut(src, dst), own_table(src, dst)
    assert got is not None, f"{name}: OpenCV has this pair"
    assert got[0].dtype == np.float32 and got[0].shape == (dst.height, dst.width) and got[0].flags.c_contiguous
    out_got, out_want = got[0] <= OUTSIDE, want[0] <= OUTSIDE
    np.testing.assert_array_equal(out_got, out_want)  # the same pixels see no source
    assert np.array_equal(got[1] <= OUTSIDE, out_want)
    inside = ~out_want
    assert inside.mean() > 0.3
    assert np.hypot(got[0] - want[0], got[1] - want[1])[inside].max() < TOL_PX


def test_table_equals_a_single_plain_opencv_call():
    """The row bands on threads give OpenCV's own table (one call, as a user writes it) where it is on the image."""
    dst = PINHOLE
    plain = cv2.initUndistortRectifyMap(PLUMB.K, PLUMB.D, None, dst.K, (dst.width, dst.height), cv2.CV_32FC1)
    for threads in (1, 3):
        got = opencv_lut(PLUMB, dst, threads=threads)
        inside = got[0] > OUTSIDE
        assert inside.mean() > 0.4
        assert np.abs(got[0] - plain[0])[inside].max() < 1e-4 and np.abs(got[1] - plain[1])[inside].max() < 1e-4


def test_build_lut_calls_opencv_where_the_models_allow(monkeypatch):
    calls = []
    real = cv2.omnidir.initUndistortRectifyMap

    def spy(*args, **kwargs):
        calls.append(args[6:8])
        return real(*args, **kwargs)

    monkeypatch.setattr(cv2.omnidir, "initUndistortRectifyMap", spy)
    build_lut(MEI, STEREO)
    assert calls and all(c[1] == cv2.omnidir.RECTIFY_STEREOGRAPHIC for c in calls)
    calls.clear()
    own = build_lut(MEI, STEREO, use_opencv=False)
    assert not calls
    assert np.hypot(*(a - b for a, b in zip(build_lut(MEI, STEREO), own)))[own[0] > OUTSIDE].max() < TOL_PX


def test_own_path_where_opencv_has_no_equivalent():
    ocam_like = OcamModel(200, 200, np.array([-60.0, 0.0, 2e-3]), np.array([50.0, 20.0]), (99.5, 99.5),
                          (1.0, 0.0, 0.0))
    assert opencv_lut(ocam_like, STEREO) is None                       # OCamCalib: not in OpenCV
    assert opencv_lut(KB, STEREO) is None                              # Kannala-Brandt into omnidir
    assert opencv_lut(KB, LongLat(64, 32, 180.0, 180.0)) is None       # Kannala-Brandt into longlat
    assert opencv_lut(MEI, LongLat(64, 32)) is None                    # the full sphere: behind Mei's domain
    assert opencv_lut(MEI, OmnidirModel.from_fov(64, 64, 185.0, xi=0.8)) is None  # destination xi != 1
    skewed = OmnidirModel(320, 300, MEI.K + np.array([[0, 3.0, 0], [0, 0, 0], [0, 0, 0]]), MEI.xi, MEI.D)
    assert opencv_lut(skewed, STEREO) is None
    assert opencv_lut(PLUMB, PinholeModel(64, 64, PINHOLE.K / 4 + np.diag([0, 0, 0.75]), [0.1, 0, 0, 0])) is None


def test_source_domain_smaller_than_the_destination_falls_back():
    """Mei with xi = 0.3 sees only rays with z > -0.3; the 185-degree square destination reaches z = -0.37 in
    its corners: OpenCV would map those corners somewhere, our models say no source, and build_lut says so."""
    narrow = OmnidirModel(320, 300, MEI.K, 0.3, MEI.D)
    assert opencv_lut(narrow, STEREO) is None
    table, want = build_lut(narrow, STEREO), own_table(narrow, STEREO)
    np.testing.assert_array_equal(table[0], want[0])
    # strong barrel distortion: theta_d stops increasing before 90 degrees, a wide pinhole reaches past it
    short = KannalaBrandtModel(320, 300, KB.K, [-0.3, 0.0, 0.0, 0.0])
    assert short.theta_max < np.pi / 2
    wide = PinholeModel.from_fov(256, 200, 170.0)
    assert opencv_lut(short, wide) is None
