"""Security checks of a graph (``probeless check``) and the CURVE part of the run plan.

Without ``security: {curve: ...}`` a node with ``host:`` binds plain TCP: anyone who reaches the
port can subscribe to its outputs, and whoever binds the port first can feed its subscribers.
``check`` warns about that, and refuses a plain bind on every interface (``0.0.0.0``, ``*``, ``::``).
With CURVE, every key file a TCP socket needs must be readable (errors name the file).
"""

from __future__ import annotations

from probeless.errors import GraphError
from probeless.launch.graph import Graph, NodeDecl
from probeless.launch.validate import split_source
from probeless.runtime.keys import key_name, key_problems
from probeless.runtime.security import is_tcp

ANY_ADDRESS = {"0.0.0.0", "*", "::", "[::]", ""}


def bind_address(endpoint: str) -> str:
    """The address part of ``tcp://ADDRESS:PORT``."""
    return endpoint[len("tcp://"):].rpartition(":")[0]


def check_security(graph: Graph, endpoints: dict[str, str | None]) -> tuple[list[GraphError], list[GraphError]]:
    """(errors, warnings) about TCP endpoints and CURVE keys; ``endpoints``: node id -> tcp endpoint or None."""
    tcp = {n: e for n, e in endpoints.items() if e is not None and is_tcp(e)}
    if not tcp:
        return [], []
    if graph.curve_keys is None:
        return _plain_tcp(graph, tcp)
    if not graph.curve_keys.is_dir():
        return [GraphError(f"CURVE key directory {graph.curve_keys} not found; create it with "
                           f"`probeless keys generate {graph.curve_keys}`", file=graph.file,
                           line=graph.security_line, key="security.curve.keys")], []
    users = set(tcp)
    for decl in graph.nodes.values():
        if any((split_source(graph, inp.source) or ("",))[0] in tcp for inp in decl.inputs.values()):
            users.add(decl.id)
    names = {key_name(graph.curve_keys, graph.nodes[n].host) for n in users}
    return key_problems(graph.curve_keys, names), []


def _plain_tcp(graph: Graph, tcp: dict[str, str]) -> tuple[list[GraphError], list[GraphError]]:
    errors, by_host = [], {}
    for node_id, endpoint in tcp.items():
        decl = graph.nodes[node_id]
        if bind_address(endpoint) in ANY_ADDRESS:
            errors.append(_at(decl, f"binds {endpoint} on every network interface without CURVE: anyone on the "
                                    f"network can read and inject messages; add `security: {{curve: {{keys: DIR}}}}` "
                                    f"or bind one address"))
        by_host.setdefault(decl.host, []).append(decl)
    warnings = [_at(decls[0], f"host {host!r} binds plain TCP (node(s) {', '.join(d.id for d in decls)}) without "
                              f"CURVE: anyone who reaches these ports can subscribe, and a process bound there "
                              f"can inject messages; add `security: {{curve: {{keys: DIR}}}}`")
                for host, decls in by_host.items()]
    return errors, warnings


def _at(decl: NodeDecl, msg: str) -> GraphError:
    return GraphError(msg, file=decl.file, line=decl.lines.get("host", decl.line), node_id=decl.id, key="host")


def curve_plan(graph: Graph, nodes: dict[str, dict]) -> dict | None:
    """``plan["curve"]``, or None without CURVE: the key directory, each node's pair name, and the pair
    behind each tcp endpoint of the plan's ``nodes`` (their ``endpoint`` and ``lossy_endpoint``)."""
    if graph.curve_keys is None:
        return None
    names = {n: key_name(graph.curve_keys, d.host) for n, d in graph.nodes.items()}
    servers = {node[k]: names[node_id] for node_id, node in nodes.items()
               for k in ("endpoint", "lossy_endpoint") if is_tcp(node.get(k) or "")}
    return {"keys": str(graph.curve_keys), "key_names": names, "servers": servers}
