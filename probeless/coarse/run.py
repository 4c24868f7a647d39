"""Offline coarse-model run: every frame of a source through brightness estimation and the texturer.

The same steps the ``brightness_estimator`` and ``coarse_texturer`` nodes take in a graph, in one
process and in order: Δ of frame k against the atlas after frame k-1 (read back as RGBA8, as the
texturer publishes it), then the texture update with that Δ.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from probeless.coarse.brightness import DEADBAND, apply_deadband, draw_sample, estimate_delta
from probeless.coarse.frames import FisheyeFrame, FrameSource
from probeless.coarse.model import CoarseConfig, CoarseModel
from probeless.progress import progress


@dataclass
class FrameRecord:
    """What one frame did."""

    stamp_ns: int
    t_s: float
    delta: np.ndarray             # (3,) Δ applied [0..1 camera units]
    texels_used: int              # texels behind Δ [count]
    inpainted: bool               # inpainting ran after this frame
    timings_ms: dict[str, float] = field(default_factory=dict)


def run_coarse(source: FrameSource, config: CoarseConfig, *, use_delta: bool = True, samples: int = 65536,
               on_frame: Callable[[CoarseModel, FisheyeFrame, FrameRecord], None] | None = None,
               deadband: float = DEADBAND, show_progress: bool = True,
               model: CoarseModel | None = None) -> tuple[CoarseModel, list[FrameRecord]]:
    """Texture the room from every frame of ``source``; ``on_frame`` sees the model after each one."""
    ctx = source.rig.renderer.ctx if source.rig is not None else None
    model = model or CoarseModel(source.floorplan, source.ceiling_height, config, ctx=ctx)
    sample = draw_sample(model.texmap, samples, seed=0)
    records: list[FrameRecord] = []
    with progress(source.count, f"coarse model: {source.name}", enabled=show_progress) as tick:
        for frame in source.frames:
            delta, used, t_delta = np.zeros(3, np.float32), 0, 0.0
            if use_delta and model.frames > 0:
                packed = model.gpu.read_packed()
                t0 = time.perf_counter()
                delta, used = estimate_delta(packed[..., :3], packed[..., 3] > 0, model.texmap, frame.image,
                                             source.model, frame.world_from_fisheye, config.fov_deg,
                                             source.floorplan, sample_idx=sample)
                delta = apply_deadband(delta, deadband)
                t_delta = (time.perf_counter() - t0) * 1e3
            inpainted = model.step(frame.image, source.model, frame.world_from_fisheye, delta, frame.t_s)
            timings = {k: v[-1] for k, v in model.timings_ms.items() if v}
            timings["brightness"] = t_delta
            rec = FrameRecord(frame.stamp_ns, frame.t_s, np.asarray(delta), used, inpainted, timings)
            records.append(rec)
            if on_frame is not None:
                on_frame(model, frame, rec)
            tick()
    return model, records
