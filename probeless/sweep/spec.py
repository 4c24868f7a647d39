"""A sweep file: what to run, over which axes, with which resources, and what to collect (docs/sweeps.md).

:func:`load_sweep` parses and checks the file's structure; every problem is a :class:`SweepError` naming the
file, the line and the key. :mod:`probeless.sweep.expand` turns a :class:`Sweep` into runs and checks each
run's arguments with the evaluation's own parser or the graph's own validation.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from probeless.errors import GraphError, SweepError
from probeless.launch.yamlload import LineDict, LineList, load_yaml

TOP_KEYS = ("name", "description", "run", "axes", "combine", "exclude", "resources", "collect", "report")
RUN_KEYS = ("eval", "graph", "args", "result", "timeout_s", "duration")
RESOURCE_KEYS = ("cpus", "gpus")
REPORT_KEYS = ("rows", "columns", "values", "over")
BUILTINS = ("run_dir", "run_id")  # placeholders every run has besides its axes
PLACEHOLDER = re.compile(r"\{([A-Za-z_][A-Za-z0-9_]*)\}")


@dataclass(frozen=True)
class Axis:
    """One axis: its name and values. A mapping value sets several placeholders at once (its ``name`` is
    the axis's label); ``line`` and ``lines`` are where the axis and each value are in the file."""

    name: str
    values: list
    line: int
    lines: list

    def label(self, i: int) -> str:
        """The value shown in the table for value ``i``: a scalar as text, a mapping's ``name``."""
        v = self.values[i]
        return str(v["name"]) if isinstance(v, dict) else _text(v)


@dataclass
class Sweep:
    """A parsed sweep file (docs/sweeps.md)."""

    file: str
    name: str
    kind: str                      # "eval" | "graph"
    target: str                    # evaluation name or graph file
    args: Any                      # eval: list of argv tokens; graph: mapping name -> value
    axes: list[Axis]
    result: str | None = None      # graph runs: JSON file the run writes (collected from)
    timeout_s: float | None = None
    duration: float | None = None  # graph runs: `probeless launch --duration`
    combine: str = "cross"
    exclude: list[dict] = field(default_factory=list)
    cpus: int = 1
    gpus: float = 0.0
    collect: dict[str, str] = field(default_factory=dict)
    report: dict[str, Any] = field(default_factory=dict)
    lines: dict[str, int] = field(default_factory=dict)  # "run.args", "collect.psnr", ... -> line

    def line(self, key: str) -> int | None:
        """The line of ``key`` (dotted, e.g. ``run.args``), or of its nearest parent that has one."""
        while key:
            if key in self.lines:
                return self.lines[key]
            key = key.rpartition(".")[0]
        return None

    def error(self, message: str, key: str) -> SweepError:
        return SweepError(message, file=self.file, line=self.line(key), key=key)


FILE_SUFFIXES = (".yaml", ".yml", ".mcap", ".json", ".txt", ".hdr", ".exr", ".png", ".jpg", ".webm", ".mp4")


def short_label(text: Any) -> str:
    """A label for run ids and report tables: a file path becomes its stem (``launch/scenes/x.yaml`` -> ``x``)."""
    s = "" if text is None else str(text)
    p = Path(s)
    return p.stem if p.suffix.lower() in FILE_SUFFIXES or ("/" in s and p.suffix) else s


def _text(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    return str(v)


def _check_keys(doc: LineDict, allowed: tuple, prefix: str, file: str, errors: list) -> None:
    for key in doc:
        if key not in allowed:
            errors.append(SweepError(f"unknown key (allowed: {', '.join(allowed)})", file=file,
                                     line=doc.line_of(key), key=f"{prefix}{key}"))


def _mapping(doc: LineDict, key: str, file: str, errors: list) -> LineDict:
    value = doc.get(key)
    if value is None:
        return LineDict()
    if not isinstance(value, LineDict):
        errors.append(SweepError("must be a mapping", file=file, line=doc.line_of(key), key=key))
        return LineDict()
    return value


def _record_lines(doc: LineDict, prefix: str, lines: dict) -> None:
    for key in doc:
        lines[f"{prefix}{key}"] = doc.line_of(key)


def load_sweep(path: str | Path) -> Sweep:
    """Parse and check a sweep file; raises SweepError (every problem found, each with file:line)."""
    file = str(path)
    if not Path(file).is_file():
        raise SweepError("no such sweep file", file=file)
    try:
        doc = load_yaml(file)
    except GraphError as exc:
        raise SweepError(exc.message, file=exc.file, line=exc.line, key=exc.key) from None
    if not isinstance(doc, LineDict):
        raise SweepError("a sweep file must be a mapping with 'run' and 'axes'", file=file)
    errors: list[SweepError] = []
    _check_keys(doc, TOP_KEYS, "", file, errors)
    lines: dict[str, int] = {}
    _record_lines(doc, "", lines)
    run, resources, report = (_mapping(doc, k, file, errors) for k in ("run", "resources", "report"))
    for sub, allowed, name in ((run, RUN_KEYS, "run"), (resources, RESOURCE_KEYS, "resources"),
                               (report, REPORT_KEYS, "report")):
        _check_keys(sub, allowed, f"{name}.", file, errors)
        _record_lines(sub, f"{name}.", lines)
    kind, target, args = _parse_run(run, doc, file, errors)
    axes = _parse_axes(doc, file, errors)
    collect = _mapping(doc, "collect", file, errors)
    _record_lines(collect, "collect.", lines)
    for key, value in collect.items():
        if not isinstance(value, str) or not value:
            errors.append(SweepError("must be a dotted path into the run's JSON, e.g. ours.*.psnr_common",
                                     file=file, line=collect.line_of(key), key=f"collect.{key}"))
    sweep = Sweep(file=file, name=str(doc.get("name") or Path(file).stem), kind=kind, target=target, args=args,
                  axes=axes, result=run.get("result"), timeout_s=_number(run, "timeout_s", file, errors),
                  duration=_number(run, "duration", file, errors), combine=str(doc.get("combine", "cross")),
                  exclude=list(doc.get("exclude") or []), cpus=int(_number(resources, "cpus", file, errors) or 1),
                  gpus=float(_number(resources, "gpus", file, errors) or 0), collect=dict(collect),
                  report=dict(report), lines=lines)
    _check_rest(sweep, errors)
    if errors:
        raise errors[0] if len(errors) == 1 else SweepError(
            f"{len(errors)} errors:\n" + "\n".join("  " + e.format() for e in errors), file=file)
    return sweep


def _number(doc: LineDict, key: str, file: str, errors: list) -> float | None:
    value = doc.get(key)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or value < 0:
        errors.append(SweepError("must be a non-negative number", file=file, line=doc.line_of(key), key=key))
        return None
    return value


def _parse_run(run: LineDict, doc: LineDict, file: str, errors: list) -> tuple[str, str, Any]:
    kinds = [k for k in ("eval", "graph") if k in run]
    if len(kinds) != 1:
        errors.append(SweepError("needs exactly one of 'eval: NAME' or 'graph: FILE'", file=file,
                                 line=doc.line_of("run"), key="run"))
        return "eval", "", []
    kind, target = kinds[0], str(run[kinds[0]])
    args = run.get("args", [] if kind == "eval" else {})
    if kind == "eval":
        from probeless.eval.harness import EVALUATIONS

        if target not in EVALUATIONS:
            errors.append(SweepError(f"unknown evaluation {target!r} (known: {', '.join(EVALUATIONS)})",
                                     file=file, line=run.line_of("eval"), key="run.eval"))
        if not isinstance(args, list):
            errors.append(SweepError("eval runs take a list of command-line tokens", file=file,
                                     line=run.line_of("args"), key="run.args"))
    else:
        if not Path(target).is_file():
            errors.append(SweepError(f"no such graph file {target!r}", file=file, line=run.line_of("graph"),
                                     key="run.graph"))
        if not isinstance(args, dict):
            errors.append(SweepError("graph runs take a mapping of graph arguments (name: value)", file=file,
                                     line=run.line_of("args"), key="run.args"))
    return kind, target, args


def _parse_axes(doc: LineDict, file: str, errors: list) -> list[Axis]:
    axes_doc = doc.get("axes")
    if not isinstance(axes_doc, LineDict) or not axes_doc:
        errors.append(SweepError("'axes' must be a mapping of axis name -> list of values", file=file,
                                 line=doc.line_of("axes"), key="axes"))
        return []
    axes = []
    for name, values in axes_doc.items():
        line = axes_doc.line_of(name)
        if not PLACEHOLDER.fullmatch(f"{{{name}}}") or name in BUILTINS:
            errors.append(SweepError("axis names are identifiers, not run_dir or run_id", file=file, line=line,
                                     key=f"axes.{name}"))
        if not isinstance(values, LineList) or not values:
            errors.append(SweepError("must be a non-empty list of values", file=file, line=line, key=f"axes.{name}"))
            continue
        for value, vline in zip(values, values.lines):
            if isinstance(value, dict) and "name" not in value:
                errors.append(SweepError("a mapping value needs a 'name' (its label in the table)", file=file,
                                         line=vline, key=f"axes.{name}"))
        axes.append(Axis(str(name), list(values), line, list(values.lines)))
    return axes


def placeholders(value: Any) -> set[str]:
    """Every ``{name}`` in a (nested) template."""
    if isinstance(value, str):
        return set(PLACEHOLDER.findall(value))
    if isinstance(value, dict):
        return set().union(*(placeholders(v) for v in value.values())) if value else set()
    if isinstance(value, list):
        return set().union(*(placeholders(v) for v in value)) if value else set()
    return set()


def known_names(sweep: Sweep) -> set[str]:
    """The placeholders a run defines: axis names, the keys of mapping values, run_dir and run_id."""
    names = set(BUILTINS) | {a.name for a in sweep.axes}
    for axis in sweep.axes:
        names |= {k for v in axis.values if isinstance(v, dict) for k in v if k != "name"}
    return names


def _check_rest(sweep: Sweep, errors: list) -> None:
    known = known_names(sweep)
    for key, template in (("run.args", sweep.args), ("run.result", sweep.result), *(
            (f"collect.{k}", v) for k, v in sweep.collect.items())):
        for name in sorted(placeholders(template) - known):
            errors.append(sweep.error(f"unknown placeholder {{{name}}} (known: {', '.join(sorted(known))})", key))
    if sweep.combine not in ("cross", "zip"):
        errors.append(sweep.error("must be 'cross' or 'zip'", "combine"))
    elif sweep.combine == "zip" and len({len(a.values) for a in sweep.axes}) > 1:
        errors.append(sweep.error("zipped axes must have the same number of values", "combine"))
    if sweep.kind == "graph" and sweep.collect and not sweep.result:
        errors.append(sweep.error("graph runs collect from a JSON file: give run.result (e.g. "
                                  "'{run_dir}/out/summary.json')", "collect"))
    axis_names = {a.name for a in sweep.axes}
    for key in sweep.collect:
        if key in axis_names or key in ("run_id", "status", "wall_s", "error", "key"):
            errors.append(sweep.error("a collected column may not share its name with an axis or run_id, status, "
                                      "wall_s, error, key", f"collect.{key}"))
    for entry in sweep.exclude:
        if not isinstance(entry, dict) or not set(entry) <= axis_names:
            errors.append(sweep.error(f"each entry is a mapping of axis -> label (axes: {', '.join(axis_names)})",
                                      "exclude"))
    for key in ("rows", "columns"):
        if key in sweep.report and sweep.report[key] not in axis_names:
            errors.append(sweep.error(f"not an axis ({', '.join(axis_names)})", f"report.{key}"))
    for value in sweep.report.get("values", []) or []:
        if value not in sweep.collect:
            errors.append(sweep.error(f"{value!r} is not a collected key", "report.values"))
