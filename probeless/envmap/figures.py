"""Figures of :func:`probeless.envmap.evaluate.evaluate_envmaps`' results (``probeless eval envmap``
``--plot`` and ``--figures``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def plot_psnr(rendered, results, path: str) -> None:
    """PSNR over the common texels over time per method, one panel per object (the oracle mode)."""
    panels = [(f"{rendered.scene.name}: {o.id} (oracle)",
               {m: (rendered.eval_times, res.series[o.id]["psnr_common"]) for m, res in results.items()})
              for o in rendered.scene.virtual_objects]
    plot_panels(panels, path)


def plot_panels(panels: list[tuple[str, dict]], path: str) -> None:
    """One panel per ``(title, {method: (times [s], PSNR over common texels [dB])})``, side by side, to ``path``
    (both evaluation modes' ``--plot``)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(panels), figsize=(6 * len(panels), 4), squeeze=False)
    for ax, (title, lines) in zip(axes[0], panels):
        for m, (times, values) in lines.items():
            ax.plot(times, values, label=m, lw=2 if m == "ours" else 1)
        ax.set_title(title)
        ax.set_xlabel("time [s]")
        ax.set_ylabel("PSNR over common texels [dB]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)


def mirror_figure(rendered, results, out_dir: str) -> None:
    """Per object, last frame: mirror spheres lit by ours, the baseline and the true map side by side
    (``mirror_<id>.png``, like the paper's Figure 13) and their cubemap nets (``cubemap_net_<id>.png``)."""
    import cv2

    from probeless.envmap.metrics import render_mirror_sphere
    from probeless.scene.preview import cube_net

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t = rendered.eval_times[-1]
    for o in rendered.scene.virtual_objects:
        tiles = []
        for name in ("ours", "baseline"):
            if name in results and o.id in results[name].last_faces:
                tiles.append((name, results[name].last_faces[o.id]))
        tiles.append(("truth", rendered.truth[o.id, t]))
        imgs, nets = [], []
        for name, faces in tiles:
            net = (np.clip(cube_net(np.asarray(faces, np.float32), 96), 0, 1) * 255).astype(np.uint8)
            cv2.putText(net, name, (8, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (255, 255, 0), 1, cv2.LINE_AA)
            nets.append(net)
            img, _ = render_mirror_sphere(np.clip(faces, 0, 1), 256)
            img = (img * 255).astype(np.uint8)
            cv2.putText(img, name, (8, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (255, 255, 0), 1, cv2.LINE_AA)
            imgs.append(img)
        cv2.imwrite(str(out / f"mirror_{o.id}.png"), cv2.cvtColor(np.hstack(imgs), cv2.COLOR_RGB2BGR))
        cv2.imwrite(str(out / f"cubemap_net_{o.id}.png"), cv2.cvtColor(np.vstack(nets), cv2.COLOR_RGB2BGR))
