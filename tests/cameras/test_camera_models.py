"""Camera models against OpenCV, analytic forms, each other, and OCamCalib's published formulas."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from locations import SHARED_DATA

from probeless.cameras import KannalaBrandtModel, OcamModel, OmnidirModel, PinholeModel, model_from_info
from probeless.cameras.io import load_calibration, load_calibration_extra, save_calibration
from probeless.errors import CalibrationError

OCAM_FILE = SHARED_DATA / "fisheye" / "ocamcalib" / "calib_results_fisheye.txt"


def random_K(rng, skew=True):
    fx, fy = rng.uniform(200, 500, 2)
    return np.array([[fx, rng.uniform(-2, 2) if skew else 0.0, rng.uniform(300, 340)],
                     [0, fy, rng.uniform(220, 260)], [0, 0, 1]])


def random_dirs(rng, n, min_z=None):
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return d if min_z is None else d[d[:, 2] > min_z]


def cv_points(p):
    return np.ascontiguousarray(p, dtype=np.float64).reshape(1, -1, 3)


# --- against OpenCV -------------------------------------------------------------------------------

@pytest.mark.parametrize("seed", range(4))
def test_omnidir_project_matches_cv2_omnidir(seed):
    rng = np.random.default_rng(seed)
    K, xi = random_K(rng), rng.uniform(0.3, 2.0)
    D = rng.uniform(-0.05, 0.05, 4) * [1, 0.2, 0.05, 0.05]
    model = OmnidirModel(640, 480, K, xi, D)
    p = random_dirs(rng, 3000) * rng.uniform(0.5, 5, (3000, 1))
    zs = p[:, 2] / np.linalg.norm(p, axis=1)
    in_domain = (zs + xi > 0) & (1 + xi * zs > 0)
    uv, valid = model.project(p)
    assert np.array_equal(valid, in_domain)
    ref, _ = cv2.omnidir.projectPoints(cv_points(p[in_domain]), np.zeros(3), np.zeros(3), K, xi, D)
    np.testing.assert_allclose(uv[valid], ref.reshape(-1, 2), atol=1e-8)
    assert np.isnan(uv[~valid]).all()


@pytest.mark.parametrize("seed", range(3))
def test_omnidir_unproject_matches_cv2_undistort_points(seed):
    rng = np.random.default_rng(seed)
    K, xi = random_K(rng), rng.uniform(0.5, 1.5)
    D = np.array([-0.04, 0.005, 0.001, -0.001]) * rng.uniform(0.5, 1.5, 4)
    model = OmnidirModel(640, 480, K, xi, D)
    px = rng.uniform([100, 80], [540, 400], (500, 2))
    rays, valid = model.unproject(px)
    assert valid.all()
    ref = cv2.omnidir.undistortPoints(px.reshape(1, -1, 2), K, D, np.array([xi]), np.eye(3)).reshape(-1, 2)
    np.testing.assert_allclose(rays[:, :2] / rays[:, 2:], ref, atol=1e-6)


@pytest.mark.parametrize("seed", range(4))
def test_kannala_brandt_project_matches_cv2_fisheye(seed):
    rng = np.random.default_rng(seed)
    K = random_K(rng)
    D = rng.uniform(-0.02, 0.02, 4)
    model = KannalaBrandtModel(640, 480, K, D)
    p = random_dirs(rng, 3000, min_z=0.01) * 2.0  # cv2.fisheye uses atan(r): only z > 0 is comparable
    uv, valid = model.project(p)
    # the domain ends where d theta_d / d theta = 1 + 3 k1 t^2 + 5 k2 t^4 + 7 k3 t^6 + 9 k4 t^8 first vanishes
    roots = np.roots([9 * D[3], 7 * D[2], 5 * D[1], 3 * D[0], 1])
    t2 = roots[(abs(roots.imag) < 1e-12) & (roots.real > 0)].real
    limit = min(math.sqrt(t2.min()) if len(t2) else math.pi, math.pi)
    theta = np.arccos(p[:, 2] / np.linalg.norm(p, axis=1))
    assert np.array_equal(valid[abs(theta - limit) > 1e-3], (theta < limit)[abs(theta - limit) > 1e-3])
    assert valid.sum() > 500
    ref, _ = cv2.fisheye.projectPoints(cv_points(p[valid]), np.zeros(3), np.zeros(3), K, D, alpha=K[0, 1] / K[0, 0])
    np.testing.assert_allclose(uv[valid], ref.reshape(-1, 2), atol=1e-8)


@pytest.mark.parametrize("seed", range(3))
def test_kannala_brandt_unproject_matches_cv2_fisheye_undistort(seed):
    rng = np.random.default_rng(seed)
    K = random_K(rng, skew=False)
    D = np.array([0.02, -0.005, 0.001, -0.0002]) * rng.uniform(0.5, 1.5, 4)
    model = KannalaBrandtModel(640, 480, K, D)
    px = K[:2, 2] + rng.uniform(-1, 1, (500, 2)) * 0.9 * min(K[0, 0], K[1, 1])
    rays, valid = model.unproject(px)
    assert valid.all() and rays[:, 2].min() > 0.2  # all within 80 degrees of the axis: comparable with cv2
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-15)
    ref = cv2.fisheye.undistortPoints(px.reshape(1, -1, 2), K, D, criteria=crit).reshape(-1, 2)
    np.testing.assert_allclose(rays[:, :2] / rays[:, 2:], ref, rtol=1e-7, atol=1e-8)


@pytest.mark.parametrize("n_coeffs", [0, 4, 5, 8, 12, 14])
def test_pinhole_matches_cv2_project_and_undistort(n_coeffs):
    rng = np.random.default_rng(n_coeffs)
    K = random_K(rng, skew=False)  # cv2.projectPoints ignores K[0, 1]
    scale = np.array([0.1, 0.02, 0.002, 0.002, 0.005, 0.05, 0.01, 0.005, 0.002, 0.001, 0.002, 0.001, 0.02, 0.02])
    D = rng.uniform(-1, 1, 14)[:n_coeffs] * scale[:n_coeffs]
    model = PinholeModel(640, 480, K, D)
    p = random_dirs(rng, 2000, min_z=0.7)
    uv, valid = model.project(p)
    assert valid.all()
    ref, _ = cv2.projectPoints(cv_points(p), np.zeros(3), np.zeros(3), K, D if n_coeffs else None)
    np.testing.assert_allclose(uv, ref.reshape(-1, 2), atol=1e-7)
    rays, ok = model.unproject(uv)
    assert ok.all()
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-15)
    und = cv2.undistortPoints(uv.reshape(1, -1, 2), K, D if n_coeffs else None, criteria=crit).reshape(-1, 2)
    np.testing.assert_allclose(rays[:, :2] / rays[:, 2:], und, atol=1e-7)
    np.testing.assert_allclose(rays, p / np.linalg.norm(p, axis=1, keepdims=True), atol=1e-9)
    assert not model.project(np.array([[0.0, 0.0, -1.0]]))[1][0]


# --- round trips ----------------------------------------------------------------------------------

def round_trip_models():
    rng = np.random.default_rng(7)
    return [
        OmnidirModel(640, 480, random_K(rng), 0.9, [-0.05, 0.01, 0.001, -0.002]),
        OmnidirModel(640, 480, random_K(rng), 1.6, [0.02, -0.003, 0.0, 0.001]),
        OmnidirModel.from_fov(1024, 1024, 200.0, xi=1.0),
        KannalaBrandtModel(640, 480, random_K(rng), [0.01, -0.005, 0.002, -0.0005]),
        KannalaBrandtModel.from_fov(1024, 1024, 220.0),
        PinholeModel(640, 480, random_K(rng), [-0.2, 0.05, 0.001, 0.001, -0.01]),
    ]


@pytest.mark.parametrize("model", round_trip_models(), ids=lambda m: m.model)
def test_project_unproject_round_trip(model):
    px = model.pixel_grid()[::37]
    rays, valid = model.unproject(px)
    back, ok = model.project(rays[valid])
    assert ok.all() and valid.mean() > 0.5
    np.testing.assert_allclose(back, px[valid], atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(rays[valid], axis=1), 1.0, atol=1e-12)


def test_wide_models_unproject_beyond_90_degrees():
    for model in (OmnidirModel.from_fov(1024, 1024, 200.0), KannalaBrandtModel.from_fov(1024, 1024, 200.0)):
        rays, valid = model.unproject(np.array([[1023.5, 511.5], [511.5, 0.0]]))  # circle edge right, near top
        assert valid.all()
        angles = np.degrees(np.arccos(rays[:, 2]))
        assert angles[0] == pytest.approx(100.0, abs=1e-9)
        assert angles[1] > 99.0 and rays[1, 1] < 0 and rays[0, 0] > 0  # up is -y, right is +x


# --- analytic forms and cross-model consistency ---------------------------------------------------

def test_from_fov_analytic_forms():
    theta = np.radians(np.linspace(0, 92.5, 50))
    rays = np.column_stack([np.sin(theta), np.zeros_like(theta), np.cos(theta)])
    kb = KannalaBrandtModel.from_fov(1024, 768, 185.0)
    f = 384 / np.radians(92.5)
    np.testing.assert_allclose(kb.project(rays)[0][:, 0] - 511.5, f * theta, atol=1e-9)  # equidistant r = f theta
    om = OmnidirModel.from_fov(1024, 768, 185.0, xi=1.0)
    f = 384 / math.tan(np.radians(92.5) / 2)
    r = om.project(rays)[0][:, 0] - 511.5
    np.testing.assert_allclose(r, f * np.sin(theta) / (1 + np.cos(theta)), atol=1e-9)  # stereographic
    np.testing.assert_allclose(r, f * np.tan(theta / 2), atol=1e-9)


def test_omnidir_with_xi_zero_is_the_pinhole():
    rng = np.random.default_rng(3)
    K, D = random_K(rng), [-0.1, 0.02, 0.001, 0.002]
    p = random_dirs(rng, 500, min_z=0.5)
    np.testing.assert_allclose(OmnidirModel(640, 480, K, 0.0, D).project(p)[0],
                               PinholeModel(640, 480, K, D).project(p)[0], atol=1e-9)


def test_kannala_brandt_taylor_series_equals_omnidir_xi_one():
    # 2 tan(t/2) = t + t^3/12 + t^5/120 + 17 t^7/20160 + 31 t^9/362880 + O(t^11): a KB model with
    # these coefficients and f_kb = f_omni / 2 is the ideal xi = 1 omnidir camera up to the O(t^11) term.
    om = OmnidirModel.from_fov(1024, 1024, 185.0, xi=1.0)
    K = om.K.copy()
    K[:2, :2] /= 2
    kb = KannalaBrandtModel(1024, 1024, K, [1 / 12, 1 / 120, 17 / 20160, 31 / 362880])
    rng = np.random.default_rng(5)
    p = random_dirs(rng, 4000, min_z=math.cos(math.radians(60)))
    np.testing.assert_allclose(kb.project(p)[0], om.project(p)[0], atol=0.01)
    px = om.project(p)[0]
    np.testing.assert_allclose(kb.unproject(px)[0], om.unproject(px)[0], atol=1e-4)


def test_kannala_brandt_fitted_to_omnidir():
    om = OmnidirModel.from_fov(800, 800, 190.0, xi=1.0)
    f = om.K[0, 0]
    theta = np.radians(np.linspace(0.5, 95, 400))
    r_norm = 2 * np.sin(theta) / (1 + np.cos(theta))  # omnidir radius / (f / 2)
    basis = np.stack([theta ** (2 * k + 3) for k in range(4)], axis=1)
    D = np.linalg.lstsq(basis, r_norm - theta, rcond=None)[0]
    K = om.K.copy()
    K[:2, :2] /= 2
    kb = KannalaBrandtModel(800, 800, K, D)
    p = random_dirs(np.random.default_rng(2), 4000, min_z=math.cos(math.radians(95)))
    err = np.linalg.norm(kb.project(p)[0] - om.project(p)[0], axis=1)
    assert err.max() < 0.1 * f / 400  # the degree-9 fit is good to a small fraction of a pixel


# --- OCamCalib ------------------------------------------------------------------------------------

def scaramuzza_cam2world(point2d, pol, xc, yc, c, d, e):
    """cam2world of OCamCalib's ocam_functions.c, literally: point2D = (row, col)."""
    invdet = 1 / (c - d * e)
    xp = invdet * ((point2d[0] - xc) - d * (point2d[1] - yc))
    yp = invdet * (-e * (point2d[0] - xc) + c * (point2d[1] - yc))
    r = math.sqrt(xp * xp + yp * yp)
    zp, r_i = pol[0], 1.0
    for a in pol[1:]:
        r_i *= r
        zp += r_i * a
    invnorm = 1 / math.sqrt(xp * xp + yp * yp + zp * zp)
    return invnorm * xp, invnorm * yp, invnorm * zp


def scaramuzza_world2cam(point3d, invpol, xc, yc, c, d, e):
    """world2cam of OCamCalib's ocam_functions.c, literally: returns (row, col)."""
    norm = math.sqrt(point3d[0] ** 2 + point3d[1] ** 2)
    theta = math.atan(point3d[2] / norm)
    rho, t_i = invpol[0], 1.0
    for b in invpol[1:]:
        t_i *= theta
        rho += t_i * b
    x, y = point3d[0] / norm * rho, point3d[1] / norm * rho
    return x * c + y * d + xc, x * e + y + yc


def test_ocam_file_is_read_verbatim():
    info = load_calibration(OCAM_FILE)
    assert (info.model, info.width, info.height) == ("ocam", 1024, 768)  # from the file's size line
    np.testing.assert_array_equal(info.ocam_poly, [-5.517655e+002, 0.0, 8.372454e-004, -6.474789e-007,
                                                   1.235631e-009])
    assert len(info.ocam_invpoly) == 8 and info.ocam_invpoly[0] == 730.949123
    np.testing.assert_array_equal(info.ocam_center, [381.777786, 505.480427])
    np.testing.assert_array_equal(info.ocam_affine, [1.0, 0.0, 0.0])


def test_ocam_round_trip_over_the_image_below_a_tenth_pixel():
    model = model_from_info(load_calibration(OCAM_FILE))
    px = model.pixel_grid()
    rays, valid = model.unproject(px)
    back, ok = model.project(rays)
    assert valid.all() and ok.all()
    assert np.linalg.norm(back - px, axis=1).max() < 0.1


def test_ocam_matches_scaramuzza_reference_formulas():
    info = load_calibration(OCAM_FILE)
    model = model_from_info(info)
    pol, invpol = list(info.ocam_poly), list(info.ocam_invpoly)
    (xc, yc), (c, d, e) = info.ocam_center, info.ocam_affine
    # a non-trivial affine too, to check the row/column bookkeeping
    sheared = OcamModel(1024, 768, pol, invpol, (xc, yc), (1.002, 0.003, -0.002))
    rng = np.random.default_rng(11)
    px = rng.uniform([0, 0], [1023, 767], (300, 2))
    for m, aff in ((model, (c, d, e)), (sheared, (1.002, 0.003, -0.002))):
        rays = m.unproject(px)[0]
        back = m.project(rays)[0]
        for (u, v), ray, (bu, bv) in zip(px, rays, back):
            ref = scaramuzza_cam2world((v, u), pol, xc, yc, *aff)  # OCam frame: x = rows, y = cols, z = -axis
            np.testing.assert_allclose(ray, (ref[1], ref[0], -ref[2]), atol=1e-12)
            row, col = scaramuzza_world2cam(ref, invpol, xc, yc, *aff)
            assert (bu, bv) == pytest.approx((col, row), abs=1e-9)
    centre_ray = model.unproject(np.array([[yc, xc]]))[0][0]
    np.testing.assert_allclose(centre_ray, [0, 0, 1], atol=1e-12)  # the centre looks along the optical axis


def test_ocam_maps_real_chessboard_lines_to_great_circles():
    # Straight board edges must unproject to rays in one plane through the centre (a great circle).
    # A swapped (row, col) centre or a plain equidistant lens with the same focal length bends them.
    img = cv2.imread(str(OCAM_FILE.parent / "test_fisheye.jpg"), cv2.IMREAD_GRAYSCALE)
    found, corners = cv2.findChessboardCorners(img, (5, 6))
    assert found
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 100, 1e-4)
    corners = cv2.cornerSubPix(img, corners, (5, 5), (-1, -1), crit).reshape(6, 5, 2).astype(np.float64)

    def worst_line_rms_deg(model):
        lines = list(corners) + list(corners.transpose(1, 0, 2))
        rms = [np.linalg.svd(model.unproject(line)[0], compute_uv=False)[-1] / math.sqrt(len(line))
               for line in lines]
        return math.degrees(max(rms))

    ocam = model_from_info(load_calibration(OCAM_FILE))
    swapped = OcamModel(1024, 768, ocam.poly, ocam.invpoly, (ocam.yc, ocam.xc))
    equidistant = KannalaBrandtModel(1024, 768, ocam.nominal_K())
    assert worst_line_rms_deg(ocam) < 0.04
    assert worst_line_rms_deg(swapped) > 0.1 and worst_line_rms_deg(equidistant) > 0.1


def test_ocam_without_size_line_infers_or_takes_overrides(tmp_path):
    text = OCAM_FILE.read_text()
    path = tmp_path / "calib_results.txt"
    path.write_text(text[:text.index("#image size")])
    info = load_calibration(path)
    assert (info.width, info.height) == (round(2 * 505.480427 + 1), round(2 * 381.777786 + 1))
    info = load_calibration(path, width=1024, height=768)
    assert (info.width, info.height) == (1024, 768)
    with pytest.raises(CalibrationError, match="caller expects 800"):
        load_calibration(OCAM_FILE, width=800)


# --- our YAML -------------------------------------------------------------------------------------

@pytest.mark.parametrize("model", round_trip_models()[::2] + [model_from_info(load_calibration(OCAM_FILE))],
                         ids=lambda m: m.model)
def test_yaml_round_trip_and_model_from_info(tmp_path, model):
    info = model.to_camera_info("fisheye", 5)
    save_calibration(tmp_path / "cam.yaml", info, extra={"rms_px": np.float64(0.25), "images_used": 12})
    back = load_calibration(tmp_path / "cam.yaml")
    for key in ("width", "height", "model", "K", "D", "xi", "ocam_poly", "ocam_invpoly", "ocam_affine",
                "ocam_center"):
        np.testing.assert_array_equal(getattr(back, key), getattr(info, key), err_msg=key)
    assert load_calibration_extra(tmp_path / "cam.yaml") == {"rms_px": 0.25, "images_used": 12}
    p = random_dirs(np.random.default_rng(1), 200, min_z=0.3)
    np.testing.assert_array_equal(model_from_info(back).project(p)[0], model.project(p)[0])


MALFORMED = {
    "missing_key.yaml": ("model: omnidir\nwidth: 640\nheight: 480\nK: [[300, 0, 320], [0, 300, 240], [0, 0, 1]]\n",
                         r"missing_key.yaml: key 'xi': missing"),
    "unknown_key.yaml": ("model: pinhole\nwidth: 640\nheight: 480\nK: [[300, 0, 320], [0, 300, 240], [0, 0, 1]]\n"
                         "focal: 3\n", r"unknown_key.yaml:5: key 'focal': unknown key"),
    "bad_K.yaml": ("model: pinhole\nwidth: 640\nheight: 480\nK: [300, 300, 320, 240]\n",
                   r"bad_K.yaml:4: key 'K': must be 3x3"),
    "bad_model.yaml": ("model: fisheye\nwidth: 640\nheight: 480\n", r"bad_model.yaml:1: key 'model'"),
    "bad_D.yaml": ("model: kannala_brandt\nwidth: 640\nheight: 480\nK: [[300, 0, 320], [0, 300, 240], [0, 0, 1]]\n"
                   "D: [0.1, 0.2]\n", r"bad_D.yaml: CameraInfo.D: 2 coefficients"),
    "not_yaml.yaml": ("model: [unclosed\n", r"not_yaml.yaml:2: invalid YAML"),
    "ocam_count.txt": ("#pol\n5 -551.7 0 0.0008\n#invpol\n2 730 315\n#centre\n381 505\n#affine\n1 0 0\n",
                       r"ocam_count.txt:2: OCamCalib polynomial"),
    "ocam_text.txt": ("5 -551.7 0 0.0008 0 0\n2 730 315\n381 centre\n1 0 0\n", r"ocam_text.txt:3: .*numbers"),
    "ocam_short.txt": ("3 -551.7 0 0.0008\n2 730 315\n381 505\n", r"ocam_short.txt: .*expected 4 or 5 data lines"),
}


@pytest.mark.parametrize("name", sorted(MALFORMED))
def test_malformed_calibration_files_name_file_and_key(tmp_path, name):
    text, pattern = MALFORMED[name]
    (tmp_path / name).write_text(text)
    with pytest.raises(CalibrationError, match=pattern):
        load_calibration(tmp_path / name)


def test_missing_file_is_a_calibration_error(tmp_path):
    with pytest.raises(CalibrationError, match="nope.yaml"):
        load_calibration(tmp_path / "nope.yaml")
