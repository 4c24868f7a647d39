"""``probeless eval``: the registry, the common options, the old spellings, the output, the layering."""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

import pytest
from locations import REPO

from probeless.eval import EVALUATIONS, add_eval_parser
from probeless.eval.harness import emit, format_result, load

ROOT = REPO
POSITIONAL = {"slam": ["data"], "fisheye-pose": ["scene.yaml"], "envmap": ["scene.yaml"], "coarse": ["scene.yaml"],
              "hdr-expand": ["scene.yaml"], "hdr-envmap": ["scene.yaml"]}
OWN_FIGURE_FLAG = {"slam": "--plot", "fisheye-pose": "--plot", "envmap": "--plot", "coarse": "--plot",
                   "glossy": "--figure", "diffuse": "--figure", "itmo": "--figure",
                   "hdr-expand": "--figure", "hdr-envmap": "--figure", "pbgi": "--figure", "ibl": "--figure"}


def parse(argv: list[str]) -> argparse.Namespace:
    from probeless.cli import build_parser

    return build_parser().parse_args(argv)


def test_registry_names_front_ends_with_add_arguments_and_run():
    assert list(EVALUATIONS) == ["slam", "fisheye-pose", "envmap", "coarse", "glossy", "diffuse", "itmo",
                                 "hdr-expand", "hdr-envmap", "pbgi", "ibl"]
    for name, ev in EVALUATIONS.items():
        module = load(name)
        assert callable(module.add_arguments) and callable(module.run), name
        assert ev.module.startswith("probeless.eval.") and ev.help
    root = argparse.ArgumentParser()
    evals = add_eval_parser(root.add_subparsers(dest="command"))
    assert set(evals.choices) == set(EVALUATIONS)


@pytest.mark.parametrize("name", list(EVALUATIONS))
def test_common_options(name):
    args = ["eval", name, *POSITIONAL.get(name, [])]
    ns = parse(args)
    assert ns.json is False and ns.no_progress is False and ns.figure is None
    ns = parse([*args, "--json", "--no-progress", OWN_FIGURE_FLAG[name], "out.png"])
    assert ns.json and ns.no_progress and ns.figure == "out.png"
    other = {"--plot": "--figure", "--figure": "--plot"}[OWN_FIGURE_FLAG[name]]
    if name == "envmap":  # --figure abbreviates --figures DIR there, as it did before
        assert parse([*args, other, "d"]).figures == "d"
    else:
        assert parse([*args, other, "b.png"]).figure == "b.png"
    assert ns.func is load(name).run


@pytest.mark.parametrize("old,name", [(["coarse", "eval", "scene.yaml"], "coarse"), (["pano", "glossy"], "glossy"),
                                      (["pano", "diffuse"], "diffuse"), (["pano", "itmo"], "itmo")])
def test_old_spelling_notes_the_new_one_and_runs_with_the_same_arguments(old, name, monkeypatch, capsys):
    seen = []
    monkeypatch.setattr(load(name), "run", lambda ns: seen.append(ns) or 7)
    ns = parse([*old, "--json", "--no-progress", OWN_FIGURE_FLAG[name], "x.png"])
    new = parse(["eval", name, *old[2:], "--json", "--no-progress", OWN_FIGURE_FLAG[name], "x.png"])
    assert ns.func(ns) == 7 and seen == [ns]
    err = capsys.readouterr()
    assert err.out == "" and err.err == f"note: 'probeless {' '.join(old[:2])}' is now 'probeless eval {name}'\n"
    keys = {k: v for k, v in vars(ns).items() if k not in ("func", "command", "coarse_cmd", "pano_command",
                                                          "eval_command")}
    assert keys == {k: v for k, v in vars(new).items() if k in keys} and set(keys) <= set(vars(new))


def test_coarse_preview_is_still_there():
    ns = parse(["coarse", "preview", "scene.yaml", "-o", "out"])
    assert ns.out == "out" and ns.func.__module__ == "probeless.coarse.cli"


def test_emit_prints_one_json_object_or_a_table(capsys):
    result = {"name": "x", "errors": {"mean": 0.25, "max": float("nan")}, "series": list(range(20)), "ok": True}
    assert emit(argparse.Namespace(json=True), result) == 0
    out = capsys.readouterr().out
    assert out.count("\n") == 1 and json.loads(out)["errors"] == {"mean": 0.25, "max": None}
    emit(argparse.Namespace(json=False), result)
    assert capsys.readouterr().out == format_result(result) + "\n"
    lines = format_result(result).splitlines()
    assert lines == ["name         x", "errors.mean  0.25", "errors.max   nan", "series       [20 values]",
                     "ok           True"]
    emit(argparse.Namespace(json=False), result, lambda r: f"own table of {r['name']}")
    assert capsys.readouterr().out == "own table of x\n"


def _imports(path: Path) -> set[str]:
    text = path.read_text()
    return set(re.findall(r"^\s*(?:from|import)\s+(probeless(?:\.\w+)*)", text, re.M))


def test_only_the_top_layer_imports_probeless_eval():
    top = {ROOT / "probeless" / "cli.py"}
    above = {ROOT / "probeless" / "eval", ROOT / "probeless" / "sweep"}   # sweep parses eval's own options
    for path in list((ROOT / "probeless").rglob("*.py")) + list((ROOT / "nodes").rglob("*.py")):
        if path in top or above & set(path.parents):
            continue
        assert not any(m == "probeless.eval" or m.startswith("probeless.eval.") for m in _imports(path)), path
    for path in (ROOT / "probeless" / "eval").glob("*.py"):
        assert not any(m.startswith("probeless.nodes") for m in _imports(path)), path
