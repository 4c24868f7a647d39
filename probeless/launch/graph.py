"""Launch graph files: dora-rs style dataflows with ROS 2 launch features (args, includes).

::

    args:
      fps: 30                                   # name: default   (or name: {default: .., doc: ..})
    include:
      - {file: camera.yaml, namespace: left, args: {fps: $(arg fps)}}
    nodes:
      - id: blur
        node: image_transform                   # registered name, module:Class or path/to/file.py:Class
        inputs:
          image: {source: left/camera/image, queue_size: 2, policy: latest}
          tick: timer/hz/$(arg fps)             # built-in timer: timer/hz/N, timer/ms/N, timer/s/N
          # all: {source: "*", exclude: [rig/gt/*]} # a pattern: one input per matching topic (launch/globs.py)
        outputs: [image]
        latched: [image]                        # also latched (floorplan, fisheye_from_rgbd, camera_info are)
        params: {operation: blur}
        restart: on-failure                     # never (default) | on-failure
        max_restarts: 3
        restart_backoff_s: 0.5
    security:                                   # optional, top-level file only: CURVE on every tcp socket
      curve: {keys: keys}                       # key directory (``probeless keys generate``), relative to this file

Substitutions in any string: ``$(arg NAME)``, ``$(env NAME)`` / ``$(env NAME default)``,
``$(dirname)`` (this file's directory) and ``$(given NAME THEN ELSE)`` (``THEN`` when argument ``NAME`` was
passed, else ``ELSE``). A string that is exactly one substitution keeps the
value's type. Inside an include, ids and input sources are prefixed with the namespace; a source
starting with ``/`` is absolute.
"""

from __future__ import annotations

import difflib
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from probeless.errors import GraphError
from probeless.launch.args import Substituter, resolve_args
from probeless.launch.relpath import rooted, untag
from probeless.launch.yamlload import LineDict, LineList, load_yaml
from probeless.runtime.latching import parse_latched
from probeless.runtime.queues import POLICIES

TOP_KEYS = {"description", "args", "hosts", "include", "nodes", "security"}
NODE_KEYS = {"id", "node", "inputs", "outputs", "params", "restart", "max_restarts", "restart_backoff_s",
             "host", "description", "latched"}
INPUT_KEYS = {"source", "queue_size", "policy", "feedback", "max_bytes", "exclude", "external"}
EXTERNAL_PREFIX = "external:"   # source of an input read from another running graph (never a node id)
INCLUDE_KEYS = {"file", "namespace", "args"}
DEFAULT_QUEUE = {"policy": "drop_oldest", "queue_size": 10}
_TIMER = re.compile(r"^timer/(hz|ms|s)/([0-9]*\.?[0-9]+)$")
_ID = re.compile(r"^[A-Za-z_][A-Za-z0-9_\-]*(/[A-Za-z_][A-Za-z0-9_\-]*)*$")


@dataclass
class InputDecl:
    """One wired input of a node."""

    name: str
    source: str                     # "<node_id>/<output>" or "timer/<unit>/<value>"
    policy: str = "drop_oldest"
    queue_size: int = 10
    line: int = 0
    timer_period_ns: int | None = None
    feedback: bool = False          # closes a loop: does not keep the node running once its other inputs end
    max_bytes: int | None = None    # byte bound of the queue [bytes]; None = the runtime's default (256 MiB)
    exclude: tuple[str, ...] = ()   # a pattern source's topics to leave out (probeless.launch.globs)
    external: str | None = None     # another running graph (run id or graph file) whose topic this input reads
    resolved: dict | None = None    # external: {run_id, endpoint, type_name}, filled by validate()


@dataclass
class NodeDecl:
    """One node of a graph after args, includes and namespaces are resolved."""

    id: str
    node: str
    file: str
    line: int
    lines: dict = field(default_factory=dict)
    inputs: dict[str, InputDecl] = field(default_factory=dict)
    outputs: list[str] | None = None
    params: dict = field(default_factory=dict)
    param_lines: dict = field(default_factory=dict)
    param_bases: dict = field(default_factory=dict)  # key -> folder a relative path is from (None: working folder)
    restart: str = "never"
    max_restarts: int = 3
    restart_backoff_s: float = 0.5
    host: str | None = None
    topics: dict[str, str] = field(default_factory=dict)  # output -> topic, when not "<id>/<output>"
    output_types: dict[str, str] = field(default_factory=dict)  # output -> type name, for "*" outputs (player)
    latched: dict[str, bool] = field(default_factory=dict)  # output name or glob -> latched (runtime/latching.py)


@dataclass
class Graph:
    """A parsed graph: nodes by id, named hosts, and the parse errors found on the way."""

    file: str
    nodes: dict[str, NodeDecl] = field(default_factory=dict)
    hosts: dict[str, dict] = field(default_factory=dict)
    args: dict[str, Any] = field(default_factory=dict)
    errors: list[GraphError] = field(default_factory=list)
    warnings: list[GraphError] = field(default_factory=list)  # filled by validate(): printed, not fatal
    curve_keys: Path | None = None  # key directory of ``security: {curve: {keys: DIR}}``
    security_line: int = 0          # line of the ``security:`` block (for messages)
    node_classes: dict[str, type] = field(default_factory=dict)  # node id -> Node class, filled by validate()
    cli_args: dict[str, Any] = field(default_factory=dict)  # the name:=value arguments of the command line


def parse_graph(path: str | Path, overrides: dict[str, Any] | None = None) -> Graph:
    """Parse a graph file and its includes. Errors are collected in ``graph.errors``."""
    graph = Graph(str(path), cli_args=dict(overrides or {}))
    cli = {k: rooted(v, None) for k, v in (overrides or {}).items()}  # command-line paths: the working folder's
    _parse_file(Path(path), cli, "", graph, stack=())
    return graph


def _parse_file(path: Path, overrides: dict, ns: str, graph: Graph, stack: tuple) -> None:
    file = str(path)
    if path.resolve() in stack:
        graph.errors.append(GraphError("include cycle: " + " -> ".join(map(str, stack + (path,))), file=file))
        return
    doc = load_yaml(path)
    if not isinstance(doc, LineDict):
        graph.errors.append(GraphError("a graph file must be a mapping with a 'nodes' list", file=file))
        return
    err = _collector(graph, file)
    for key in doc:
        if key not in TOP_KEYS:
            err(f"unknown top-level key{_suggest(key, TOP_KEYS)}", doc.line_of(key), key=key)
    args = resolve_args(doc.get("args"), overrides, err, doc.line_of("args"), is_root=not stack,
                        cli_err=graph.errors.append)
    args = _defaults(args, overrides, doc, path, err)
    if not stack:
        graph.args = dict(args)
    subst = Substituter(args, path.parent, err, given=overrides)
    for name, host in (_mapping(doc, "hosts", err) or {}).items():
        graph.hosts[str(name)] = subst(host, doc.line_of("hosts"))
    if "security" in doc:
        _parse_security(subst(doc["security"], doc.line_of("security")), doc.line_of("security"), path, graph,
                        err, is_root=not stack)
    for i, inc in enumerate(_sequence(doc, "include", err)):
        line = doc["include"].lines[i]
        _include(subst(inc, line), line, path, ns, graph, stack + (path.resolve(),), err)
    for i, raw in enumerate(_sequence(doc, "nodes", err)):
        decl = _parse_node(raw, doc["nodes"].lines[i], ns, file, subst, err)
        if decl is None:
            continue
        if decl.id in graph.nodes:
            err(f"duplicate node id (first at {graph.nodes[decl.id].file}:{graph.nodes[decl.id].line})",
                decl.line, node_id=decl.id, key="id")
            continue
        graph.nodes[decl.id] = decl


def _parse_security(block: Any, line: int, path: Path, graph: Graph, err, is_root: bool) -> None:
    """``security: {curve: {keys: DIR}}``: DIR relative to the graph file."""
    if not is_root:
        err("'security' belongs in the top-level graph file, not in an include", line, key="security")
        return
    curve = block.get("curve") if isinstance(block, dict) else None
    if not isinstance(block, dict) or set(block) != {"curve"} or not isinstance(curve, dict) \
            or set(curve) != {"keys"} or not isinstance(curve["keys"], str) or not curve["keys"]:
        err("'security' must be {curve: {keys: DIR}} (DIR from `probeless keys generate DIR`)", line,
            key="security")
        return
    graph.curve_keys = (path.parent / curve["keys"]).resolve()
    graph.security_line = curve.line_of("keys") if isinstance(curve, LineDict) else line


def _defaults(args: dict, overrides: dict, doc: LineDict, path: Path, err) -> dict:
    """Substitute the defaults: a default may use $(dirname), $(env) and $(arg NAME) of an argument declared
    above it (e.g. ``objects: {default: $(arg scene)}``)."""
    out: dict = {}
    decl = doc.get("args") or {}
    for k, v in args.items():
        if k not in overrides and isinstance(v, str):
            line = decl.line_of(k) if isinstance(decl, LineDict) else doc.line_of("args")
            v = Substituter(dict(out), path.parent, err, given=overrides)(v, line)
        out[k] = v
    return out


def _suggest(key: Any, allowed: set[str]) -> str:
    close = difflib.get_close_matches(str(key), allowed, n=1)
    hint = f"did you mean '{close[0]}'? " if close else ""
    return f" ({hint}allowed: {', '.join(sorted(allowed))})"


def _collector(graph: Graph, file: str):
    def err(msg: str, line: int | None = None, node_id: str | None = None, key: str | None = None) -> None:
        graph.errors.append(GraphError(msg, file=file, line=line, node_id=node_id, key=key))
    return err


def _mapping(doc: LineDict, key: str, err) -> LineDict | None:
    value = doc.get(key)
    if value is not None and not isinstance(value, dict):
        err(f"'{key}' must be a mapping", doc.line_of(key), key=key)
        return None
    return value


def _sequence(doc: LineDict, key: str, err) -> list:
    value = doc.get(key)
    if value is None:
        return []
    if not isinstance(value, LineList):
        err(f"'{key}' must be a list", doc.line_of(key), key=key)
        return []
    return value


def _include(inc: Any, line: int, parent: Path, ns: str, graph: Graph, stack: tuple, err) -> None:
    if not isinstance(inc, dict) or "file" not in inc:
        err("an include needs at least 'file'", line, key="include")
        return
    for key in inc:
        if key not in INCLUDE_KEYS:
            err(f"unknown include key (allowed: {', '.join(sorted(INCLUDE_KEYS))})", inc.line_of(key), key=key)
    path = (parent.parent / str(inc["file"])).resolve()
    if not path.exists():
        err(f"included file not found: {path}", inc.line_of("file"), key="file")
        return
    sub_ns = str(inc.get("namespace") or "")
    if sub_ns and not _ID.match(sub_ns):
        err(f"invalid namespace {sub_ns!r}", inc.line_of("namespace"), key="namespace")
        return
    full_ns = "/".join(p for p in (ns, sub_ns) if p)
    try:
        args = {k: rooted(v, parent.parent) for k, v in (inc.get("args") or {}).items()}  # paths: from this file
        _parse_file(path, args, full_ns, graph, stack)
    except GraphError as exc:
        graph.errors.append(exc)


def _parse_node(raw: Any, line: int, ns: str, file: str, subst: Substituter, err) -> NodeDecl | None:
    if not isinstance(raw, LineDict):
        err("each node must be a mapping with 'id' and 'node'", line)
        return None
    local_id = raw.get("id")
    if not isinstance(local_id, str) or not _ID.match(local_id) or local_id == "timer":
        err(f"invalid or missing node id {local_id!r} (letters, digits, _ and -; 'timer' is reserved)",
            raw.line_of("id"), key="id")
        return None
    node_id = f"{ns}/{local_id}" if ns else local_id
    raw = subst(raw, line)
    for key in raw:
        if key not in NODE_KEYS:
            err(f"unknown node key{_suggest(key, NODE_KEYS)}", raw.line_of(key), node_id, key)
    decl = NodeDecl(node_id, raw.get("node"), file, raw.line, dict(raw.lines))
    if not isinstance(decl.node, str) or not decl.node:
        err("missing 'node' (a registered node type or module:Class)", raw.line, node_id, "node")
        return None
    _parse_inputs(raw.get("inputs"), raw.line_of("inputs"), ns, decl, err)
    outputs = raw.get("outputs")
    if outputs is not None:
        if isinstance(outputs, list) and all(isinstance(o, str) for o in outputs):
            decl.outputs = list(outputs)
        else:
            err("'outputs' must be a list of output names", raw.line_of("outputs"), node_id, "outputs")
    if "latched" in raw:
        decl.latched, problem = parse_latched(raw["latched"])
        if problem:
            err(problem, raw.line_of("latched"), node_id, "latched")
    params = raw.get("params") or LineDict()
    if isinstance(params, dict):
        decl.params, decl.param_bases = untag(dict(params))
        decl.param_lines = dict(getattr(params, "lines", {}))
    else:
        err("'params' must be a mapping", raw.line_of("params"), node_id, "params")
    _parse_lifecycle(raw, decl, err)
    return decl


def _parse_lifecycle(raw: LineDict, decl: NodeDecl, err) -> None:
    decl.restart = raw.get("restart", "never")
    if decl.restart not in ("never", "on-failure"):
        err("restart must be 'never' or 'on-failure'", raw.line_of("restart"), decl.id, "restart")
    decl.max_restarts = raw.get("max_restarts", 3)
    if type(decl.max_restarts) is not int or decl.max_restarts < 0:
        err("max_restarts must be an integer >= 0", raw.line_of("max_restarts"), decl.id, "max_restarts")
    decl.restart_backoff_s = raw.get("restart_backoff_s", 0.5)
    if not isinstance(decl.restart_backoff_s, (int, float)) or decl.restart_backoff_s < 0:
        err("restart_backoff_s must be a number >= 0", raw.line_of("restart_backoff_s"), decl.id,
            "restart_backoff_s")
    host = raw.get("host")
    if host is not None and not isinstance(host, str):
        err("host must be a host name from 'hosts:' or ADDRESS:PORT", raw.line_of("host"), decl.id, "host")
    decl.host = host


def _parse_inputs(inputs: Any, line: int, ns: str, decl: NodeDecl, err) -> None:
    if inputs is None:
        return
    if not isinstance(inputs, LineDict):
        err("'inputs' must be a mapping of input name: source", line, decl.id, "inputs")
        return
    for name, spec in inputs.items():
        iline = inputs.line_of(name)
        key = f"inputs.{name}"
        if isinstance(spec, str):
            spec = {"source": spec}
        if not isinstance(spec, dict) or not isinstance(spec.get("source"), str):
            err("an input is 'node_id/output', 'timer/hz/N' or {source, queue_size, policy}", iline, decl.id, key)
            continue
        for k in spec:
            if k not in INPUT_KEYS:
                err(f"unknown input key {k!r} (allowed: {', '.join(sorted(INPUT_KEYS))})", iline, decl.id, key)
        policy = spec.get("policy", DEFAULT_QUEUE["policy"])
        size = spec.get("queue_size", 1 if policy == "latest" else DEFAULT_QUEUE["queue_size"])
        if policy not in POLICIES:
            err(f"unknown policy {policy!r} (allowed: {', '.join(POLICIES)})", iline, decl.id, key)
            continue
        if type(size) is not int or size < 1:
            err(f"queue_size must be an integer >= 1, got {size!r}", iline, decl.id, key)
            continue
        if policy == "latest" and size != 1:
            err("policy 'latest' keeps one message; omit queue_size or set it to 1", iline, decl.id, key)
            continue
        feedback = spec.get("feedback", False)
        if not isinstance(feedback, bool):
            err(f"feedback must be true or false, got {feedback!r}", iline, decl.id, key)
            continue
        max_bytes = spec.get("max_bytes")
        if max_bytes is not None and (type(max_bytes) is not int or max_bytes < 1):
            err(f"max_bytes must be an integer >= 1 [bytes], got {max_bytes!r}", iline, decl.id, key)
            continue
        exclude = spec.get("exclude", [])
        if not isinstance(exclude, list) or not all(isinstance(x, str) and x for x in exclude):
            err(f"exclude must be a list of topic patterns, got {exclude!r}", iline, decl.id, key)
            continue
        if exclude and not any(c in "*?[" for c in spec["source"]):
            err("exclude applies to a pattern source (with *, ? or [) only", iline, decl.id, key)
            continue
        if "external" in spec:
            _external_input(str(name), spec, policy, size, iline, decl, err)
            continue
        decl.inputs[str(name)] = _input(str(name), spec["source"], ns, policy, size, iline, decl.id, err)
        decl.inputs[str(name)].feedback = feedback
        decl.inputs[str(name)].max_bytes = max_bytes
        decl.inputs[str(name)].exclude = tuple(_namespaced(x, ns) for x in exclude)


def _external_input(name: str, spec: dict, policy: str, size: int, line: int, decl: NodeDecl, err) -> None:
    """``{source: TOPIC, external: RUN_ID|GRAPH_FILE}``: a topic of another running graph (launch/external.py)."""
    key, external, source = f"inputs.{name}", spec["external"], spec["source"]
    if not isinstance(external, str) or not external:
        err("external must name a running graph: its run id (`probeless runs`) or its graph file", line,
            decl.id, key)
    elif policy == "block":
        err("an external input cannot use policy 'block' (it would hold up the other graph); use latest or "
            "drop_oldest", line, decl.id, key)
    elif any(c in source for c in "*?[") or source.startswith("timer/"):
        err("an external input names one topic of the other graph, e.g. cam/image", line, decl.id, key)
    else:
        inp = InputDecl(name, EXTERNAL_PREFIX + source.lstrip("/"), policy, size, line)
        inp.external = external
        decl.inputs[name] = inp


def _input(name: str, source: str, ns: str, policy: str, size: int, line: int, node_id: str, err) -> InputDecl:
    inp = InputDecl(name, source, policy, size, line)
    if source.startswith("timer/"):
        m = _TIMER.match(source)
        if "$(" in source:
            return inp  # an argument that was not given or was out of range: reported where it was passed
        if m and float(m.group(2)) <= 0:
            err(f"timer {source!r}: the {'rate' if m.group(1) == 'hz' else 'period'} must be above 0, "
                f"got {m.group(2)}", line, node_id, f"inputs.{name}")
            return inp
        if not m:
            err(f"invalid timer {source!r} (use timer/hz/N, timer/ms/N or timer/s/N)", line, node_id,
                f"inputs.{name}")
            return inp
        value = float(m.group(2))
        inp.timer_period_ns = int({"hz": 1e9 / value, "ms": value * 1e6, "s": value * 1e9}[m.group(1)])
        return inp
    inp.source = _namespaced(source, ns)
    return inp


def _namespaced(source: str, ns: str) -> str:
    """A source (or topic pattern) inside namespace ``ns``; a leading ``/`` makes it absolute."""
    return source[1:] if source.startswith("/") else (f"{ns}/{source}" if ns else source)
