"""Graph validation without starting anything: node types, params, wiring, types, hosts, cycles, security."""

from __future__ import annotations

import difflib
import fnmatch
from pathlib import Path
from typing import Any

from probeless.errors import GraphError, ParamError
from probeless.launch.globs import expand_patterns
from probeless.launch.graph import Graph, NodeDecl
from probeless.launch.relpath import explain, root_input_paths
from probeless.runtime.node import input_type, output_type
from probeless.runtime.params import check_params
from probeless.runtime.registry import resolve_node


def validate(graph: Graph) -> list[GraphError]:
    """All errors of a parsed graph (parse errors first). Also fills ``node_classes`` for the plan and
    ``warnings`` (e.g. plain TCP without CURVE)."""
    errors = list(graph.errors)
    classes: dict[str, type] = {}
    for decl in graph.nodes.values():
        try:
            classes[decl.id] = resolve_node(decl.node, base=Path(decl.file).parent)
        except GraphError as exc:
            errors.append(GraphError(exc.message, file=decl.file, line=decl.lines.get("node", decl.line),
                                     node_id=decl.id, key="node"))
    errors += expand_patterns(graph, classes)
    for decl in graph.nodes.values():
        cls = classes.get(decl.id)
        if cls is None:
            continue
        rooted = root_input_paths(decl.params, decl.param_bases, cls.Params, Path(decl.file).parent)
        errors += explain(check_params(cls.Params, decl.params, node_id=decl.id, file=decl.file,
                                       lines=decl.param_lines, line=decl.lines.get("params", decl.line)), rooted)
        errors += _check_outputs(decl, cls)
        errors += _check_latched(decl, cls)
        errors += _check_inputs(graph, decl, cls, classes)
        errors += _check_host(graph, decl)
    errors += _check_cycles(graph)
    errors += _check_lockstep(graph, classes)
    errors += _check_security(graph)
    graph.node_classes = classes
    return _merge_arg_errors(graph, errors)


def _merge_arg_errors(graph: Graph, errors: list[GraphError]) -> list[GraphError]:
    """Param errors caused by one bad command-line value (``scene:=nope.yaml`` used by three nodes) become a
    single command-line error naming the argument and every param it reached."""
    out, merged = [], {}
    for e in errors:
        arg = _arg_at_fault(graph, e) if isinstance(e, ParamError) else None
        if arg is None:
            out.append(e)
        elif (arg, e.message) in merged:
            merged[(arg, e.message)].append(e)
        else:
            merged[(arg, e.message)] = [e]
            out.append((arg, e.message))
    result = []
    for item in out:
        if isinstance(item, GraphError):
            result.append(item)
            continue
        arg, message = item
        used = ", ".join(f"{e.node_id}.{e.key} ({e.file}:{e.line})" for e in merged[item])
        result.append(GraphError(f"argument {arg}:={graph.cli_args[arg]}: {message} (used by {used})",
                                 file="command line"))
    return result


def _arg_at_fault(graph: Graph, e: GraphError) -> str | None:
    """The command-line argument whose (text) value the error is about, if any."""
    for name, value in graph.cli_args.items():
        if isinstance(value, str) and value and e.message.startswith(f"{value}:"):
            return name
    return None


def _check_security(graph: Graph) -> list[GraphError]:
    """TCP without CURVE (warnings; an error on every interface), or unusable CURVE key files."""
    from probeless.launch.secure import check_security  # secure.py builds on this module

    endpoints = {}
    for decl in graph.nodes.values():
        if decl.host is None or decl.host in graph.hosts or _literal_host(decl.host):
            endpoints[decl.id] = host_endpoint(graph, decl)
    errors, graph.warnings = check_security(graph, endpoints)
    return errors


def split_source(graph: Graph, source: str) -> tuple[str, str] | None:
    """(node_id, output) of an input source, matching the longest existing node id prefix."""
    parts = source.split("/")
    for cut in range(len(parts) - 1, 0, -1):
        node_id = "/".join(parts[:cut])
        if node_id in graph.nodes:
            return node_id, "/".join(parts[cut:])
    return None


def _err(decl: NodeDecl, msg: str, key: str, line: int | None = None) -> GraphError:
    return GraphError(msg, file=decl.file, line=line or decl.lines.get(key.split(".")[0], decl.line),
                      node_id=decl.id, key=key)


def _check_outputs(decl: NodeDecl, cls: type) -> list[GraphError]:
    errors = []
    for out in decl.outputs or []:
        if not output_type(cls, out)[0]:
            errors.append(_err(decl, f"{decl.node} has no output {out!r} (declared: "
                                     f"{', '.join(cls.OUTPUTS) or 'none'})", "outputs"))
    return errors


def _check_latched(decl: NodeDecl, cls: type) -> list[GraphError]:
    """Every name of a node's ``latched:`` key is one of its outputs; every glob matches one."""
    errors = []
    outs = [o for o in _outputs_of(decl, cls) if o != "diagnostics"]
    for name in decl.latched:
        if any(c in name for c in "*?["):
            if not any(fnmatch.fnmatchcase(o, name) for o in outs):
                errors.append(_err(decl, f"latched: {name!r} matches no output of {decl.node} (outputs: "
                                         f"{', '.join(outs) or 'none'})", "latched"))
        elif name == "diagnostics" or not output_type(cls, name)[0] or (decl.outputs is not None
                                                                       and name not in decl.outputs):
            errors.append(_err(decl, f"latched: {decl.node} has no output {name!r} "
                                     f"({_did_you_mean(name, outs)}outputs: {', '.join(outs) or 'none'})",
                               "latched"))
    return errors


def _check_inputs(graph: Graph, decl: NodeDecl, cls: type, classes: dict) -> list[GraphError]:
    errors = []
    for inp in decl.inputs.values():
        key = f"inputs.{inp.name}"
        declared, want = input_type(cls, inp.name)
        if not declared:
            errors.append(_err(decl, f"{decl.node} has no input {inp.name!r} (declared: "
                                     f"{', '.join(cls.INPUTS) or 'none'})", key, inp.line))
            continue
        if inp.external is not None:
            from probeless.launch.external import check_external  # external.py builds on the graph module
            errors += check_external(decl, inp, want)
            continue
        if inp.timer_period_ns is not None:
            from probeless.messages.header import Tick
            if want is not None and want is not Tick:
                errors.append(_err(decl, f"timer input delivers core/Tick, input expects {want.TYPE_NAME}",
                                   key, inp.line))
            continue
        if inp.source.startswith("timer/"):
            continue  # malformed timer, reported by the parser
        split = split_source(graph, inp.source)
        if split is None:
            errors.append(_err(decl, f"dangling input: no node publishes {inp.source!r} "
                                     f"({_did_you_mean(inp.source, _all_topics(graph, classes))}"
                                     f"expected '<node_id>/<output>')", key, inp.line))
            continue
        src_id, out = split
        src = graph.nodes[src_id]
        src_cls = classes.get(src_id)
        if src_cls is None:
            continue
        has, got = output_type(src_cls, out)
        if not has or (src.outputs is not None and out not in src.outputs and out != "diagnostics"):
            outs = _outputs_of(src, src_cls)
            errors.append(_err(decl, f"dangling input: node {src_id!r} ({src.node}) has no output {out!r} "
                                     f"({_did_you_mean(out, outs)}outputs: {', '.join(outs) or 'none'})",
                               key, inp.line))
        elif want is not None and got is not None and want.TYPE_NAME != got.TYPE_NAME:
            errors.append(_err(decl, f"type mismatch: {src_id}/{out} publishes {got.TYPE_NAME}, "
                                     f"input {inp.name!r} expects {want.TYPE_NAME}", key, inp.line))
    return errors


def _did_you_mean(name: str, candidates: list[str]) -> str:
    close = difflib.get_close_matches(name, candidates, n=1)
    return f"did you mean '{close[0]}'? " if close else ""


def _outputs_of(decl: NodeDecl, cls: type) -> list[str]:
    """The output names a node offers in this graph (its ``outputs:`` list, else its class's)."""
    names = decl.outputs if decl.outputs is not None else [o for o in cls.OUTPUTS if not o.endswith("*")]
    return list(names) + ["diagnostics"]


def _all_topics(graph: Graph, classes: dict) -> list[str]:
    return [f"{d.id}/{o}" for d in graph.nodes.values() if d.id in classes for o in _outputs_of(d, classes[d.id])]


def _check_host(graph: Graph, decl: NodeDecl) -> list[GraphError]:
    errors = []
    if decl.host is not None and decl.host not in graph.hosts and not _literal_host(decl.host):
        errors.append(_err(decl, f"unknown host {decl.host!r} (declare it under 'hosts:' or use ADDRESS:PORT)",
                           "host"))
    for inp in decl.inputs.values():
        split = split_source(graph, inp.source) if inp.timer_period_ns is None else None
        if split and graph.nodes[split[0]].host != decl.host and graph.nodes[split[0]].host is None:
            errors.append(_err(decl, f"input crosses hosts but node {split[0]!r} has no 'host:', so its "
                                     f"outputs are local ipc endpoints", f"inputs.{inp.name}", inp.line))
    return errors


def _literal_host(host: str) -> tuple[str, int] | None:
    addr, _, port = host.rpartition(":")
    return (addr, int(port)) if addr and port.isdigit() and 0 < int(port) < 65536 else None


def host_endpoint(graph: Graph, decl: NodeDecl) -> str | None:
    """tcp endpoint of a node's outputs when it declares a host, else None (ipc)."""
    if decl.host is None:
        return None
    literal = _literal_host(decl.host)
    if literal:
        return f"tcp://{_bracket(literal[0])}:{literal[1]}"
    host = graph.hosts[decl.host]
    same = [d.id for d in graph.nodes.values() if d.host == decl.host]
    # two ports per node: PORT (lossless, for 'block' inputs) and PORT+1 (lossy: latest, drop_oldest, tools)
    port = int(host.get('port_base', 7400)) + 2 * same.index(decl.id)
    return f"tcp://{_bracket(str(host.get('address', '127.0.0.1')))}:{port}"


def _bracket(address: str) -> str:
    """An IPv6 address in the brackets a ZeroMQ endpoint needs (``::`` -> ``[::]``); others unchanged."""
    return f"[{address}]" if ":" in address and not address.startswith("[") else address


def _check_lockstep(graph: Graph, classes: dict) -> list[GraphError]:
    """One lockstep player at most: each waits until every other node is idle, so two would wait for each
    other forever."""
    players = [d for d in graph.nodes.values()
               if getattr(classes.get(d.id), "plays_lockstep", lambda params: False)(d.params)]
    return [_err(d, f"a second lockstep player: {players[0].id!r} and {d.id!r} both play in lockstep (rate: 0 or "
                    f"lockstep: true) and would wait for each other forever; give one a rate > 0", "params")
            for d in players[1:]]


def _check_cycles(graph: Graph) -> list[GraphError]:
    """A cycle is an error when every input on it has policy 'block' (it could deadlock)."""
    edges: dict[str, list[tuple[str, Any]]] = {n: [] for n in graph.nodes}
    for decl in graph.nodes.values():
        for inp in decl.inputs.values():
            split = split_source(graph, inp.source) if inp.timer_period_ns is None else None
            if split and inp.policy == "block":
                edges[split[0]].append((decl.id, inp))
    errors, state = [], {}

    def visit(node: str, path: list[str]) -> None:
        state[node] = 1
        for nxt, inp in edges[node]:
            if state.get(nxt) == 1:
                cycle = path[path.index(nxt):] + [nxt] if nxt in path else [node, nxt]
                decl = graph.nodes[nxt]
                errors.append(_err(decl, "cycle of blocking inputs " + " -> ".join(cycle) +
                                   " could deadlock; give one input on it policy latest or drop_oldest",
                                   f"inputs.{inp.name}", inp.line))
            elif state.get(nxt) is None:
                visit(nxt, path + [nxt])
        state[node] = 2

    for node in graph.nodes:
        if state.get(node) is None:
            visit(node, [node])
    return errors
