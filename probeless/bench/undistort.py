"""``probeless bench undistort``: what fisheye undistortion costs, and the same mapping by OpenCV
(also part of ``probeless bench sensors``).

1. **The rig's case**: one synthetic 1024x1024 rgb8 frame from an OCamCalib source (the real sample
   calibration, centred on the frame) into the runtime model (ideal omnidir, xi = 1, 185 degrees,
   1024x1024): the one-off table build (``lut_build_ms``) and the per-frame ``cv2.remap`` through it
   (``remap_ms``), absolute; ``max_px_diff``: the largest distance between the positions the remap
   really samples and the float64 model positions [px] (goal <= 0.5) over the ``max_px_diff_pixels``
   destination pixels inside the source; ``mean_abs_diff``: mean |LUT output - per-pixel evaluation|.
2. **Against the reference** (``undistort_reference``): OpenCV cannot read an OCamCalib model, so the
   same kind of mapping from a Mei source (unified model with radial-tangential distortion, xi = 1.1)
   into the same runtime model (xi = 1, 185 degrees, 1024x1024), both ways: ours (:func:`build_lut`
   + :func:`remap`) and ``cv2.omnidir.initUndistortRectifyMap`` (RECTIFY_STEREOGRAPHIC: the xi = 1
   model, with the axes turned and the focal halved to our convention, :func:`cv2_stereographic_maps`,
   one call as a user would write it) + ``cv2.remap``. For this pair :func:`build_lut` itself calls
   OpenCV (:mod:`probeless.cameras.undistort_cv2`: the same function on row bands in parallel threads,
   then positions off the source image marked; ``build_path`` says which path it took); our own-model
   table (``build_lut(..., use_opencv=False)``) is timed too (``build_ms.own_models``). Both tables and
   both outputs are compared (the gate: ``map_agreement_px`` <= ``MAP_GATE_PX``, ``output_max_abs_diff``
   <= 1 level), and the table against our own models' float64 positions (``own_model_agreement_px``);
   ``undistort_build_ratio`` = our build / OpenCV's, ``undistort_remap_ratio`` = our per-frame remap /
   OpenCV's, each the best of ``repeats`` alternating runs (load drift hits both alike).

Times of part 1 are medians of several runs; those of part 2 best-of-N. Without ``--json`` the figures
are printed as indented JSON; ``--quick``: fewer repeats.
"""

from __future__ import annotations

import json
import statistics
import time

import cv2
import numpy as np

from probeless.bench.common import emit
from probeless.cameras import OcamModel, OmnidirModel
from probeless.cameras.base import CameraModel
from probeless.cameras.io import load_calibration
from probeless.cameras.undistort import (
    OUTSIDE,
    build_lut,
    maps_from_positions,
    remap,
    sample_positions,
    undistort_direct,
)
from probeless.cameras.undistort_cv2 import STEREO_R, opencv_lut
from probeless.jsonio import json_safe
from probeless.paths import SHARED_DATA

OCAM_FILE = SHARED_DATA / "fisheye" / "ocamcalib" / "calib_results_fisheye.txt"
SIZE = 1024
MAP_GATE_PX = 1e-3  # max |our table - OpenCV's table| [px] over destination pixels inside the source
MEI_K = np.array([[330.0, 0.0, 511.5], [0.0, 331.0, 512.3], [0.0, 0.0, 1.0]])
MEI_XI, MEI_D = 1.1, np.array([-0.25, 0.07, 2e-4, -1e-4])
UNDISTORT_REFERENCE = ("cv2.omnidir.initUndistortRectifyMap (RECTIFY_STEREOGRAPHIC, float32 maps) + cv2.remap, "
                       "same Mei source, same 1024x1024 xi=1 output")


def ocam_source(size: int = SIZE) -> OcamModel:
    """The shared OCamCalib sample calibration, re-centred on a size x size frame."""
    info = load_calibration(OCAM_FILE)
    centre = ((size - 1) / 2, (size - 1) / 2)
    return OcamModel(size, size, info.ocam_poly, info.ocam_invpoly, centre, info.ocam_affine)


def synthetic_frame(src: CameraModel) -> np.ndarray:
    """rgb8 fisheye frame of a lon/lat checkerboard with colour ramps, rendered through ``src``."""
    rays, valid = src.unproject(src.pixel_grid())
    rays = np.where(valid[:, None], rays, 0.0)
    lon = np.degrees(np.arctan2(rays[:, 0], rays[:, 2]))
    lat = np.degrees(np.arcsin(np.clip(-rays[:, 1], -1, 1)))
    checker = ((np.floor(lon / 15) + np.floor(lat / 15)) % 2).astype(np.float64)
    rgb = np.stack([128 + 100 * checker, 128 + lon * 0.7, 128 + lat * 1.4], axis=1)
    rgb[~valid] = 0
    return np.clip(rgb, 0, 255).astype(np.uint8).reshape(src.height, src.width, 3)


def effective_positions(lut: tuple[np.ndarray, np.ndarray], src: CameraModel) -> np.ndarray:
    """(H, W, 2) positions cv2.remap really samples: remap an image holding its own (u, v) coordinates.

    Bilinear interpolation of a linear ramp is exact, so this includes cv2's 1/32 px quantisation;
    valid where the position lies inside [0, W - 1] x [0, H - 1] (elsewhere black border mixes in).
    """
    u, v = np.meshgrid(np.arange(src.width, dtype=np.float32), np.arange(src.height, dtype=np.float32))
    return remap(np.stack([u, v], axis=-1), lut).astype(np.float64)


def _median_ms(fn, repeats: int) -> float:
    """Median wall time of ``repeats`` calls of ``fn`` [ms]."""
    times = []
    for _ in range(max(1, repeats)):
        t0 = time.perf_counter()
        fn()
        times.append((time.perf_counter() - t0) * 1e3)
    return statistics.median(times)


def _timed_ms(fn, *args):
    """(``fn(*args)``, its wall time [ms])."""
    t0 = time.perf_counter()
    out = fn(*args)
    return out, (time.perf_counter() - t0) * 1e3


def _alternating_ms(fns: dict, repeats: int) -> dict[str, list[float]]:
    """Wall times [ms] of each function in ``fns``, called in turn ``repeats`` times (load drift hits all alike)."""
    times = {k: [] for k in fns}
    for _ in range(max(1, repeats)):
        for k, fn in fns.items():
            times[k].append(_timed_ms(fn)[1])
    return times


def cv2_stereographic_maps(src: OmnidirModel, dst: OmnidirModel) -> tuple[np.ndarray, np.ndarray]:
    """OpenCV's table for ``src`` (Mei: K, xi, D) -> ``dst`` (ideal omnidir, xi = 1, no skew), float32.

    RECTIFY_STEREOGRAPHIC is the xi = 1 projection with m = 2 x / (1 + z) (ours: x / (1 + z)) and its
    centre ray along -y: hence the halved focal lengths and the rotation :data:`STEREO_R`."""
    if abs(dst.xi - 1.0) > 1e-12 or len(dst.D) or dst.K[0, 1] != 0:
        raise ValueError("cv2_stereographic_maps: the destination must be an ideal omnidir model, xi = 1, no skew")
    P = np.array(dst.K, np.float64)
    P[0, 0] /= 2.0
    P[1, 1] /= 2.0
    return cv2.omnidir.initUndistortRectifyMap(np.asarray(src.K, np.float64), np.asarray(src.D, np.float64)
                                               .reshape(1, 4), np.array([float(src.xi)]), STEREO_R, P,
                                               (dst.width, dst.height), cv2.CV_32FC1,
                                               cv2.omnidir.RECTIFY_STEREOGRAPHIC)


def rig_case(repeats: int) -> dict:
    """Part 1 of the module doc: the OCam source into the runtime model, absolute costs and sampling."""
    src, dst = ocam_source(), OmnidirModel.from_fov(SIZE, SIZE, 185.0, xi=1.0)
    frame = synthetic_frame(src)
    builds = [_timed_ms(build_lut, src, dst) for _ in range(max(1, repeats // 3))]
    lut = builds[-1][0]
    remap(frame, lut)  # warm-up (cv2 thread pool, caches)
    exact = sample_positions(src, dst)
    used = effective_positions(lut, src)
    interior = ((exact >= 0) & (exact <= np.array([src.width - 1, src.height - 1]))).all(axis=-1)
    diff = np.linalg.norm(used - exact, axis=-1)[interior]
    out_lut = remap(frame, lut).astype(np.float64)
    return {"source": "ocam (shared sample calibration, centred)", "target": "omnidir xi=1 fov=185 deg, 1024x1024",
            "lut_build_ms": statistics.median(t for _, t in builds),
            "remap_ms": _median_ms(lambda: remap(frame, lut), 5 * repeats),
            "max_px_diff": float(diff.max()), "max_px_diff_pixels": int(interior.sum()),
            "mean_abs_diff": float(np.abs(out_lut - undistort_direct(frame, src, dst)).mean())}


def reference_case(repeats: int) -> dict:
    """Part 2 of the module doc: ours vs OpenCV on the same Mei -> xi = 1 mapping, tables and outputs gated."""
    src = OmnidirModel(SIZE, SIZE, MEI_K, MEI_XI, MEI_D)
    dst = OmnidirModel.from_fov(SIZE, SIZE, 185.0, xi=1.0)
    frame = synthetic_frame(src)
    theirs, ours = cv2_stereographic_maps(src, dst), build_lut(src, dst)
    exact = sample_positions(src, dst)
    inside = np.isfinite(exact).all(axis=-1)
    agree = float(np.hypot(ours[0] - theirs[0], ours[1] - theirs[1])[inside].max())
    own = float(np.hypot(ours[0] - exact[..., 0], ours[1] - exact[..., 1])[inside].max())
    same_outside = bool(np.array_equal(ours[0] <= OUTSIDE, maps_from_positions(exact)[0] <= OUTSIDE))
    out_ours, out_cv2 = remap(frame, ours), cv2.remap(frame, *theirs, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)
    out_diff = np.abs(out_ours.astype(np.int16) - out_cv2.astype(np.int16))
    n = 5 * repeats
    builds = _alternating_ms({"ours": lambda: build_lut(src, dst), "cv2": lambda: cv2_stereographic_maps(src, dst)}, n)
    builds["own_models"] = _alternating_ms({"own": lambda: build_lut(src, dst, use_opencv=False)},
                                           max(1, repeats // 3))["own"]
    frames = _alternating_ms({"ours": lambda: remap(frame, ours), "cv2": lambda: cv2.remap(
        frame, *theirs, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)}, n)
    build = {k: min(v) for k, v in builds.items()}
    per_frame = {k: min(v) for k, v in frames.items()}
    gate_met = bool(agree <= MAP_GATE_PX and int(out_diff.max()) <= 1 and own <= MAP_GATE_PX and same_outside)
    return {"source": f"omnidir (Mei) xi={MEI_XI}, D={MEI_D.tolist()}, 1024x1024",
            "target": "omnidir xi=1 fov=185 deg, 1024x1024", "undistort_reference": UNDISTORT_REFERENCE,
            "build_path": "opencv" if opencv_lut(src, dst) is not None else "own_models",
            "output_shapes": {"ours": list(out_ours.shape), "cv2": list(out_cv2.shape)},
            "build_ms": build, "remap_ms": per_frame, "build_ms_median": {k: statistics.median(v)
                                                                          for k, v in builds.items()},
            "timing": f"best of {n} alternating runs (own_models: best of {len(builds['own_models'])})",
            "undistort_build_ratio": build["ours"] / build["cv2"],
            "undistort_build_speedup": build["cv2"] / build["ours"],
            "undistort_remap_ratio": per_frame["ours"] / per_frame["cv2"],
            "ratio_definition": "ours / OpenCV time (> 1: ours slower); undistort_build_speedup = OpenCV / ours",
            "map_agreement_px": agree, "map_agreement_pixels": int(inside.sum()),
            "own_model_agreement_px": own, "outside_pixels_equal_own_models": same_outside,
            "output_max_abs_diff": int(out_diff.max()), "output_mean_abs_diff": float(out_diff.mean()),
            "gate": {"map_agreement_px_max": MAP_GATE_PX, "output_max_abs_diff_max": 1,
                     "own_model_agreement_px_max": MAP_GATE_PX}, "gate_met": gate_met}


def measure(quick: bool = False) -> dict:
    """Both parts of the module doc; see there for the keys."""
    repeats = 3 if quick else 9
    rig, ref = rig_case(repeats), reference_case(repeats)
    return {"frame": f"{SIZE}x{SIZE} rgb8", **rig, "reference": ref,
            "undistort_reference": ref["undistort_reference"],
            "undistort_build_ratio": ref["undistort_build_ratio"],
            "undistort_build_speedup": ref["undistort_build_speedup"], "build_path": ref["build_path"],
            "undistort_remap_ratio": ref["undistort_remap_ratio"], "gate_met": ref["gate_met"],
            "repeats": repeats, "cv2_threads": cv2.getNumThreads()}


def print_table(result: dict) -> None:
    """The figures as indented JSON."""
    print(json.dumps(json_safe(result), indent=2))


def main(json_out: bool = False, quick: bool = False) -> int:
    """Measure; indented JSON, or exactly one JSON line with ``json_out``. 0 always (figures, not a test)."""
    emit(measure(quick=quick), json_out, print_table)
    return 0


if __name__ == "__main__":
    from probeless.bench.common import module_main

    raise SystemExit(module_main(__spec__.name))
