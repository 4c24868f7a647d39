"""What the pipeline is told about the rig and the room (the scene's ``given`` block); rendering uses the truth.

Each perturbation draws from its own stream of ``numpy.random.default_rng((seed, k))`` so turning one on
or off does not change the others.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial.transform import Rotation

from probeless.cameras.extrinsics import load_extrinsics
from probeless.cameras.io import load_calibration
from probeless.errors import CalibrationError, GeometryError, SceneError
from probeless.geom.floorplan import check_floorplan
from probeless.geom.polygon import signed_area
from probeless.messages.sensor import CameraInfo
from probeless.scene.effects_spec import ExtrinsicsError, FloorplanError, Given, IntrinsicsError

_FLOORPLAN, _EXTRINSICS, _INTRINSICS = 1, 2, 3


@dataclass(frozen=True)
class GivenRig:
    """The values handed to the pipeline."""

    floorplan: np.ndarray          # (N, 2) counter-clockwise [m, world]
    ceiling_height: float          # [m]
    fisheye_from_rgbd: np.ndarray  # (4, 4)
    fisheye_info: CameraInfo       # stamp 0, frame "fisheye"
    clock_offset_s: float          # added to fisheye stamps [s]


def area_centroid(poly: np.ndarray) -> np.ndarray:
    """Centroid of the area of a simple polygon (N, 2)."""
    a, b = poly, np.roll(poly, -1, axis=0)
    cross = a[:, 0] * b[:, 1] - b[:, 0] * a[:, 1]
    return np.sum((a + b) * cross[:, None], axis=0) / (6.0 * signed_area(poly))


def perturb_floorplan(poly: np.ndarray, height: float, err: FloorplanError,
                      rng: np.random.Generator) -> tuple[np.ndarray, float]:
    """(vertices offset by N(0, vertex_sigma_m) per coordinate, then rotated by rotation_deg about the true
    area centroid; height + ceiling_m)."""
    moved = poly + rng.normal(0.0, err.vertex_sigma_m, poly.shape) if err.vertex_sigma_m > 0 else poly.copy()
    c, a = area_centroid(poly), np.radians(err.rotation_deg)
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    return (moved - c) @ R.T + c, height + err.ceiling_m


def perturb_extrinsics(T: np.ndarray, err: ExtrinsicsError, rng: np.random.Generator) -> np.ndarray:
    """``T`` with N(0, translation_sigma_m) added to each translation component and rotated by a rotation
    vector with N(0, rotation_sigma_deg) components (applied in the fisheye frame: R' = dR @ R)."""
    out = np.array(T, dtype=np.float64)
    dr = rng.normal(0.0, np.radians(err.rotation_sigma_deg), 3)
    out[:3, :3] = Rotation.from_rotvec(dr).as_matrix() @ out[:3, :3]
    out[:3, 3] += rng.normal(0.0, err.translation_sigma_m, 3)
    return out


def perturb_intrinsics(info: CameraInfo, err: IntrinsicsError, rng: np.random.Generator) -> CameraInfo:
    """``info`` with fx, fy scaled by 1 + N(0, focal_rel_sigma) (one draw each), cx, cy + N(0, center_sigma_px)
    and (omnidir) xi + N(0, xi_sigma)."""
    K = info.K.copy()
    f = 1.0 + rng.normal(0.0, err.focal_rel_sigma, 2)
    c = rng.normal(0.0, err.center_sigma_px, 2)
    xi = rng.normal(0.0, err.xi_sigma)
    K[0, 0], K[1, 1] = K[0, 0] * f[0], K[1, 1] * f[1]
    K[0, 2], K[1, 2] = K[0, 2] + c[0], K[1, 2] + c[1]
    return replace(info, K=K, xi=max(0.0, info.xi + xi) if info.model == "omnidir" else info.xi)


def given_rig(given: Given | None, floorplan: np.ndarray, ceiling_height: float, fisheye_from_rgbd: np.ndarray,
              fisheye_info: CameraInfo, where: str = "given") -> GivenRig:
    """Resolve a ``given`` block against the truth; SceneError naming ``where`` and the key at fault."""
    if given is None:
        return GivenRig(floorplan, ceiling_height, fisheye_from_rgbd, fisheye_info, 0.0)
    rng = lambda k: np.random.default_rng((given.seed, k))  # noqa: E731
    if given.floorplan is not None:
        floorplan, ceiling_height = perturb_floorplan(floorplan, ceiling_height, given.floorplan, rng(_FLOORPLAN))
        try:
            check_floorplan(floorplan, f"{where}.floorplan (the perturbed floorplan)")
        except GeometryError as exc:
            raise SceneError(f"{exc}; use a smaller vertex_sigma_m or another seed") from None
        if ceiling_height <= 0:
            raise SceneError(f"{where}.floorplan.ceiling_m: the given ceiling height {ceiling_height} m is not > 0")
    if (e := given.extrinsics) is not None:
        fisheye_from_rgbd = (_file_extrinsics(e, where) if e.from_file
                             else perturb_extrinsics(fisheye_from_rgbd, e, rng(_EXTRINSICS)))
    if (i := given.fisheye_intrinsics) is not None:
        fisheye_info = (_file_intrinsics(i, fisheye_info, where) if i.from_file
                        else perturb_intrinsics(fisheye_info, i, rng(_INTRINSICS)))
    return GivenRig(floorplan, ceiling_height, fisheye_from_rgbd, fisheye_info, given.clock_offset_s)


def _file_extrinsics(e: ExtrinsicsError, where: str) -> np.ndarray:
    try:
        return load_extrinsics(e.from_file)
    except CalibrationError as exc:
        raise SceneError(f"{where}.extrinsics.from_file: {exc}") from None


def _file_intrinsics(i: IntrinsicsError, true_info: CameraInfo, where: str) -> CameraInfo:
    try:
        info = load_calibration(i.from_file, frame_id=true_info.header.frame_id)
    except CalibrationError as exc:
        raise SceneError(f"{where}.fisheye_intrinsics.from_file: {exc}") from None
    if (info.width, info.height) != (true_info.width, true_info.height):
        raise SceneError(f"{where}.fisheye_intrinsics.from_file: {i.from_file} is for {info.width}x{info.height} "
                         f"images, the fisheye renders {true_info.width}x{true_info.height}")
    return info


def told_errors(truth: GivenRig, told: GivenRig) -> dict[str, float]:
    """How far what the pipeline is told is from the truth: vertex offsets [m] (min, max), ceiling [m],
    extrinsics translation [m] and rotation angle [deg], fisheye fx/fy relative errors, centre offsets [px],
    clock [s]."""
    moved = np.linalg.norm(told.floorplan - truth.floorplan, axis=1)
    dR = told.fisheye_from_rgbd[:3, :3] @ truth.fisheye_from_rgbd[:3, :3].T
    K0, K1 = truth.fisheye_info.K, told.fisheye_info.K
    return {"vertex_min_m": float(moved.min()), "vertex_max_m": float(moved.max()),
            "ceiling_m": told.ceiling_height - truth.ceiling_height,
            "extrinsics_m": float(np.linalg.norm(told.fisheye_from_rgbd[:3, 3] - truth.fisheye_from_rgbd[:3, 3])),
            "extrinsics_deg": float(np.degrees(np.linalg.norm(Rotation.from_matrix(dR).as_rotvec()))),
            "fx_rel": K1[0, 0] / K0[0, 0] - 1, "fy_rel": K1[1, 1] / K0[1, 1] - 1,
            "cx_px": K1[0, 2] - K0[0, 2], "cy_px": K1[1, 2] - K0[1, 2], "clock_s": told.clock_offset_s}
