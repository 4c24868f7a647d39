"""The command line of ``probeless eval envmap --graph`` (:mod:`probeless.eval.envmap_graph` does the work):
its options, the text table, the ``--plot`` picture."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from probeless.errors import ProbelessError
from probeless.eval.envmap_graph import CACHE, GRAPH_METHODS, evaluate_graph


def add_graph_arguments(p) -> None:
    """``--graph`` and its options (``probeless eval envmap``)."""
    g = p.add_argument_group("graph mode (score the shipped graph)")
    g.add_argument("--graph", metavar="GRAPH", help="run this graph in lockstep on the recording (e.g. "
                                                     "launch/probeless.yaml) and score its envmap topics")
    g.add_argument("--graph-methods", nargs="+", choices=list(GRAPH_METHODS), default=list(GRAPH_METHODS),
                   help="envmap_node swaps to run (default: ours baseline)")
    g.add_argument("--graph-lighting", nargs="+", metavar="MODE",
                   help="run each method once per lighting mode (lighting:=MODE, e.g. ldr hdr) and score every run "
                        "on the texels all runs observed: the modes compare in one table")
    g.add_argument("--graph-arg", action="append", default=[], metavar="NAME:=VALUE",
                   help="extra graph argument for every run, e.g. dense:=false (repeatable)")
    g.add_argument("--truth-size", type=int, default=32, help="truth cubemap face size when rendering a scene "
                                                              "[texels] (default 32)")
    g.add_argument("--cache", metavar="DIR", default=str(CACHE),
                   help=f"where rendered scene recordings are kept, keyed by scene, duration and truth size "
                        f"(default {CACHE})")
    g.add_argument("--graph-record", nargs="+", default=[], metavar="TOPIC",
                   help="also record these topics of each run in <runs-dir>/<method>/maps.mcap")
    g.add_argument("--runs-dir", metavar="DIR", default="out/eval_envmap_graph",
                   help="where each run's maps, video and launch log go (default out/eval_envmap_graph/<scene>)")


def graph_table(result: dict[str, Any]) -> str:
    """The graph-mode scores as a text table (mode and graph in the title)."""
    from probeless.envmap.score import SCORES

    cols = [k for k in SCORES if k not in ("psnr_all",)] + ["psnr_all"]
    linear = [m for m, lin in result.get("linear_maps", {}).items() if lin]
    hdr = f"; linear (HDR) maps: {', '.join(linear)}" if linear else ""
    lines = [f"mode: graph ({result['graph']}, lockstep on {result['recording']}{hdr})",
             f"{'method':<15}{'object':<10}" + "".join(f"{k:>21}" for k in cols)]
    for method, objects in result["methods"].items():
        for oid, e in objects.items():
            lines.append(f"{method:<15}{oid:<10}" + "".join(f"{e[k]:>21.3f}" for k in cols))
    return "\n".join(lines)


def run_graph_mode(ns) -> int:
    """``probeless eval envmap --graph GRAPH SCENE_OR_BAG``: evaluate, print the table or one JSON object."""
    from probeless.eval.harness import emit
    from probeless.progress import stdout_to_stderr

    if getattr(ns, "oracle", False):
        raise ProbelessError("--graph and --oracle are two modes: give one")
    if getattr(ns, "figures", None):
        raise ProbelessError("--figures draws the oracle mode's mirror spheres; the graph mode writes each run's "
                             "video and cube nets under --runs-dir")
    with stdout_to_stderr():
        result = evaluate_graph(ns.scene, graph=ns.graph, methods=ns.graph_methods, duration=ns.duration,
                                envmap_size=ns.truth_size, out_dir=Path(ns.runs_dir) / Path(ns.scene).stem,
                                graph_args=ns.graph_arg, show_progress=not ns.no_progress, cache=Path(ns.cache),
                                record=tuple(ns.graph_record), lightings=ns.graph_lighting)
    if getattr(ns, "figure", None):
        plot_graph(result, ns.figure)
    return emit(ns, result, graph_table)


def plot_graph(result: dict[str, Any], path: str) -> None:
    """PSNR over the common texels over time per method, one panel per object (the graph mode's ``--plot``)."""
    from probeless.envmap.figures import plot_panels

    methods = result["methods"]
    objects = sorted({o for per in methods.values() for o in per})
    plot_panels([(f"{Path(result['scene']).stem}: {o} (graph, lockstep)",
                  {m: (per[o]["times_s"], per[o]["series"]["psnr_common"]) for m, per in methods.items()})
                 for o in objects], path)
