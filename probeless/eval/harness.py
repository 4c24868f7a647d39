"""The shared part of ``probeless eval <name>``: the registry, the common options and the output.

Every evaluation is a module of :mod:`probeless.eval` with ``add_arguments(parser)`` and
``run(ns) -> int``, registered in :data:`EVALUATIONS`. Its compute code lives in the algorithm
package (``probeless.tracking``, ``probeless.coarse``, ``probeless.pano`` ...); the module only
parses, runs and prints. Common options, added by :func:`add_common_options`:

* ``--json``: print exactly one JSON object on stdout (:func:`probeless.jsonio.print_json`);
* ``--figure`` / ``--plot``: the picture an evaluation draws (both spellings; the evaluation's
  original one is listed first), ``ns.figure``;
* ``--no-progress``: no progress bar on stderr.

Without ``--json`` the result is printed by the evaluation's own table printer, or as a plain
aligned two-column table of the (flattened) result dict (:func:`format_result`).

Some evaluations had another spelling before this group existed (``probeless coarse eval``,
``probeless pano glossy``); :func:`add_old_spellings` keeps them working: they print a one-line
note on stderr, then run the evaluation with the same arguments.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from dataclasses import dataclass
from types import ModuleType
from typing import Any, Callable

from probeless.jsonio import print_json


@dataclass(frozen=True)
class Evaluation:
    """One ``probeless eval NAME``: its front-end module, one-line help and old spelling (if any)."""

    module: str  # importable module with add_arguments(parser) and run(ns) -> int
    help: str
    old: str | None = None  # "GROUP COMMAND": the spelling before ``probeless eval``, still accepted


EVALUATIONS: dict[str, Evaluation] = {
    "slam": Evaluation("probeless.eval.slam", "run the dense SLAM on a dataset and report ATE, RPE, failures and "
                                              "costs"),
    "fisheye-pose": Evaluation("probeless.eval.fisheye_pose", "fisheye pose from interpolated RGB-D poses vs the "
                                                              "true one"),
    "envmap": Evaluation("probeless.eval.envmap", "environment maps at the virtual objects vs ground truth, for "
                                                  "ours, the baseline and the ablations"),
    "coarse": Evaluation("probeless.eval.coarse", "coarse room model: texture error against the scene's true "
                                                  "surface colours, with and without Δ", old="coarse eval"),
    "glossy": Evaluation("probeless.eval.glossy", "360° IBL: glossy ring sampling vs a Monte Carlo Phong-lobe "
                                                  "integral", old="pano glossy"),
    "diffuse": Evaluation("probeless.eval.diffuse", "360° IBL: diffuse map (GPU, matmul, SH9) vs the exact "
                                                    "convolution of the full-resolution frame: errors and timings",
                          old="pano diffuse"),
    "itmo": Evaluation("probeless.eval.itmo", "360° IBL, Figure 7 quantified: spheres lit by LDR, inverse tone "
                                              "mapped LDR and true HDR maps, image errors against true HDR",
                       old="pano itmo"),
    "hdr-expand": Evaluation("probeless.eval.hdr_expand", "HDR expansion of an LDR cloud (paper 001, §6.2): cloud "
                                                          "radiance and lit spheres vs synthetic ground truth"),
    "hdr-envmap": Evaluation("probeless.eval.hdr_envmap", "HDR coarse and dense models (paper 001 §4 on paper 003's "
                                                          "models): environment maps vs the rig's linear truth, "
                                                          "LDR vs HDR"),
    "pbgi": Evaluation("probeless.eval.pbgi", "PBGI and environment-map renderings of a sphere vs Mitsuba 3, one "
                                              "bounce (paper 001, Figure 14)"),
    "ibl": Evaluation("probeless.eval.ibl", "every ibl_compositor material on a sphere under HDR panoramas and a "
                                            "room's cubemap vs Mitsuba 3 (issue 27)"),
}

# help of a command group that only holds old spellings (created by add_old_spellings)
OLD_GROUP_HELP = {"pano": "360° video IBL (paper 002): accuracy of the fast paths against brute-force references "
                          "(now 'probeless eval glossy|diffuse|itmo')"}


def load(name: str) -> ModuleType:
    """The front-end module of evaluation ``name``."""
    return importlib.import_module(EVALUATIONS[name].module)


def add_evaluation(subparsers: Any, name: str, old: bool = False) -> argparse.ArgumentParser:
    """Add evaluation ``name`` to ``subparsers``; returns its parser.

    With ``old`` it is added as its old spelling's command (``glossy`` of ``pano glossy``, to the
    ``pano`` group's subparsers): it runs the evaluation after a note on stderr saying where the
    command now lives.
    """
    ev, module = EVALUATIONS[name], load(name)
    if not old:
        p = subparsers.add_parser(name, help=ev.help, description=ev.help)
        module.add_arguments(p)
        p.set_defaults(func=module.run)
        return p
    if ev.old is None:
        raise ValueError(f"evaluation {name!r} has no old spelling")
    spelled, new = f"probeless {ev.old}", f"probeless eval {name}"
    note = f"note: '{spelled}' is now '{new}'"
    p = subparsers.add_parser(ev.old.split()[1], help=f"{ev.help} (now '{new}')",
                              description=f"{ev.help}\n\n{note}; this spelling still works.",
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    module.add_arguments(p)
    p.set_defaults(func=_with_note(module.run, note))
    return p


def _with_note(run: Callable[[argparse.Namespace], int], note: str) -> Callable[[argparse.Namespace], int]:
    def func(ns: argparse.Namespace) -> int:
        print(note, file=sys.stderr, flush=True)
        return run(ns)

    return func


def add_eval_parser(subparsers: Any) -> Any:
    """Add the ``eval`` command group with every evaluation of :data:`EVALUATIONS`; returns its subparsers."""
    p = subparsers.add_parser("eval", help="evaluate pipeline stages against ground truth",
                              description="evaluate pipeline stages against ground truth; every evaluation "
                                          "takes --json (one JSON object on stdout) and --no-progress, and "
                                          "where it draws a picture --figure/--plot OUT.png")
    evals = p.add_subparsers(dest="eval_command", required=True)
    for name in EVALUATIONS:
        add_evaluation(evals, name)
    return evals


def add_old_spellings(subparsers: Any, groups: dict[str, Any] | None = None) -> None:
    """Add each evaluation's old spelling ``GROUP COMMAND``.

    ``groups`` maps a command group already added (``coarse``, which keeps ``preview``) to its
    subparsers; a group not given is added to the top-level ``subparsers`` here (``pano``).
    """
    groups = dict(groups or {})
    for name, ev in EVALUATIONS.items():
        if ev.old is None:
            continue
        group = ev.old.split()[0]
        if group not in groups:
            g = subparsers.add_parser(group, help=OLD_GROUP_HELP.get(group))
            groups[group] = g.add_subparsers(dest=f"{group}_command", required=True)
        add_evaluation(groups[group], name, old=True)


# --- common options ------------------------------------------------------------------------------

def add_common_options(parser: argparse.ArgumentParser, *, json_help: str = "print one JSON object",
                       figure: tuple[str, str] | None = None, figure_alias: bool = True,
                       figure_metavar: str = "OUT.png", progress_help: str = "no progress bar"
                       ) -> argparse._ArgumentGroup:
    """``--json``, the figure option and ``--no-progress`` in a group "common options".

    ``figure``: (the evaluation's own flag, ``--figure`` or ``--plot``; help), stored in
    ``ns.figure``; with ``figure_alias`` the other spelling is accepted too.
    """
    g = parser.add_argument_group("common options")
    g.add_argument("--json", action="store_true", help=json_help)
    if figure is not None:
        flag, help_text = figure
        flags = [flag] + ([{"--figure": "--plot", "--plot": "--figure"}[flag]] if figure_alias else [])
        g.add_argument(*flags, dest="figure", metavar=figure_metavar, help=help_text)
    g.add_argument("--no-progress", action="store_true", help=progress_help)
    return g


# --- output --------------------------------------------------------------------------------------

def emit(ns: argparse.Namespace, result: Any, table: Callable[[Any], str | None] | None = None,
         places: int | None = None) -> int:
    """Print ``result``: one JSON object with ``--json`` (floats rounded to ``places``), else
    ``table(result)`` (a printer that prints itself returns None) or :func:`format_result`. Returns 0."""
    if getattr(ns, "json", False):
        print_json(result, places)
        return 0
    text = table(result) if table is not None else format_result(result)
    if text is not None:
        print(text)
    return 0


def _cell(value: Any, max_items: int = 8) -> str:
    if value is None:
        return "-"
    if isinstance(value, bool):
        return str(value)
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, (list, tuple)):
        if len(value) > max_items:
            return f"[{len(value)} values]"
        return "[" + ", ".join(_cell(v, max_items) for v in value) + "]"
    return str(value)


def flatten(result: dict, prefix: str = "") -> list[tuple[str, Any]]:
    """(dotted key, leaf value) of every non-dict value of a nested dict, in order."""
    rows: list[tuple[str, Any]] = []
    for key, value in result.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict) and value:
            rows += flatten(value, name + ".")
        else:
            rows.append((name, value))
    return rows


def format_result(result: Any, title: str | None = None) -> str:
    """A result dict as a plain aligned two-column table (key, value); long lists are counted, not shown."""
    if not isinstance(result, dict):
        return _cell(result)
    rows = [(k, _cell(v)) for k, v in flatten(result)]
    width = max((len(k) for k, _ in rows), default=0)
    lines = [title] if title else []
    lines += [f"{k:<{width}}  {v}" for k, v in rows]
    return "\n".join(lines)
