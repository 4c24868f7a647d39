"""Accuracy of the coarse texture on synthetic scenes against the true surface colours (:mod:`.truth`).

Per evaluated frame, the mean absolute error (0..255 camera units, over RGB) of core texels that
are: ``in_view`` (updated from this frame), ``stale`` (observed before, out of view now: they
rely on Δ to follow lighting changes), ``inpainted`` (never observed, filled by Telea); plus the
signed mean of ``stale`` (a brightness bias) and the observed / inpainted coverage.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from probeless.coarse.frames import scene_source
from probeless.coarse.model import INPAINTED_S, CoarseConfig
from probeless.coarse.run import run_coarse
from probeless.coarse.truth import true_atlas


def texel_errors(rgb: np.ndarray, last_seen: np.ndarray, truth: np.ndarray, core: np.ndarray,
                 t_s: float) -> dict[str, float]:
    """Error statistics of one atlas state (module doc); NaN for an empty class."""
    diff = (np.clip(rgb, 0, 1) - truth) * 255.0
    err = np.abs(diff).mean(axis=2)
    observed = core & (last_seen >= 0)
    in_view = observed & (last_seen == np.float32(t_s))
    classes = {"in_view": in_view, "stale": observed & ~in_view, "inpainted": core & (last_seen == INPAINTED_S)}
    out = {name: float(err[m].mean()) if m.any() else float("nan") for name, m in classes.items()}
    stale = classes["stale"]
    out["stale_bias"] = float(diff[stale].mean()) if stale.any() else float("nan")
    out["observed_fraction"] = float(observed.sum() / core.sum())
    out["inpainted_fraction"] = float(classes["inpainted"].sum() / core.sum())
    return out


@dataclass
class EvalRun:
    """Errors over time of one run."""

    use_delta: bool
    t_s: list[float] = field(default_factory=list)
    errors: list[dict[str, float]] = field(default_factory=list)
    delta: list[list[float]] = field(default_factory=list)   # Δ per evaluated frame [0..255]

    def series(self, key: str) -> np.ndarray:
        return np.array([e[key] for e in self.errors])


def evaluate_scene(path: str | Path, *, duration: float | None = None, config: CoarseConfig | None = None,
                   use_delta: bool = True, every: int = 3, stride: int = 1, cube_size: int = 512,
                   show_progress: bool = True) -> EvalRun:
    """Run the coarse model over a scene with true poses; errors every ``every`` frames and at the last."""
    source = scene_source(path, duration, stride=stride, cube_size=cube_size)
    config = config or CoarseConfig(atlas_size=512, fov_deg=source.texture_fov_deg)
    rig, run = source.rig, EvalRun(use_delta)
    truths: dict[tuple, np.ndarray] = {}
    count = source.count

    def on_frame(model, frame, rec) -> None:
        k = model.frames - 1
        if k % every and k != count - 1:
            return
        key = tuple(np.round(frame.light_scale, 6))
        if key not in truths:
            truths[key] = true_atlas(rig.renderer, model.layout, frame.light_scale, rig.scene.fisheye.exposure)
        rgb, seen = model.atlas()
        run.t_s.append(frame.t_s)
        run.errors.append(texel_errors(rgb, seen, truths[key], model.texmap.core, frame.t_s))
        run.delta.append((np.asarray(rec.delta) * 255).tolist())

    model, _ = run_coarse(source, config, use_delta=use_delta, on_frame=on_frame, show_progress=show_progress)
    model.release()
    return run


def summarize(run: EvalRun, after_s: float | None = None) -> dict[str, float]:
    """Mean of each error over the evaluated frames (those at or after ``after_s`` when given), and the last."""
    keep = np.ones(len(run.t_s), bool) if after_s is None else np.asarray(run.t_s) >= after_s
    out = {}
    for key in ("in_view", "stale", "inpainted", "stale_bias"):
        vals = run.series(key)[keep]
        vals = vals[np.isfinite(vals)]
        out[f"{key}_mean"] = float(vals.mean()) if len(vals) else float("nan")
    out.update({f"final_{k}": v for k, v in run.errors[-1].items()})
    return out


def plot_runs(runs: list[EvalRun], path: str | Path, title: str, switch_s: float | None = None) -> None:
    """Error over time of each run (with / without Δ): stale, in view, inpainted, and the stale bias."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(12, 4.2))
    for run in runs:
        tag = "with Δ" if run.use_delta else "without Δ"
        style = "-" if run.use_delta else "--"
        for key, color in (("stale", "C0"), ("in_view", "C1"), ("inpainted", "C2")):
            axes[0].plot(run.t_s, run.series(key), style, color=color, label=f"{key} ({tag})")
        axes[1].plot(run.t_s, run.series("stale_bias"), style, color="C3", label=f"stale bias ({tag})")
    for ax in axes:
        if switch_s is not None:
            ax.axvline(switch_s, color="k", lw=0.8, ls=":")
        ax.set_xlabel("time [s]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    axes[0].set_ylabel("mean |texture - truth| [0..255]")
    axes[1].set_ylabel("mean (texture - truth) of stale texels [0..255]")
    fig.suptitle(title)
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
