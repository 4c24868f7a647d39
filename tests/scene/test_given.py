"""The ``given`` block: perturbations have the requested statistics, seeds reproduce, files load, bad ones fail."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from probeless.cameras.extrinsics import save_extrinsics
from probeless.cameras.io import save_calibration
from probeless.cameras.omnidir import OmnidirModel
from probeless.errors import SceneError
from probeless.geom.polygon import signed_area
from probeless.geom.rotation import transform_from_rpy
from probeless.scene.effects_spec import ExtrinsicsError, FloorplanError, Given, IntrinsicsError
from probeless.scene.given import area_centroid, given_rig, perturb_extrinsics, perturb_floorplan, perturb_intrinsics

LOUNGE = np.array([[0, 0], [6, 0], [6, 3], [3, 3], [3, 5], [0, 5]], np.float64)
T = transform_from_rpy([0.0, -0.06, -0.02], [-90, 0, 0])
INFO = OmnidirModel.from_fov(1024, 1024, 185).to_camera_info("fisheye")


def test_area_centroid_of_the_l_shape():
    # two rectangles: 6x3 at (3, 1.5) and 3x2 at (1.5, 4): area-weighted mean
    assert area_centroid(LOUNGE) == pytest.approx((18 * np.array([3, 1.5]) + 6 * np.array([1.5, 4])) / 24)


def test_floorplan_vertex_offsets_have_the_requested_sigma():
    err = FloorplanError(vertex_sigma_m=0.03)
    offsets = np.concatenate([perturb_floorplan(LOUNGE, 2.7, err, np.random.default_rng(s))[0] - LOUNGE
                              for s in range(2000)])
    assert offsets.mean() == pytest.approx(0.0, abs=4 * 0.03 / np.sqrt(offsets.size))
    assert offsets.std() == pytest.approx(0.03, rel=0.03)


def test_floorplan_rotation_about_the_centroid_and_ceiling_offset():
    poly, height = perturb_floorplan(LOUNGE, 2.7, FloorplanError(rotation_deg=1.0, ceiling_m=0.03),
                                     np.random.default_rng(0))
    assert height == pytest.approx(2.73)
    for a, b in ((LOUNGE, poly),):
        ea, eb = np.roll(a, -1, 0) - a, np.roll(b, -1, 0) - b
        angles = np.degrees(np.arctan2(eb[:, 1], eb[:, 0]) - np.arctan2(ea[:, 1], ea[:, 0]))
        np.testing.assert_allclose((angles + 180) % 360 - 180, 1.0, atol=1e-9)
    assert area_centroid(poly) == pytest.approx(area_centroid(LOUNGE), abs=1e-12)
    assert signed_area(poly) == pytest.approx(signed_area(LOUNGE))


def test_extrinsics_perturbation_statistics():
    err = ExtrinsicsError(translation_sigma_m=0.01, rotation_sigma_deg=0.5)
    draws = np.array([perturb_extrinsics(T, err, np.random.default_rng(s)) for s in range(2000)])
    dt = draws[:, :3, 3] - T[:3, 3]
    dr = np.degrees(Rotation.from_matrix(draws[:, :3, :3] @ T[:3, :3].T).as_rotvec())
    np.testing.assert_allclose(dt.std(axis=0), 0.01, rtol=0.07)  # 4 sigma of a 2000-sample std
    np.testing.assert_allclose(dr.std(axis=0), 0.5, rtol=0.07)
    for d in draws[:20]:
        assert np.allclose(d[:3, :3] @ d[:3, :3].T, np.eye(3), atol=1e-12) and np.linalg.det(d[:3, :3]) > 0


def test_intrinsics_perturbation_statistics():
    err = IntrinsicsError(focal_rel_sigma=0.005, center_sigma_px=2.0, xi_sigma=0.01)
    draws = [perturb_intrinsics(INFO, err, np.random.default_rng(s)) for s in range(3000)]
    fx = np.array([d.K[0, 0] for d in draws]) / INFO.K[0, 0] - 1
    cy = np.array([d.K[1, 2] for d in draws]) - INFO.K[1, 2]
    xi = np.array([d.xi for d in draws]) - INFO.xi
    assert fx.std() == pytest.approx(0.005, rel=0.05) and cy.std() == pytest.approx(2.0, rel=0.05)
    assert xi.std() == pytest.approx(0.01, rel=0.05)
    assert all(d.width == 1024 and d.model == "omnidir" for d in draws)


def test_seeds_reproduce_and_differ():
    given = Given(seed=4, floorplan=FloorplanError(0.03, 1.0, 0.03), extrinsics=ExtrinsicsError(0.01, 0.5),
                  fisheye_intrinsics=IntrinsicsError(0.005, 2.0), clock_offset_s=0.01)
    a, b = (given_rig(given, LOUNGE, 2.7, T, INFO) for _ in range(2))
    c = given_rig(Given(seed=5, floorplan=given.floorplan, extrinsics=given.extrinsics,
                        fisheye_intrinsics=given.fisheye_intrinsics), LOUNGE, 2.7, T, INFO)
    np.testing.assert_array_equal(a.floorplan, b.floorplan)
    np.testing.assert_array_equal(a.fisheye_from_rgbd, b.fisheye_from_rgbd)
    np.testing.assert_array_equal(a.fisheye_info.K, b.fisheye_info.K)
    assert not np.allclose(a.floorplan, c.floorplan) and not np.allclose(a.fisheye_from_rgbd, c.fisheye_from_rgbd)
    assert a.clock_offset_s == 0.01
    # turning one perturbation off leaves the others' draws unchanged
    d = given_rig(Given(seed=4, extrinsics=given.extrinsics), LOUNGE, 2.7, T, INFO)
    np.testing.assert_array_equal(d.fisheye_from_rgbd, a.fisheye_from_rgbd)
    np.testing.assert_array_equal(d.floorplan, LOUNGE)


def test_no_given_is_the_truth():
    g = given_rig(None, LOUNGE, 2.7, T, INFO)
    assert g.floorplan is LOUNGE and g.fisheye_from_rgbd is T and g.fisheye_info is INFO and g.clock_offset_s == 0


def test_from_files(tmp_path):
    calibrated = np.array(T)
    calibrated[:3, 3] += [0.004, -0.002, 0.001]
    save_extrinsics(tmp_path / "ext.yaml", calibrated)
    info = OmnidirModel(1024, 1024, INFO.K * [[1.01], [1.0], [1]], 0.95).to_camera_info("x")
    save_calibration(tmp_path / "fish.yaml", info)
    g = given_rig(Given(0, extrinsics=ExtrinsicsError(from_file=tmp_path / "ext.yaml"),
                        fisheye_intrinsics=IntrinsicsError(from_file=tmp_path / "fish.yaml")), LOUNGE, 2.7, T, INFO)
    np.testing.assert_allclose(g.fisheye_from_rgbd, calibrated, atol=1e-9)
    np.testing.assert_allclose(g.fisheye_info.K, info.K)
    assert g.fisheye_info.xi == pytest.approx(0.95) and g.fisheye_info.header.frame_id == "fisheye"
    save_calibration(tmp_path / "small.yaml", OmnidirModel.from_fov(640, 640, 185).to_camera_info())
    with pytest.raises(SceneError, match="given.fisheye_intrinsics.from_file: .*640x640"):
        given_rig(Given(0, fisheye_intrinsics=IntrinsicsError(from_file=tmp_path / "small.yaml")),
                  LOUNGE, 2.7, T, INFO)
    (tmp_path / "bad.yaml").write_text("nothing: here\n")
    with pytest.raises(SceneError, match="given.extrinsics.from_file"):
        given_rig(Given(0, extrinsics=ExtrinsicsError(from_file=tmp_path / "bad.yaml")), LOUNGE, 2.7, T, INFO)


def test_a_perturbed_floorplan_that_is_no_longer_simple_is_an_error():
    sliver = np.array([[0, 0], [4, 0], [4, 0.05], [2, 0.02], [0, 0.05]], np.float64)
    raised = 0
    for seed in range(10):
        try:
            given_rig(Given(seed, floorplan=FloorplanError(vertex_sigma_m=0.2)), sliver, 2.5, T, INFO)
        except SceneError as exc:
            assert "given.floorplan (the perturbed floorplan)" in str(exc)
            raised += 1
    assert raised > 0
