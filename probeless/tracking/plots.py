"""Trajectory plots (PNG): estimated (rigidly aligned) vs true positions, and the ATE over time; fisheye pose errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np

VIEWS = ((0, 1, "top view (x-y)"), (0, 2, "side view (x-z)"), (1, 2, "side view (y-z)"))
AXES = "xyz"


def _sparse(n_gt: int, n_est: int) -> bool:
    """Ground truth for only a few of the frames: draw it as markers, not as a line."""
    return n_gt < max(20, n_est // 10)


def plot_trajectory(path: str | Path, *, t_s: np.ndarray, est_aligned: np.ndarray, gt_t_s: np.ndarray,
                    gt: np.ndarray, gt_est: np.ndarray, errors: np.ndarray, title: str) -> Path:
    """Write a 2x2 figure: three orthogonal views and the error over time.

    ``est_aligned`` (N, 3): every estimated position (after the ATE alignment) at times ``t_s``;
    ``gt`` (M, 3) true positions at ``gt_t_s`` with ``gt_est`` (M, 3) the aligned estimates at the
    same frames and ``errors`` (M,) their distances (m).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sparse = _sparse(len(gt), len(est_aligned))
    fig, axes = plt.subplots(2, 2, figsize=(11, 9))
    for ax, (a, b, name) in zip(axes.flat, VIEWS):
        ax.plot(est_aligned[:, a], est_aligned[:, b], "-", color="tab:blue", lw=1.2, label="estimated (aligned)")
        ax.plot(gt[:, a], gt[:, b], "o" if sparse else "-", color="black", lw=1.2, ms=5, mfc="none",
                label="ground truth")
        for p, q in zip(gt_est, gt):
            ax.plot([p[a], q[a]], [p[b], q[b]], "-", color="tab:red", lw=0.6, alpha=0.6)
        ax.plot([], [], "-", color="tab:red", lw=0.6, label="difference")
        ax.set_xlabel(f"{AXES[a]} [m]")
        ax.set_ylabel(f"{AXES[b]} [m]")
        ax.set_title(name)
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(True, alpha=0.3)
    axes.flat[0].legend(loc="best", fontsize=8)
    ax = axes.flat[3]
    ax.plot(gt_t_s, errors * 1000.0, "o-" if sparse else "-", color="tab:red", lw=1.0, ms=4)
    rmse = float(np.sqrt(np.mean(errors ** 2))) if len(errors) else float("nan")
    ax.axhline(rmse * 1000.0, color="gray", ls="--", lw=0.8, label=f"RMSE {rmse * 1000:.1f} mm")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("position error after alignment [mm]")
    ax.set_title(f"ATE over time ({len(errors)} frames with ground truth)")
    ax.legend(loc="best", fontsize=8)
    ax.grid(True, alpha=0.3)
    fig.suptitle(title)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def plot_fisheye_errors(name: str, errors: dict, out: str | Path) -> Path:
    """PNG of :func:`probeless.tracking.fisheye_eval.evaluate`'s errors (mode -> ModeErrors): rotation
    and translation error vs time (top) and their histograms (bottom), log scales."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    floor = {"rot_deg": 1e-6, "trans_mm": 1e-5}  # exact poses would vanish from a log axis
    fig, axes = plt.subplots(2, 2, figsize=(12, 7))
    for col, (key, label) in enumerate((("rot_deg", "rotation error [deg]"), ("trans_mm", "translation error [mm]"))):
        values = {m: np.maximum(getattr(e, key), floor[key]) for m, e in errors.items()}
        both = np.concatenate([v for v in values.values() if len(v)] or [np.array([floor[key], 1.0])])
        bins = np.geomspace(both.min(), max(both.max(), both.min() * 10), 40)
        for mode, e in errors.items():
            style = "--" if mode == "nearest" else "-"  # nearest and latest coincide when the offset is < half a period
            axes[0, col].plot(e.stamps_ns / 1e9, values[mode], style, marker=".", ms=3, lw=0.8, label=mode)
            axes[1, col].hist(values[mode], bins=bins, histtype="step", linestyle=style, label=mode)
        axes[0, col].set(yscale="log", xlabel="fisheye stamp [s]", ylabel=label)
        axes[1, col].set(xscale="log", xlabel=label, ylabel="frames")
        axes[0, col].legend(fontsize=8)
        axes[0, col].grid(True, which="both", alpha=0.3)
    fig.suptitle(f"fisheye pose from RGB-D poses: {name}")
    fig.tight_layout()
    fig.savefig(out, dpi=100)
    plt.close(fig)
    return Path(out)
