"""``probeless eval envmap SCENE``: ours vs the baseline and the ablations against the rig's true maps.

Modes: ``--graph GRAPH`` runs the shipped graph in lockstep on a ``scene render`` recording and scores its
``envmap`` topics (:mod:`probeless.eval.envmap_graph`: SLAM poses, the calibration the recording gives, the
graph's own Δ handling; ``"mode": "graph"``); ``--oracle`` (the default when ``--graph`` is not given) is the
offline re-implementation given the true poses, extrinsics, camera model and floorplan
(:func:`probeless.envmap.evaluate.evaluate_envmaps`); every table and the JSON name the mode (``"mode": "oracle"``).
Each mode is an option in :func:`add_arguments` and a ``run_<mode>`` function
that :func:`run` picks. The scores are :func:`probeless.envmap.score.score_envmap`'s; the pictures
:mod:`probeless.envmap.figures`. ``--plot`` has no ``--figure`` alias here: ``--figure`` already
abbreviates ``--figures DIR``.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from probeless.envmap.methods import METHODS, METRICS, TABLE
from probeless.eval.envmap_graph_cli import add_graph_arguments
from probeless.eval.harness import add_common_options, emit

ORACLE = ("oracle: offline replay with the true fisheye poses, extrinsics, camera model and floorplan, dense model "
          "from RGB-D frames at true poses, no SLAM")
COMMON = "texels both ours and baseline observed (each method's own observed texels when either is not run)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``probeless eval envmap``."""
    p.add_argument("scene", metavar="SCENE_OR_BAG", help="scene file (.yaml), or a recording made by "
                                                         "`scene render` (evaluated through the scene it stores)")
    add_common_options(p, json_help="print one JSON object: method -> object -> metric",
                       figure=("--plot", "envmap PSNR over time, one line per method"), figure_alias=False,
                       progress_help="no progress bars")
    p.add_argument("--oracle", action="store_true",
                   help="the offline oracle evaluation (true poses, extrinsics, camera model; the default mode)")
    p.add_argument("--methods", nargs="+", choices=METHODS, default=list(METHODS), help="methods to run")
    p.add_argument("--duration", type=float, metavar="S", help="scene time to evaluate [s] (default: all)")
    p.add_argument("--every", type=int, default=3, help="compare every n-th fisheye frame used (default 3)")
    p.add_argument("--stride", type=int, default=1, help="use every n-th fisheye frame (default 1)")
    p.add_argument("--face-size", type=int, default=64, help="cubemap face size [texels] (default 64)")
    p.add_argument("--atlas-size", type=int, default=512, help="coarse atlas side [texels] (default 512)")
    p.add_argument("--figures", metavar="DIR", help="write mirror spheres of the last frame: ours / baseline / truth")
    add_graph_arguments(p)


def scene_path(path: str) -> str:
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


def run(ns: argparse.Namespace) -> int:
    """The chosen mode's evaluation (module doc). Returns the exit status."""
    if ns.graph:
        from probeless.eval.envmap_graph_cli import run_graph_mode

        return run_graph_mode(ns)
    return run_oracle(ns)


def run_oracle(ns: argparse.Namespace) -> int:
    """Render, evaluate every method offline, draw, print the table or one JSON object. Returns the exit status."""
    from probeless.envmap.evaluate import MODE, evaluate_envmaps
    from probeless.progress import stdout_to_stderr

    with stdout_to_stderr():
        rendered, results = evaluate_envmaps(scene_path(ns.scene), duration=ns.duration, methods=ns.methods,
                                             face_size=ns.face_size, atlas_size=ns.atlas_size, every=ns.every,
                                             stride=ns.stride, show_progress=not ns.no_progress)
    out: dict[str, Any] = {"mode": MODE, "mode_detail": ORACLE, "scene": ns.scene, "times_s": rendered.eval_times,
                           "units": "camera LDR (PSNR peak 1); log_rmse_hdr, pu21_psnr against the linear truth",
                           "common_texels": COMMON}
    for m, res in results.items():
        means = res.means()
        out[m] = {o: {**vals, "series": {k: list(res.series[o][k]) for k in METRICS}}
                  for o, vals in means.items()}  # non-finite values become null in print_json
    if "ours" in results and "baseline" in results:
        ours, base = results["ours"].means(), results["baseline"].means()
        for key, metric in (("ours_minus_baseline_psnr_db", "envmap_psnr"),
                            ("ours_minus_baseline_psnr_common_db", "psnr_common")):
            out[key] = {o: ours[o][metric] - base[o][metric] for o in ours}
    if ns.figure:
        from probeless.envmap.figures import plot_psnr

        plot_psnr(rendered, results, ns.figure)
    if ns.figures:
        from probeless.envmap.figures import mirror_figure

        mirror_figure(rendered, results, ns.figures)
    return emit(ns, out, lambda _: table(results, MODE))


def table(results, mode: str) -> str:
    """Mean metrics per method and object as a text table, headed by the mode that made it."""
    lines = [f"mode: {mode}; *_common over {COMMON}",
             f"{'method':<16}{'object':<12}" + "".join(f"{k:>21}" for k in TABLE)]
    for m, res in results.items():
        for o, vals in res.means().items():
            lines.append(f"{m:<16}{o:<12}" + "".join(f"{vals[k]:>21.3f}" for k in TABLE))
    return "\n".join(lines)
