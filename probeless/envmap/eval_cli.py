"""``probeless eval envmap SCENE``: ours vs the baseline and the ablations against the rig's true maps."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from probeless.envmap.evaluate import METHODS, METRICS


def add_envmap_eval(eval_subparsers: Any) -> argparse.ArgumentParser:
    """Add ``envmap`` to the subparsers of the ``probeless eval`` command group."""
    p = eval_subparsers.add_parser("envmap", help="environment maps at the virtual objects vs ground truth, "
                                                  "for ours, the baseline and the ablations")
    p.add_argument("scene", metavar="SCENE_OR_BAG", help="scene file (.yaml), or a recording made by "
                                                         "`scene render` (evaluated through the scene it stores)")
    p.add_argument("--json", action="store_true", help="print one JSON object: method -> object -> metric")
    p.add_argument("--methods", nargs="+", choices=METHODS, default=list(METHODS), help="methods to run")
    p.add_argument("--duration", type=float, metavar="S", help="scene time to evaluate [s] (default: all)")
    p.add_argument("--every", type=int, default=3, help="compare every n-th fisheye frame used (default 3)")
    p.add_argument("--stride", type=int, default=1, help="use every n-th fisheye frame (default 1)")
    p.add_argument("--face-size", type=int, default=64, help="cubemap face size [texels] (default 64)")
    p.add_argument("--atlas-size", type=int, default=512, help="coarse atlas side [texels] (default 512)")
    p.add_argument("--plot", metavar="OUT.png", help="envmap PSNR over time, one line per method")
    p.add_argument("--figures", metavar="DIR", help="write mirror spheres of the last frame: ours / baseline / truth")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.set_defaults(func=cmd_eval_envmap)
    return p


def _scene_path(path: str) -> str:
    """A scene file, or the scene a `scene render` recording stores in its metadata (written to a temp file)."""
    p = Path(path)
    if p.suffix in (".yaml", ".yml"):
        return str(p)
    import tempfile

    from probeless.bag.reader import BagReader
    from probeless.errors import BagError

    with BagReader(p) as reader:
        meta = reader.metadata().get("probeless.scene", {})
    if "yaml" not in meta:
        raise BagError(f"{path}: no probeless.scene metadata; evaluate the scene file instead")
    if Path(meta.get("file", "")).is_file():
        return meta["file"]
    tmp = Path(tempfile.mkdtemp()) / f"{meta.get('name', 'scene')}.yaml"  # assets must then be absolute paths
    tmp.write_text(meta["yaml"])
    return str(tmp)


def _finite(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def cmd_eval_envmap(ns: argparse.Namespace) -> int:
    from probeless.envmap.evaluate import evaluate_envmaps
    from probeless.progress import stdout_to_stderr

    with stdout_to_stderr():
        rendered, results = evaluate_envmaps(_scene_path(ns.scene), duration=ns.duration, methods=ns.methods,
                                             face_size=ns.face_size, atlas_size=ns.atlas_size, every=ns.every,
                                             stride=ns.stride, show_progress=not ns.no_progress)
    out: dict[str, Any] = {"scene": ns.scene, "times_s": rendered.eval_times, "units": "camera LDR (PSNR peak 1)"}
    for m, res in results.items():
        means = res.means()
        out[m] = {o: {**{k: _finite(v) for k, v in vals.items()},
                      "series": {k: [_finite(x) for x in res.series[o][k]] for k in METRICS}}
                  for o, vals in means.items()}
    if "ours" in results and "baseline" in results:
        out["ours_minus_baseline_psnr_db"] = {o: _finite(results["ours"].means()[o]["envmap_psnr"]
                                                         - results["baseline"].means()[o]["envmap_psnr"])
                                              for o in results["ours"].means()}
    if ns.plot:
        plot_psnr(rendered, results, ns.plot)
    if ns.figures:
        mirror_figure(rendered, results, ns.figures)
    if ns.json:
        print(json.dumps(out))
        return 0
    print(table(results))
    return 0


def table(results) -> str:
    """Mean metrics per method and object as a text table."""
    lines = [f"{'method':<16}{'object':<12}" + "".join(f"{k:>14}" for k in METRICS)]
    for m, res in results.items():
        for o, vals in res.means().items():
            lines.append(f"{m:<16}{o:<12}" + "".join(f"{vals[k]:>14.3f}" for k in METRICS))
    return "\n".join(lines)


def plot_psnr(rendered, results, path: str) -> None:
    """Envmap PSNR over time per method, one panel per object."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    objects = [o.id for o in rendered.scene.virtual_objects]
    fig, axes = plt.subplots(1, len(objects), figsize=(6 * len(objects), 4), squeeze=False)
    for ax, o in zip(axes[0], objects):
        for m, res in results.items():
            ax.plot(rendered.eval_times, res.series[o]["envmap_psnr"], label=m, lw=2 if m == "ours" else 1)
        ax.set_title(f"{rendered.scene.name}: {o}")
        ax.set_xlabel("time [s]")
        ax.set_ylabel("envmap PSNR [dB]")
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
