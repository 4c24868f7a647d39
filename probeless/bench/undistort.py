"""``probeless bench undistort``: fisheye undistortion by precomputed LUT + cv2.remap vs direct per-pixel model
evaluation (also part of ``probeless bench sensors``).

One synthetic 1024x1024 rgb8 fisheye frame from an OCamCalib source (the real sample calibration,
centred on the frame) is converted to the runtime model (ideal omnidir, xi = 1, 185 degrees,
1024x1024). Both paths run side by side in this process, alternating, and the median of several
repeats is reported:

* ``direct_ms``: :func:`undistort_direct`: both models evaluated for all pixels, then cv2.remap;
* ``lut_ms``: :func:`remap` through the float32 LUT built once (``lut_build_s``);
* ``max_px_diff``: the largest distance between the positions the LUT remap really samples and the
  direct float64 model positions [px] (goal <= 0.5), over the ``max_px_diff_pixels`` destination
  pixels that sample the source interior; ``mean_abs_diff``: mean |LUT output - direct output|
  [8-bit levels] over the whole frame.

Without ``--json`` the figures are printed as indented JSON; ``--quick``: fewer repeats.
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
from probeless.cameras.undistort import build_lut, remap, sample_positions, undistort_direct
from probeless.jsonio import json_safe
from probeless.paths import SHARED_DATA

OCAM_FILE = SHARED_DATA / "fisheye" / "ocamcalib" / "calib_results_fisheye.txt"
SIZE = 1024


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


def _time_ms(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return (time.perf_counter() - t0) * 1e3


def measure(quick: bool = False) -> dict:
    """Measure LUT vs direct undistortion side by side; see the module docstring for the keys."""
    repeats = 3 if quick else 9
    src = ocam_source()
    dst = OmnidirModel.from_fov(SIZE, SIZE, 185.0, xi=1.0)
    frame = synthetic_frame(src)

    builds = []
    for _ in range(1 if quick else 3):
        t0 = time.perf_counter()
        lut = build_lut(src, dst)
        builds.append(time.perf_counter() - t0)

    remap(frame, lut), undistort_direct(frame, src, dst)  # warm-up (cv2 thread pool, caches)
    direct, lut_times = [], []
    for _ in range(repeats):
        direct.append(_time_ms(lambda: undistort_direct(frame, src, dst)))
        lut_times.append(statistics.median(_time_ms(lambda: remap(frame, lut)) for _ in range(5)))

    exact = sample_positions(src, dst)
    used = effective_positions(lut, src)
    interior = ((exact >= 0) & (exact <= np.array([src.width - 1, src.height - 1]))).all(axis=-1)
    diff = np.linalg.norm(used - exact, axis=-1)[interior]
    out_lut = remap(frame, lut).astype(np.float64)
    out_direct = undistort_direct(frame, src, dst).astype(np.float64)

    direct_ms, lut_ms = statistics.median(direct), statistics.median(lut_times)
    return {
        "frame": f"{SIZE}x{SIZE} rgb8",
        "source": "ocam (shared sample calibration, centred)",
        "target": "omnidir xi=1 fov=185 deg, 1024x1024",
        "lut_build_s": statistics.median(builds),
        "direct_ms": direct_ms,
        "lut_ms": lut_ms,
        "undistort_speedup": direct_ms / lut_ms,
        "max_px_diff": float(diff.max()),
        "max_px_diff_pixels": int(interior.sum()),
        "mean_abs_diff": float(np.abs(out_lut - out_direct).mean()),
        "repeats": repeats,
        "cv2_threads": cv2.getNumThreads(),
    }


def print_table(result: dict) -> None:
    print(json.dumps(json_safe(result), indent=2))


def main(json_out: bool = False, quick: bool = False) -> int:
    """Measure; indented JSON, or exactly one JSON line with ``json_out``. 0 always (figures, not a test)."""
    emit(measure(quick=quick), json_out, print_table)
    return 0


if __name__ == "__main__":
    from probeless.bench.common import module_main

    raise SystemExit(module_main(__spec__.name))
