"""ZeroMQ CURVE on a node's TCP sockets: encryption and authentication for graphs that span hosts.

The launcher's plan carries ``plan["curve"] = {"keys": DIR, "key_names": {node_id: pair},
"servers": {tcp_endpoint: pair}}`` when the graph has ``security: {curve: {keys: DIR}}``. In a
node process, :func:`node_curve` reads its own pair from DIR (on first use); then

- a publisher that binds ``tcp://`` is a CURVE server with that secret key, and a ZAP handler
  (one :class:`zmq.auth.thread.ThreadAuthenticator` per process) accepts only clients whose
  public key is in ``DIR/public/``;
- a SUB that connects to ``tcp://`` is a CURVE client with its pair and the publishing node's
  public key, so it talks to no other server.

``ipc://`` sockets are left alone: they live in the private run directory.
"""

from __future__ import annotations

import logging
from pathlib import Path

import zmq
from zmq.auth.thread import ThreadAuthenticator

from probeless.errors import GraphError
from probeless.runtime.keys import DEFAULT_KEY, allowed_dir, load_pair, load_public, secret_file

log = logging.getLogger("probeless.security")


def is_tcp(endpoint: str) -> bool:
    """True for endpoints that cross the network."""
    return endpoint.startswith("tcp://")


class NodeCurve:
    """The CURVE keys of one node process and its ZAP authenticator (started on the first server)."""

    def __init__(self, keys_dir: str | Path, key_names: dict[str, str], servers: dict[str, str], node_id: str):
        self.keys_dir = Path(keys_dir)
        self.key_names, self.servers = key_names, servers
        self.node_id = node_id
        self.auth: ThreadAuthenticator | None = None
        self._pair: tuple[bytes, bytes] | None = None

    def pair(self) -> tuple[bytes, bytes]:
        """(public, secret) of this node's pair, read on first use: ipc-only nodes need no key file.

        A process that is no node of the graph (a topic tool, an attached recorder) uses the pair
        ``graph`` when its secret is on this machine, else the first host pair whose secret is.
        """
        if self._pair is None:
            name = self.key_names.get(self.node_id)
            if name is None:
                names = [DEFAULT_KEY] + sorted(set(self.key_names.values()))
                name = next((n for n in names if secret_file(self.keys_dir, n).exists()), DEFAULT_KEY)
            self._pair = load_pair(self.keys_dir, name)
        return self._pair

    def server(self, zctx: zmq.Context, sock: zmq.Socket, endpoint: str) -> None:
        """Make ``sock`` a CURVE server before it binds ``endpoint`` (tcp only)."""
        if not is_tcp(endpoint):
            return
        public_secret = self.pair()
        if self.auth is None:
            allowed = allowed_dir(self.keys_dir)
            self.auth = ThreadAuthenticator(zctx, log=log)
            self.auth.start()  # the ZAP handler exists before any peer can connect
            self.auth.configure_curve(domain="*", location=str(allowed))
        sock.curve_publickey, sock.curve_secretkey = public_secret
        sock.curve_server = True

    def client(self, sock: zmq.Socket, endpoint: str) -> None:
        """Make ``sock`` a CURVE client of the graph's publisher at ``endpoint`` before it connects (tcp only)."""
        if not is_tcp(endpoint):
            return
        if endpoint not in self.servers:
            raise GraphError(f"node {self.node_id!r}: {endpoint} is no publisher of this graph; no CURVE server key")
        sock.curve_serverkey = load_public(self.keys_dir, self.servers[endpoint])
        sock.curve_publickey, sock.curve_secretkey = self.pair()

    def stop(self) -> None:
        """Stop the authenticator (before the context terminates)."""
        if self.auth is not None:
            self.auth.stop()
            self.auth = None


def node_curve(plan: dict, node_id: str) -> NodeCurve | None:
    """The node's CURVE keys when the plan asks for CURVE, else None (plain sockets)."""
    curve = plan.get("curve")
    if not curve:
        return None
    return NodeCurve(curve["keys"], curve["key_names"], curve["servers"], node_id)


def tool_curve(plan: dict, tool_id: str = "__tool__") -> NodeCurve | None:
    """CURVE keys for a tool joining a running graph (see :meth:`NodeCurve.pair`); None without CURVE."""
    return node_curve(plan, tool_id)
