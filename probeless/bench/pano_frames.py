"""Per-frame timings of the 360° IBL pipeline's stages for ``probeless bench pano`` (:mod:`probeless.bench.pano`).

Frames come from the shipped video (decoded before anything is timed) or, if it is missing, a
synthetic sky frame. Frame 0 is a warm-up (shader compiles, weight caches), left out of every list.
"""

from __future__ import annotations

import contextlib
import time
from pathlib import Path

import numpy as np

from probeless.paths import SHARED_DATA

VIDEO = SHARED_DATA / "video360" / "bled_lake_360_timelapse_720p_vp9.webm"
SMALL, DIFFUSE = (128, 64), (32, 16)
MONO, FOV_DEG = (1280, 720), 90.0
NUMPY_ITMOS = ("paper", "landis", "akyuz", "banterle")


def stats(values: list[float]) -> dict:
    """mean, p50, p95 and count of per-frame timings [ms]."""
    a = np.asarray(values, np.float64)
    if a.size == 0:
        return {"mean": float("nan"), "p50": float("nan"), "p95": float("nan"), "n": 0}
    return {"mean": float(a.mean()), "p50": float(np.median(a)), "p95": float(np.percentile(a, 95)), "n": int(a.size)}


def ms(fn, *args, **kwargs):
    """(``fn(*args, **kwargs)``, its wall time [ms])."""
    t0 = time.perf_counter()
    out = fn(*args, **kwargs)
    return out, (time.perf_counter() - t0) * 1e3


def best_ms(fn, repeats: int):
    """(the last result of ``fn()``, the least of ``repeats`` wall times [ms])."""
    runs = [ms(fn) for _ in range(max(1, repeats))]
    return runs[-1][0], min(t for _, t in runs)


def synthetic_frame(width: int = 1280, height: int = 640) -> np.ndarray:
    """(H, W, 3) uint8 stand-in 360° frame: sky gradient, a clipped sun, a darker ground."""
    from probeless.pano.equirect import pixel_directions

    d = pixel_directions(width, height)
    sun = np.array([0.6, 0.3, 0.74]) / np.linalg.norm([0.6, 0.3, 0.74])
    sky = np.where(d[..., 2:] > 0, [0.35, 0.55, 0.9], [0.35, 0.3, 0.25]) * (0.6 + 0.4 * np.abs(d[..., 2:]))
    sky = sky + 2.0 * np.exp(40.0 * (d @ sun - 1.0))[..., None]
    return np.round(np.clip(sky, 0, 1) * 255).astype(np.uint8)


def load_frames(n: int, path: Path = VIDEO) -> tuple[list[np.ndarray], str]:
    """The first ``n`` frames of the video (decoded now, off the clock) and what they are; ``n`` copies
    of :func:`synthetic_frame` if the file is missing (the description says so)."""
    from probeless.pano.sources import VideoFrames

    if not path.is_file():
        return [synthetic_frame()] * n, f"synthetic 1280x640 frame (video file missing: {path})"
    frames = []
    with VideoFrames(str(path)) as video:
        for _, _, rgb in video:
            frames.append(rgb)
            if len(frames) == n:
                break
    return frames, f"{path.name}: first {len(frames)} frames, {frames[0].shape[1]}x{frames[0].shape[0]}"


def time_lighting(frames: list[np.ndarray], ctx, tick) -> tuple[dict, list, list]:
    """Per-frame ITMO and diffuse map times [ms] (frame 0 left out); the HDR frames and diffuse maps."""
    from probeless.pano import itmo
    from probeless.pano.diffuse import diffuse_map
    from probeless.pano.gpu_diffuse import GpuDiffuse
    from probeless.pano.gpu_itmo import GpuItmo

    gpu_itmo, gpu_diffuse = GpuItmo(ctx, "paper"), GpuDiffuse(ctx, DIFFUSE, SMALL)
    t: dict[str, list[float]] = {k: [] for k in ("itmo_gpu_paper", "diffuse_gpu_32x16", "diffuse_matmul_32x16",
                                                 *(f"itmo_numpy_{op}" for op in NUMPY_ITMOS))}
    hdrs, diffs = [], []
    for k, rgb in enumerate(frames):
        (hdr, small), t_gpu = ms(gpu_itmo.run, rgb, SMALL, np.float16)
        row = {"itmo_gpu_paper": t_gpu}
        for op in NUMPY_ITMOS:
            ldr = rgb.astype(np.float32) / np.float32(255.0)
            row[f"itmo_numpy_{op}"] = ms(itmo.apply_itmo, op, ldr if op == "paper" else itmo.gamma_decode(ldr))[1]
        diff, row["diffuse_gpu_32x16"] = ms(gpu_diffuse.apply, small)
        row["diffuse_matmul_32x16"] = ms(diffuse_map, small, DIFFUSE)[1]
        if k > 0:
            for key, v in row.items():
                t[key].append(v)
        hdrs.append(hdr)
        diffs.append(diff)
        tick()
    gpu_itmo.release()
    gpu_diffuse.release()
    return t, hdrs, diffs


def make_renderer(ctx):
    """A PanoRenderer with the ``pano_compositor``'s five default objects."""
    from probeless.ibl.objects import object_from_dict
    from probeless.pano.objects import DEFAULT_OBJECTS, resolve_mesh
    from probeless.pano.render import PanoRenderer

    objects = [object_from_dict(resolve_mesh(o), f"objects[{i}]") for i, o in enumerate(DEFAULT_OBJECTS)]
    return PanoRenderer(objects, ctx=ctx), len(objects)


def time_compositing(renderer, frames, hdrs, diffs, stereo_frames: int, tick) -> dict[str, list[float]]:
    """Per-frame upload and mono / stereo view times [ms] and their stages (frame 0 left out)."""
    from probeless.pano.composite import render_view
    from probeless.pano.view import HMD_EYE_SIZE, head_pose

    t: dict[str, list[float]] = {}
    for k, (rgb, hdr, diff) in enumerate(zip(frames, hdrs, diffs)):
        pose = head_pose(k / 30.0, yaw0_deg=-5.0, yaw_deg_per_s=5.0, pitch_deg=-8.0, pitch_amp_deg=2.0)
        _, t_up = ms(lambda: (renderer.set_environment(hdr, diff), renderer.set_background(rgb)))
        stages: dict[str, float] = {"upload": t_up}
        _, stages["mono_view"] = ms(render_view, renderer, pose, FOV_DEG, *MONO, timed=_stages(stages, "mono"))
        if k < stereo_frames:
            _, stages["stereo_view"] = ms(render_view, renderer, pose, FOV_DEG, *HMD_EYE_SIZE, stereo=True,
                                           timed=_stages(stages, "stereo"))
        for key, v in stages.items() if k > 0 else ():
            t.setdefault(key, []).append(v)
        tick()
    return t


def _stages(into: dict[str, float], prefix: str):
    """A ``timed(stage)`` context manager factory adding each stage's time [ms] to ``into[prefix_stage]``
    (the two eyes of a stereo frame add up)."""
    @contextlib.contextmanager
    def timed(stage: str):
        t0 = time.perf_counter()
        yield
        key = f"{prefix}_{stage}"
        into[key] = into.get(key, 0.0) + (time.perf_counter() - t0) * 1e3
    return timed
