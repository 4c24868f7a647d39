"""The diffuse map accuracy table and its picture rows (``probeless eval diffuse``, :mod:`probeless.eval.diffuse`).

Uses :mod:`probeless.pano.diffuse_eval` (the exact reference, the method names); that module does not
import this one.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

import numpy as np

from probeless.color import linear_to_srgb
from probeless.pano.diffuse_eval import METHODS, TIMED, exact_diffuse
from probeless.pano.sources import read_panorama


def tonemap(x: np.ndarray, exposure: float) -> np.ndarray:
    """Display RGB 0..1 of linear radiance: Reinhard ``y / (1 + y)`` of ``y = exposure * x``, sRGB."""
    y = np.asarray(x, np.float64) * exposure
    return linear_to_srgb(y / (1.0 + y))


def diffuse_figure(hdr: Any, out_png: str | Path, out_size: tuple[int, int] = (32, 16),
                   gpu_in_size: tuple[int, int] = (128, 64)) -> Path:
    """PNG with one row per panorama (``hdr``: an array or path, or a list of them): the input
    tone-mapped, the GPU map, the exact full-resolution map, the SH9 map (all at ``out_size``, shown
    with bilinear filtering, same exposure) and the relative error [%] of the GPU map and of its
    radiance-moments variant."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from probeless.pano.diffuse import sh9_irradiance_map
    from probeless.pano.gpu_diffuse import GpuDiffuse

    items = list(hdr) if isinstance(hdr, (list, tuple)) else [hdr]
    gpu = GpuDiffuse(None, out_size, gpu_in_size)
    moments = GpuDiffuse(gpu.ctx, out_size, gpu_in_size, weights="moments")
    fig, axes = plt.subplots(len(items), 6, figsize=(21, 2.3 * len(items)), squeeze=False)
    for row, item in zip(axes, items):
        name = Path(item).name if isinstance(item, (str, Path)) else ""
        img = read_panorama(str(item)) if isinstance(item, (str, Path)) else np.asarray(item, np.float32)
        exact = exact_diffuse(img, out_size)
        maps = [gpu.apply(img), exact, sh9_irradiance_map(img, out_size)]
        exposure = 1.0 / max(float(np.mean(exact)), 1e-12)  # the diffuse map's mean radiance -> 0.5
        titles = [f"{name} (tone-mapped)", "GPU Algorithm 1", "exact, full resolution", "SH9"]
        for ax, pic, title in zip(row, [img] + maps, titles):
            ax.imshow(tonemap(np.clip(pic, 0, None), exposure), interpolation="bilinear")
            ax.set_title(title, fontsize=9)
        for ax, fast, label in ((row[4], maps[0], "GPU"), (row[5], moments.apply(img), "GPU moments")):
            rel = 100.0 * np.max(np.abs(fast - exact) / np.maximum(exact, 1e-12), axis=2)
            im = ax.imshow(rel, cmap="magma", interpolation="nearest")
            ax.set_title(f"{label} rel. error [%], max {rel.max():.3f}", fontsize=9)
            fig.colorbar(im, ax=ax, fraction=0.025)
        for ax in row:
            ax.set_xticks([]), ax.set_yticks([])
    moments.release()
    gpu.release()
    fig.tight_layout()
    out = Path(out_png)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=90)
    plt.close(fig)
    return out


def format_table(summary: dict[str, dict[str, Any]], sizes: Sequence[tuple[int, int]]) -> str:
    """A text table of :func:`~probeless.pano.diffuse_eval.summarize`'s output: per size and method the
    worst max / average mean relative error; the median time [ms] of each timed method and of the exact
    reference, and each method's speed-up over that reference (``*`` where the error gate is not met)."""
    lines = [f"{'size':<8}" + "".join(f"{m + ' max / mean':>25}" for m in METHODS)
             + "".join(f"{m + ' ms':>15}" for m in TIMED) + f"{'exact ms':>10}"
             + "".join(f"{m + ' x':>15}" for m in TIMED)]
    for w, h in sizes:
        e = summary[f"{w}x{h}"]
        errs = "".join(f"{e[m + '_max_rel_error']:>14.2e} / {e[m + '_mean_rel_error']:.2e}" for m in METHODS)
        times = "".join(f"{e[m + '_s'] * 1e3:>15.1f}" for m in TIMED) + f"{e['exact_s'] * 1e3:>10.1f}"
        gains = "".join(f"{e[m + '_speedup']:>14.2f}{' ' if e[m + '_gate_met'] else '*'}" for m in TIMED)
        lines.append(f"{f'{w}x{h}':<8}{errs}{times}{gains}")
    lines.append("x: speed-up over the exact FFT convolution (same frame, same map); *: max error above the gate")
    return "\n".join(lines)
