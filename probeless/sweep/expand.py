"""From a :class:`~probeless.sweep.spec.Sweep` to its runs: axes crossed or zipped, placeholders filled,
stable run ids, each run's command checked up front (the evaluation's own parser, the graph's validation)."""

from __future__ import annotations

import argparse
import hashlib
import itertools
import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from probeless.errors import SweepError
from probeless.sweep.spec import PLACEHOLDER, Sweep, short_label

MAX_DEPTH = 4  # an axis value may name another axis's placeholder, this deep


@dataclass
class Run:
    """One run of a sweep: its id, the table's axis columns, the ``probeless`` argv and what to collect."""

    run_id: str
    labels: dict[str, str]          # axis -> label (the table's axis columns)
    argv: list[str]                 # arguments of `python -m probeless`
    run_dir: str                    # results/<run-id>, absolute
    result_file: str | None         # graph runs: the JSON file collected from (None: the eval's stdout)
    collect: dict[str, str]         # column -> dotted path, placeholders filled
    inputs: list[str]               # files hashed into the resume key

    def key(self) -> str:
        """The resume key: a hash of the resolved command (run dir abstracted) and the input files' bytes."""
        h = hashlib.sha256(json.dumps([a.replace(self.run_dir, "{run_dir}") for a in self.argv]).encode())
        for path in sorted(set(self.inputs)):
            h.update(path.encode())
            h.update(hashlib.sha256(Path(path).read_bytes()).digest() if Path(path).is_file() else b"missing")
        return h.hexdigest()[:16]


def substitute(value: Any, env: dict[str, Any], depth: int = 0) -> Any:
    """Fill ``{name}`` placeholders; a string that is exactly one placeholder takes the value's type."""
    if isinstance(value, str):
        whole = PLACEHOLDER.fullmatch(value)
        if whole:
            v = env[whole.group(1)]
            return substitute(v, env, depth + 1) if depth < MAX_DEPTH else v
        return PLACEHOLDER.sub(lambda m: _text(substitute(env[m.group(1)], env, depth + 1)
                                               if depth < MAX_DEPTH else env[m.group(1)]), value)
    if isinstance(value, list):
        return [substitute(v, env, depth) for v in value]
    if isinstance(value, dict):
        return {k: substitute(v, env, depth) for k, v in value.items()}
    return value


def _text(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (list, dict)):
        return json.dumps(v)
    return str(v)


def flatten_argv(tokens: list) -> list[str]:
    """Argv tokens as strings; a list (from an axis value) is spliced in."""
    out: list[str] = []
    for t in tokens:
        out += flatten_argv(t) if isinstance(t, list) else [_text(t)]
    return out


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.]+", "_", short_label(text)).strip("_")[:40] or "x"


def combinations(sweep: Sweep) -> list[tuple[int, ...]]:
    """Value indices of every run, in file order, excluded ones left out."""
    sizes = [range(len(a.values)) for a in sweep.axes]
    combos = list(zip(*sizes)) if sweep.combine == "zip" else list(itertools.product(*sizes))

    def excluded(combo) -> bool:
        labels = {a.name: a.label(i) for a, i in zip(sweep.axes, combo)}
        return any(all(labels[k] == _text(v) for k, v in e.items()) for e in sweep.exclude)

    return [c for c in combos if not excluded(c)]


def expand(sweep: Sweep, out_dir: str | Path) -> list[Run]:
    """Every run of ``sweep``, writing under ``out_dir``; run ids are ``label-label-...`` (a short hash is
    added where two runs' labels slug alike)."""
    out_dir = Path(out_dir).resolve()
    combos = combinations(sweep)
    ids = ["-".join(_slug(a.label(i)) for a, i in zip(sweep.axes, c)) for c in combos]
    extra = _eval_flags(sweep.target) if sweep.kind == "eval" else []
    runs = []
    for combo, run_id in zip(combos, ids):
        if ids.count(run_id) > 1:
            run_id += "-" + hashlib.sha256(json.dumps(combo).encode()).hexdigest()[:6]
        runs.append(_make_run(sweep, combo, run_id, out_dir / run_id, extra))
    return runs


def _eval_flags(name: str) -> list[str]:
    """Appended to every eval run: ``--json``, and ``--no-progress`` where the evaluation has it."""
    return ["--json"] + (["--no-progress"] if "--no-progress" in eval_parser(name)._option_string_actions else [])


def _make_run(sweep: Sweep, combo: tuple[int, ...], run_id: str, run_dir: Path, extra: list[str]) -> Run:
    env: dict[str, Any] = {"run_dir": str(run_dir), "run_id": run_id}
    labels = {}
    for axis, i in zip(sweep.axes, combo):
        value = axis.values[i]
        labels[axis.name] = axis.label(i)
        env[axis.name] = value["name"] if isinstance(value, dict) else value
        if isinstance(value, dict):
            env.update({k: v for k, v in value.items() if k != "name"})
    collect = {k: substitute(v, env) for k, v in sweep.collect.items()}
    if sweep.kind == "eval":
        argv = ["eval", sweep.target, *flatten_argv(substitute(list(sweep.args), env))]
        argv += [flag for flag in extra if flag not in argv]
        return Run(run_id, labels, argv, str(run_dir), None, collect, [a for a in argv if _is_file(a)])
    args = substitute(dict(sweep.args), env)
    argv = ["launch", sweep.target, *(f"{k}:={_text(v)}" for k, v in args.items())]
    if sweep.duration:
        argv += ["--duration", _text(sweep.duration)]
    inputs = [sweep.target] + [str(v) for v in args.values() if isinstance(v, str) and _is_file(v)]
    return Run(run_id, labels, argv, str(run_dir), substitute(sweep.result, env), collect, inputs)


def _is_file(token: str) -> bool:
    return not token.startswith("-") and len(token) < 4096 and Path(token).is_file()


# --- up-front checks -----------------------------------------------------------------------------

class _Parser(argparse.ArgumentParser):
    """An evaluation's parser that raises instead of printing usage and exiting."""

    def error(self, message: str):
        raise SweepError(message)

    def exit(self, status: int = 0, message: str | None = None):
        raise SweepError(message or "the arguments ask the parser to exit (--help?)")


def eval_parser(name: str) -> argparse.ArgumentParser:
    """The parser of ``probeless eval NAME``, built the way :func:`probeless.eval.harness.add_evaluation` does."""
    from probeless.eval.harness import load

    p = _Parser(prog=f"probeless eval {name}", add_help=False)
    load(name).add_arguments(p)
    return p


def check_runs(sweep: Sweep, runs: list[Run]) -> None:
    """Parse every run's command without running it; SweepError naming the file, line and run on the first
    bad one (an unknown flag, a bad value, a missing input file, a graph that does not validate)."""
    if sweep.kind == "eval":
        parser = eval_parser(sweep.target)
        for run in runs:
            _check_eval(sweep, parser, run)
    else:
        seen = set()
        for run in runs:
            if run.argv[2:] and tuple(run.argv) not in seen:
                seen.add(tuple(run.argv))
                _check_graph(sweep, run)


def _check_eval(sweep: Sweep, parser: argparse.ArgumentParser, run: Run) -> None:
    try:
        ns = parser.parse_args(run.argv[2:])
    except SweepError as exc:
        raise sweep.error(f"run {run.run_id}: probeless eval {sweep.target}: {exc.message}", "run.args") from None
    inputs = [a for a in parser._actions if not a.option_strings] + [
        a for a in parser._actions if a.dest == "graph"]
    for action in inputs:
        value = getattr(ns, action.dest, None)
        for v in value if isinstance(value, list) else [value]:
            if isinstance(v, str) and v and not Path(v).exists():
                err = sweep.error(f"run {run.run_id}: no such file {v!r} ({action.metavar or action.dest})",
                                  "run.args")
                err.line, err.key = _value_line(sweep, v) or (err.line, err.key)
                raise SweepError(err.message, file=err.file, line=err.line, key=err.key)


def _value_line(sweep: Sweep, value: str) -> tuple[int, str] | None:
    """(line, key) of the axis value ``value`` came from, if it is one."""
    for axis in sweep.axes:
        for v, line in zip(axis.values, axis.lines):
            if v == value or (isinstance(v, dict) and value in v.values()):
                return line, f"axes.{axis.name}"
    return None


def _check_graph(sweep: Sweep, run: Run) -> None:
    from probeless.launch.graph import parse_graph
    from probeless.launch.validate import validate
    from probeless.launch.yamlload import load_yaml_text

    overrides = {}
    for token in run.argv[2:]:
        if ":=" in token:
            name, _, value = token.partition(":=")
            overrides[name] = load_yaml_text(value, f"argument {name}") if value else ""
    errors = validate(parse_graph(sweep.target, overrides))
    if errors:
        raise sweep.error(f"run {run.run_id}: graph {sweep.target} does not validate:\n"
                          + "\n".join("  " + e.format() for e in errors), "run.args")
