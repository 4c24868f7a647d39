"""``probeless bench sensors``: synthetic rig render rate, and LUT undistortion against per-pixel model evaluation.

1. **Rig render rate** on the default scene (``launch/scenes/l_shaped_lounge.yaml``: 640x480 RGB-D,
   1024x1024 omnidir fisheye through a 512 cubemap, one 64-texel ground-truth cubemap per fisheye
   frame): frames rendered back to back after one warm-up frame of each kind; RGB-D frames/s (colour
   + depth + pose), fisheye frames/s without and with the ground-truth cubemaps, and the share of a
   frame spent in the GPU renderer (llvmpipe on this machine: the CPU).
2. **Undistortion** (``probeless.bench.undistort``): a 1024x1024 fisheye frame converted to the
   runtime omnidir model: the one-off table build and the per-frame ``cv2.remap``, absolute
   (``max_px_diff`` = largest difference of the sampling positions, goal <= 0.5 px); and the same
   kind of mapping against ``cv2.omnidir.initUndistortRectifyMap`` + ``cv2.remap``
   (``undistort_reference``): ``undistort_build_ratio`` and ``undistort_remap_ratio`` (ours / OpenCV),
   ``undistort_build_speedup`` (OpenCV / ours; ``speed_goals_met`` against issue 30's >= 1.0, kept apart
   from ``goals_met``, the accuracy gates), with the gate on the agreement of the two tables and outputs.

``--json`` prints exactly one JSON object on stdout; progress goes to stderr.
"""

from __future__ import annotations

import json
import platform
import time

import numpy as np

from probeless.bench.common import emit, log, rounded
from probeless.paths import REPO_ROOT

SCENE = REPO_ROOT / "launch" / "scenes" / "l_shaped_lounge.yaml"
GOALS = {"max_px_diff_max": 0.5, "reference_gate_met": True}
SPEED_GOALS = {"undistort_build_speedup_min": 1.0}  # issue 30: the table build at >= 1.0x OpenCV's


def _rate(fn, events) -> tuple[float, float]:
    """(frames per second, median seconds per frame) of ``fn`` over ``events``."""
    times = []
    for event in events:
        t0 = time.perf_counter()
        fn(event)
        times.append(time.perf_counter() - t0)
    return len(times) / sum(times), float(np.median(times))


def bench_rig(quick: bool) -> dict:
    """Render rates of the default scene."""
    from probeless.scene.parse import load_scene
    from probeless.scene.rig import FISHEYE_FRAME, RGBD_FRAME, Rig, frame_schedule

    scene = load_scene(SCENE)
    events = frame_schedule(scene)
    rgbd = [e for e in events if e.kind == RGBD_FRAME][: 6 if quick else 30]
    fish = [e for e in events if e.kind == FISHEYE_FRAME][: 3 if quick else 12]
    t0 = time.perf_counter()
    rig = Rig(scene)
    setup_s = time.perf_counter() - t0
    rig.render_rgbd(rgbd[0])
    list(rig.messages(fish[0]))  # warm-up: shader compilation, texture uploads
    log(f"rig: {len(rgbd)} RGB-D and {len(fish)} fisheye frames of {scene.name}")
    rgbd_fps, rgbd_s = _rate(rig.render_rgbd, rgbd)
    fish_fps, fish_s = _rate(rig.render_fisheye, fish)
    full_fps, _ = _rate(lambda e: list(rig.messages(e)), fish)
    rig.release()
    return {"scene": scene.name, "setup_s": setup_s, "rgbd_fps": rgbd_fps, "rgbd_ms": rgbd_s * 1e3,
            "fisheye_fps": fish_fps, "fisheye_ms": fish_s * 1e3, "fisheye_with_gt_envmaps_fps": full_fps,
            "rgbd_size": [scene.rgbd.width, scene.rgbd.height],
            "fisheye_size": [scene.fisheye.width, scene.fisheye.height]}


def main(json_out: bool = False, quick: bool = False) -> int:
    from probeless.bench.undistort import measure as bench_undistort

    rig = bench_rig(quick)
    log(f"rig: RGB-D {rig['rgbd_fps']:.1f} frames/s, fisheye {rig['fisheye_fps']:.1f} frames/s")
    und = bench_undistort(quick=quick)
    log(f"undistort: table build {und['lut_build_ms']:.0f} ms once, remap {und['remap_ms']:.2f} ms per frame, "
        f"max sampling difference {und['max_px_diff']:.3g} px; vs OpenCV ({und['build_path']} path): build "
        f"x{und['undistort_build_ratio']:.2f} (speed-up {und['undistort_build_speedup']:.2f}), "
        f"remap x{und['undistort_remap_ratio']:.2f}, gate met {und['gate_met']}")
    result = {"benchmark": "sensors", "quick": quick, "machine": platform.machine(), "rig": rig, "undistort": und,
              "undistort_reference": und["undistort_reference"],
              "undistort_build_ratio": und["undistort_build_ratio"],
              "undistort_build_speedup": und["undistort_build_speedup"],
              "undistort_remap_ratio": und["undistort_remap_ratio"], "goals": GOALS,
              "goals_met": bool(und["max_px_diff"] <= GOALS["max_px_diff_max"] and und["gate_met"]),
              "speed_goals": SPEED_GOALS, "speed_goals_met": {
                  "undistort_build_speedup": bool(und["undistort_build_speedup"]
                                                  >= SPEED_GOALS["undistort_build_speedup_min"])}}
    emit(rounded(result), json_out, print_table)
    return 0


def print_table(result: dict) -> None:
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    from probeless.bench.common import module_main

    raise SystemExit(module_main(__spec__.name))
