"""Issue 29: the radiometric camera model, calibrated against the synthetic rig's true response, vignetting and
white balance (the scene file's ``sensor_effects.fisheye``), and its file's validation.

Metrics (docs/cameras/radiometry.md): the max relative error of the inverse response over codes 10-245 without the
sensor's noise and over 48-245 with it (below ~48 the light_switch_realistic fisheye's noise, read noise 0.002 of full
scale, leaves an SNR under 9 per frame and averaged codes are biased); the max relative error of the vignetting
factor over the image circle; the white-balance gains relative to green. All must be <= 2 %.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from probeless.cameras.radiometry import load_radiometry, parse_radiometry, radiometry_dict, save_radiometry
from probeless.cameras.radiometry_calibrate import average_frames, calibrate_flat_field, calibrate_response
from probeless.cameras.radiometry_stack import read_stack, write_stack
from probeless.errors import CalibrationError
from probeless.scene.effects_spec import CameraEffects, Noise, Vignetting
from probeless.scene.rig_bracket import DEFAULT_EV, fisheye_radiance, record_stack, small_fisheye
from tests.locations import REPO

SCENE = REPO / "launch/scenes/light_switch_realistic.yaml"
SIZE = 128
CODES = np.arange(256) / 255.0


def _noiseless(scene):
    fx = scene.sensor_effects
    return replace(scene, sensor_effects=replace(fx, fisheye=replace(fx.fisheye, noise=None)))


@pytest.fixture(scope="module")
def view():
    """(scene, radiance, rays) of light_switch_realistic's fisheye at t = 0, SIZE x SIZE."""
    from probeless.scene.parse import load_scene

    scene = small_fisheye(load_scene(SCENE), SIZE)
    radiance, rays = fisheye_radiance(scene, 0.0, cube_size=64)
    return scene, radiance, rays


def _stack(scene, radiance, rays, frames, ev=DEFAULT_EV, labelled=None):
    stack = record_stack(scene, radiance, rays, [2.0 ** e for e in ev], frames)
    means, noise, ts = average_frames([im for _, im in stack], [e for e, _ in stack])
    if labelled is not None:  # what the camera *reports*, when that is wrong
        ts = [labelled(t) for t in ts]
    return means, noise, ts


def _response_error(inverse, gamma, lo):
    true = CODES ** gamma
    return float(np.max(np.abs(inverse[:, lo:246] / true[lo:246] - 1)))


def test_response_matches_the_rigs_gamma_with_noise_and_without(view):
    scene, radiance, rays = view
    gamma = scene.sensor_effects.fisheye.gamma
    means, noise, ts = _stack(scene, radiance, rays, frames=8)
    fit = calibrate_response(means, ts, noise=noise)
    assert fit.valid_codes[0] <= 48 and fit.valid_codes[1] >= 245
    assert _response_error(fit.inverse, gamma, 48) <= 0.02
    clean = _noiseless(scene)
    means, _, ts = _stack(clean, radiance, rays, frames=1)
    assert _response_error(calibrate_response(means, ts).inverse, gamma, 10) <= 0.02


def test_wrong_exposures_give_a_wrong_response(view):
    """The check can fail: a camera that reports 1.5x steps where it took 2x ones is calibrated to another gamma."""
    scene, radiance, rays = view
    means, _, ts = _stack(_noiseless(scene), radiance, rays, frames=1, labelled=lambda t: 1.5 ** np.log2(t))
    assert _response_error(calibrate_response(means, ts).inverse, scene.sensor_effects.fisheye.gamma, 16) > 0.1


def test_vignetting_and_white_balance_match_the_rig(view):
    scene, _, rays = view
    fx = scene.sensor_effects.fisheye
    means, noise, ts = _stack(scene, *view[1:], frames=8)
    inverse = calibrate_response(means, ts, noise=noise).inverse
    flat, _ = fisheye_radiance(scene, flat=0.5)
    frames = [im for _, im in record_stack(scene, flat, rays, [1.0], 8)]
    fit = calibrate_flat_field(frames, inverse)
    # truth: the scene file's poly coefficients about the fisheye's principal point (the image centre)
    inside = np.any(rays != 0, axis=-1)
    v, u = np.mgrid[0:SIZE, 0:SIZE]
    r2 = ((u - (SIZE - 1) / 2) ** 2 + (v - (SIZE - 1) / 2) ** 2) / (0.25 * 2 * (SIZE - 1) ** 2)
    true_v = 1 + sum(k * r2 ** (i + 1) for i, k in enumerate(fx.vignetting.coeffs))
    r2_fit = ((u - fit.center[0]) ** 2 + (v - fit.center[1]) ** 2) / (0.25 * 2 * (SIZE - 1) ** 2)
    got_v = 1 + sum(k * r2_fit ** (i + 1) for i, k in enumerate(fit.coeffs))
    assert np.max(np.abs(got_v[inside] / true_v[inside] - 1)) <= 0.02
    true_wb = np.asarray(fx.wb_gains) / fx.wb_gains[1]
    np.testing.assert_allclose(fit.gains, true_wb, rtol=0.01)


def test_an_srgb_camera_with_two_term_vignetting_synthetic_content():
    """Content not seen in development: random log-uniform radiance through an sRGB camera (the clean rig's curve),
    no rendering; exposures in whole stops."""
    from probeless.color import srgb_to_linear
    from probeless.scene.camera_sim import CameraSim

    rng = np.random.default_rng(3)
    h, w = 96, 128
    radiance = np.exp(rng.uniform(np.log(2e-3), np.log(4.0), (h, w, 1))) * rng.uniform(0.6, 1.0, (h, w, 3))
    effects = CameraEffects(vignetting=Vignetting("poly", (-0.25, 0.05)), noise=Noise(full_well=20000,
                                                                                      read_sigma=0.0005))
    cos_theta = np.ones((h, w))
    frames, exposures = [], []
    for e in 2.0 ** np.arange(-3, 5):
        sim = CameraSim(effects, float(e), cos_theta, ((w - 1) / 2, (h - 1) / 2), None, (5, 0))
        for i in range(4):
            frames.append(sim.record(radiance.astype(np.float32), 0.0, len(frames)))
            exposures.append(float(e))
    means, noise, ts = average_frames(frames, exposures)
    fit = calibrate_response(means, ts, noise=noise)
    true = srgb_to_linear(CODES)
    lo = max(fit.valid_codes[0], 16)
    assert lo <= 32
    assert np.max(np.abs(fit.inverse[:, lo:246] / true[lo:246] - 1)) <= 0.02


def test_radiometry_file_round_trip_and_errors(tmp_path):
    inverse = np.tile(CODES ** 2.2, (3, 1))
    from probeless.cameras.radiometry import Radiometry
    from probeless.cameras.radiometry import Vignetting as FileVignetting

    r = Radiometry(inverse, (20, 254), FileVignetting((-0.3, 0.01), (63.5, 47.5), 128, 96), np.array([0.9, 1, 1.1]))
    path = tmp_path / "radiometry.yaml"
    save_radiometry(path, r)
    back = load_radiometry(path)
    np.testing.assert_allclose(back.inverse, inverse, atol=1e-8)
    assert back.vignetting == r.vignetting and back.valid_codes == (20, 254)
    image = np.full((96, 128, 3), 128, np.uint8)
    lin = back.linear(image, exposure=2.0)
    assert lin[47, 63, 1] == pytest.approx((128 / 255) ** 2.2 / 2.0 / back.vignetting.factor()[47, 63], rel=1e-5)
    good = radiometry_dict(r)
    bad_cases = [
        ({**good, "radiometry": 2}, "'radiometry'"),
        ({**good, "response": {"inverse": {"r": good["response"]["inverse"]["r"]}}}, "'response.inverse.g'"),
        ({**good, "response": {"inverse": {**good["response"]["inverse"], "b": list(np.linspace(1, 0, 256))}}},
         "'response.inverse.b'"),
        ({**good, "vignetting": {**good["vignetting"], "coeffs": []}}, "'vignetting.coeffs'"),
        ({**good, "vignetting": {**good["vignetting"], "width": "wide"}}, "'vignetting.width'"),
        ({**good, "white_balance": {"gains": [1, -1, 1]}}, "'white_balance.gains'"),
    ]
    for data, key in bad_cases:
        with pytest.raises(CalibrationError, match=f"^{tmp_path / 'x.yaml'}: key {key}"):
            parse_radiometry(data, tmp_path / "x.yaml")
    (tmp_path / "broken.yaml").write_text("radiometry: [1\n")
    with pytest.raises(CalibrationError, match="broken.yaml: cannot read"):
        load_radiometry(tmp_path / "broken.yaml")


def test_stack_folder_errors_name_the_file_and_line(tmp_path):
    image = np.zeros((8, 8, 3), np.uint8)
    write_stack(tmp_path, [(1.0, image), (2.0, image)])
    images, exposures, names = read_stack(tmp_path)
    assert exposures == [1.0, 2.0] and names == ["frame_000.png", "frame_001.png"] and images[0].shape == (8, 8, 3)
    csv = tmp_path / "exposures.csv"
    csv.write_text("file,exposure\nframe_000.png,fast\n")
    with pytest.raises(CalibrationError, match="exposures.csv: line 2: exposure 'fast'"):
        read_stack(tmp_path)
    csv.write_text("file,exposure\nmissing.png,1\n")
    with pytest.raises(CalibrationError, match="line 2: cannot read image"):
        read_stack(tmp_path)
    csv.write_text("name,time\n")
    with pytest.raises(CalibrationError, match="line 1: the header"):
        read_stack(tmp_path)
    with pytest.raises(CalibrationError, match="at least 3 different exposures"):
        calibrate_response([image, image], [1.0, 2.0])


def test_cli_bracket_calibrate_and_check(tmp_path, capsys):
    """The documented commands end to end on a small fisheye: scene bracket (stack, flat field), calibrate response,
    calibrate vignetting, scene check-radiometry."""
    import json

    from probeless.cli import main

    scene, out = str(SCENE), tmp_path / "radiometry.yaml"
    assert main(["scene", "bracket", scene, "-o", str(tmp_path / "stack"), "--size", "96", "--frames", "6"]) == 0
    assert main(["scene", "bracket", scene, "-o", str(tmp_path / "flat"), "--size", "96", "--flat", "0.5"]) == 0
    assert main(["calibrate", "response", "--stack", str(tmp_path / "stack"), "-o", str(out)]) == 0
    assert main(["calibrate", "response", "--stack", str(tmp_path / "stack"), "-o", str(out)]) == 2  # no --force
    assert main(["calibrate", "vignetting", "--flat", str(tmp_path / "flat"), "--radiometry", str(out)]) == 0
    r = load_radiometry(out)
    assert r.vignetting is not None and r.gains is not None and r.vignetting.width == 96
    capsys.readouterr()
    assert main(["scene", "check-radiometry", scene, str(out), "--codes", "48", "245", "--json"]) == 0
    errors = json.loads(capsys.readouterr().out)
    assert errors["response_max_rel_error"] < 0.03 and errors["vignetting_max_rel_error"] < 0.02
    assert errors["white_balance_max_rel_error"] < 0.02
