"""Figure 7 quantified: the simulated camera, the sphere renderer against analytic cases, the error
metrics, and that clipping a sun really darkens the lighting while the paper's ITMO brings part back."""

import argparse
import json

import cv2
import numpy as np
import pytest

from probeless.color import from_srgb8, linear_to_srgb
from probeless.eval import add_evaluation
from probeless.pano import equirect, itmo_eval, itmo_maps, itmo_metrics, spheres
from probeless.pano.itmo_maps import SphereLighting, SphereSetup

SETUP = SphereSetup(size=33)


def test_make_ldr_round_trips_unsaturated_and_clips_the_rest():
    rng = np.random.default_rng(1)
    hdr = rng.uniform(0.0, 4.0, (64, 128, 3)).astype(np.float32) ** 2
    k = 0.4
    ldr = itmo_maps.make_ldr(hdr, k)
    assert ldr.dtype == np.uint8 and ldr.shape == hdr.shape
    lin = hdr * k
    ok, sat = lin < 0.995, lin >= 1.0
    assert ok.mean() > 0.2 and sat.mean() > 0.2
    # unsaturated: back to linear within the 8-bit quantisation (half a code, plus the LUT's one code)
    code_err = np.abs(linear_to_srgb(from_srgb8(ldr)[ok]) - linear_to_srgb(lin[ok])) * 255
    assert code_err.max() <= 1.0 + 1e-6 and code_err.mean() < 0.3
    assert np.all(ldr[sat] == 255)


def test_camera_exposure_meters_the_weighted_percentile():
    # top hemisphere luminance 1, bottom 4: equal solid angles, whatever the row count
    w, h = 256, 128
    hdr = np.ones((h, w, 3), np.float32)
    hdr[h // 2:] = 4.0
    assert itmo_maps.camera_exposure(hdr, 0.9, 0.5) == pytest.approx(0.5 / 4.0)
    assert itmo_maps.camera_exposure(hdr, 0.25, 0.18) == pytest.approx(0.18)
    # a polar cap of the first 16 rows covers (1 - cos(16 pi / 128)) / 2 = 3.8% of the sphere:
    # unweighted it would be 12.5% of the pixels, so the 90th weighted percentile must be the rest
    cap = np.full((h, w, 3), 2.0, np.float32)
    cap[:16] = 100.0
    frac = (1 - np.cos(16 * np.pi / h)) / 2
    assert frac < 0.05
    assert itmo_maps.camera_exposure(cap, 0.9, 0.5) == pytest.approx(0.25)
    assert itmo_maps.camera_exposure(cap, 1 - frac / 2, 0.5) == pytest.approx(0.005)


def test_constant_environment_gives_constant_spheres():
    env = np.full((64, 128, 3), [2.0, 1.0, 0.5], np.float32)
    out = itmo_maps.render_spheres(SphereLighting.of(env), SphereSetup(size=21, albedo=0.7, specular=0.9))
    np.testing.assert_allclose(out["diffuse"], np.broadcast_to([1.4, 0.7, 0.35], out["diffuse"].shape), rtol=1e-5)
    for obj in ("glossy", "mirror"):
        np.testing.assert_allclose(out[obj], np.broadcast_to([1.8, 0.9, 0.45], out[obj].shape), rtol=1e-5)


def _direction_env(w=512, h=256):
    d = equirect.pixel_directions(w, h)
    return (d + 1.5).astype(np.float32)  # colour = direction (shifted positive), smooth


@pytest.mark.parametrize("forward", [(1.0, 0.0, 0.0), (0.3, -1.0, 0.4), (-0.5, 0.2, -0.6)])
def test_mirror_sphere_centre_reflects_towards_the_viewer(forward):
    size = 41
    view = spheres.sphere_view(size, forward)
    f = np.asarray(forward) / np.linalg.norm(forward)
    img = view.image(spheres.shade("mirror", view.normals, view.reflect, _direction_env()))
    np.testing.assert_allclose(img[size // 2, size // 2], -f + 1.5, atol=5e-3)  # the direction towards the viewer
    # every pixel: unit normal facing the viewer, angle of incidence = angle of reflection
    v = -f
    assert np.all(view.normals @ v >= 0) and np.allclose(np.linalg.norm(view.normals, axis=1), 1)
    np.testing.assert_allclose(np.sum(view.reflect * view.normals, axis=1), view.normals @ v, atol=1e-12)
    np.testing.assert_allclose(view.reflect + v, 2 * (view.normals @ v)[:, None] * view.normals, atol=1e-12)


def test_sphere_image_layout_top_is_up_right_is_right():
    size = 31
    view = spheres.sphere_view(size, (1.0, 0.0, 0.0))  # looking along +x with z up: image right is -y
    n = view.image(view.normals)
    for r, c in [(1, 15), (15, 29), (7, 22), (24, 8)]:
        x, y = (c + 0.5) / size * 2 - 1, 1 - (r + 0.5) / size * 2
        np.testing.assert_allclose(n[r, c], [-np.sqrt(1 - x * x - y * y), -x, y], atol=1e-6)
    assert not view.mask[0, 0] and view.mask[size // 2, size // 2]
    assert view.mask.sum() == len(view.normals) == pytest.approx(np.pi / 4 * size * size, rel=0.02)


def test_errors_zero_for_the_hdr_map_itself_and_scale_separates_level():
    rng = np.random.default_rng(3)
    ref = rng.uniform(0.0, 2.0, (500, 3))
    e = itmo_metrics.image_errors(ref, ref)
    assert e["rel_rmse"] == 0 and e["rel_rmse_scaled"] == 0 and e["psnr"] == float("inf") and e["scale"] == 1
    e2 = itmo_metrics.image_errors(2 * ref, ref)
    assert e2["rel_rmse"] == pytest.approx(1.0) and e2["scale"] == pytest.approx(0.5)
    assert e2["rel_rmse_scaled"] == pytest.approx(0.0, abs=1e-12)
    # display PSNR by hand
    d = lambda x: linear_to_srgb(np.clip(x, 0, 1))  # noqa: E731
    assert e2["psnr"] == pytest.approx(10 * np.log10(1 / np.mean((d(2 * ref) - d(ref)) ** 2)))


def test_rank_margins():
    r = itmo_metrics.rank({"ldr": 0.6, "a": 0.3, "b": 0.4}, "min")
    assert r["best"] == "a" and r["runner_up"] == "b" and r["margin_over_runner_up"] == pytest.approx(4 / 3)
    assert r["margin_over_ldr"] == pytest.approx(2.0) and r["ranking"] == ["a", "b", "ldr"]
    p = itmo_metrics.rank({"ldr": 20.0, "a": 25.0}, "max")
    assert p["best"] == "a" and p["margin_over_ldr"] == pytest.approx(5.0)


def _sun_panorama(w=256, h=128, sun_deg=8.0, sun=200.0):
    d = equirect.pixel_directions(w, h)
    s = np.array([1.0, 0.0, 0.3]) / np.linalg.norm([1.0, 0.0, 0.3])
    hdr = np.full((h, w, 3), [0.30, 0.32, 0.36], np.float32)
    hdr[d @ s > np.cos(np.radians(sun_deg))] = sun
    return hdr, s


def test_low_dynamic_range_scene_is_lit_the_same_by_ldr_and_hdr():
    d = equirect.pixel_directions(256, 128)
    hdr = (0.2 + 0.1 * d[..., 2:3] + 0.05 * d[..., :1] * np.array([1.0, 0.8, 0.6])).astype(np.float32)
    res, _ = itmo_eval.evaluate_panorama("flat", hdr, SETUP)
    assert res["clipped_fraction"] == 0 and res["ldr_energy_fraction"] == pytest.approx(1.0)
    for obj, e in res["errors"]["ldr"].items():
        assert e["rel_rmse"] < 0.01 and e["psnr"] > 40, obj  # only quantisation is left


@pytest.mark.slow
def test_clipped_sun_darkens_ldr_lighting_and_paper_itmo_recovers_part():
    hdr, s = _sun_panorama()
    k = itmo_maps.camera_exposure(hdr)
    maps = itmo_maps.lighting_maps(hdr, k)
    assert maps["ldr"].max() <= 1.0 and maps["hdr"].max() == pytest.approx(200.0 * k)
    np.testing.assert_allclose(maps["hdr"], hdr * k, rtol=1e-6)
    toward, away = (-s[0], -s[1], 0.0), (s[0], s[1], 0.0)  # camera with the sun behind it / in front of it
    contrast = {}
    for m in ("ldr", "paper", "hdr"):
        lit = SphereLighting.of(maps[m])
        front = itmo_maps.render_spheres(lit, SETUP, views=(toward,))["diffuse"]
        back = itmo_maps.render_spheres(lit, SETUP, views=(away,))["diffuse"]
        contrast[m] = front.mean() / back.mean() - 1.0  # light from the sun's side over the rest
        if m == "hdr":
            hdr_front = front
        elif m == "ldr":
            ldr_front = front
    assert np.all(ldr_front <= hdr_front * 1.01 + 1e-3)  # clipping only removes light
    assert hdr_front.mean() > 3 * ldr_front.mean()
    assert contrast["ldr"] < contrast["paper"] < contrast["hdr"]
    assert contrast["paper"] > 2 * contrast["ldr"]
    res, _ = itmo_eval.evaluate_panorama("sun", hdr, SETUP)
    e = res["errors"]
    assert e["paper"]["diffuse"]["rel_rmse_scaled"] < e["ldr"]["diffuse"]["rel_rmse_scaled"]
    assert e["paper"]["diffuse"]["rel_rmse"] < e["ldr"]["diffuse"]["rel_rmse"]


@pytest.mark.slow
def test_cli_json_and_figure(tmp_path, capsys):
    hdr, _ = _sun_panorama(128, 64)
    path = tmp_path / "sun.hdr"
    assert cv2.imwrite(str(path), hdr[..., ::-1].copy())
    ap = argparse.ArgumentParser()
    add_evaluation(ap.add_subparsers(dest="cmd"), "itmo")
    fig = tmp_path / "grid.png"
    ns = ap.parse_args(["itmo", "--json", "--no-progress", "--panorama", str(path), "--figure", str(fig)])
    assert ns.func(ns) == 0
    out = json.loads(capsys.readouterr().out)
    (pano,) = out["panoramas"]
    assert pano["name"] == "sun" and set(pano["errors"]) == set(itmo_maps.MAPS) - {"hdr"}
    assert set(pano["errors"]["ldr"]) == set(spheres.OBJECTS)
    assert set(out["overall"]["winners"]["diffuse"]) == set(itmo_metrics.METRICS)
    img = cv2.imread(str(fig))
    rows = len(itmo_maps.MAPS) * itmo_eval.FIGURE_SIZE
    assert img.shape[0] > rows and img.shape[1] == 110 + 3 * itmo_eval.FIGURE_SIZE
