"""Foxglove bridge node: the graph's topics live in Foxglove, through the Foxglove SDK's WebSocket server.

Open Foxglove, "Open connection", ``ws://127.0.0.1:8765`` (the URL is logged at start). Every wired input
whose type has a Foxglove equivalent becomes a channel in the schemas of ``probeless bag export --format
foxglove`` (:mod:`probeless.bag.foxglove`: images, depth, poses, point clouds, meshes; JSON encoding), so
a recording exported to MCAP and the live graph look the same. Channels are advertised at start when the
plan knows the input's type, else on the input's first message (a ``bag_player``'s ``*`` outputs).

Only what a client subscribes to costs anything: inputs are raw (``RAW_INPUTS``), and a message on a
channel no client subscribes to is neither decoded nor converted, only counted. The counts per topic
(sent, skipped) are logged when the node stops; the ``encode`` stage of its diagnostics times the rest.

Lossy by construction, so a slow viewer never slows the graph: wire the inputs with ``policy: latest``
(the bridge drops what it cannot convert in time), and the server keeps at most ``message_backlog_size``
messages per client: when a client reads slower than the graph publishes, the SDK drops that client's
*oldest* queued message for each new one (its control queue is the same size; if that fills, the SDK
disconnects the client). :meth:`foxglove.Channel.log` never waits for a client.

The server has no authentication: binding anything but a loopback address logs a warning.
"""

from __future__ import annotations

import ipaddress
from dataclasses import dataclass

import foxglove

from probeless import wire
from probeless.bag.foxglove import SCHEMA_OF_TYPE, encode, schema_json, to_foxglove
from probeless.errors import ParamError, SchemaError
from probeless.runtime import Node, param
from probeless.runtime.receiver import RawMessage


def is_loopback(host: str) -> bool:
    """Whether ``host`` only accepts connections from this machine."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


class _LogNotes:
    """Lossy-conversion notes (float images through the sRGB curve...), each logged once."""

    def __init__(self, log) -> None:
        self.log, self.seen = log, set()

    def note(self, text: str) -> None:
        if text not in self.seen:
            self.seen.add(text)
            self.log.info("%s", text)


class FoxgloveBridge(Node):
    """Serves its raw inputs to Foxglove clients over WebSocket (``foxglove.sdk.v1``), converting on demand."""

    INPUTS = {"*": None}
    RAW_INPUTS = True

    @dataclass(frozen=True)
    class Params:
        host: str = param("127.0.0.1", doc="address to listen on; not loopback = open to the network, no auth")
        port: int = param(8765, min=0, max=65535, doc="WebSocket port; 0 = any free port (logged)")
        message_backlog_size: int = param(8, min=1, max=100_000,
                                          doc="messages queued per client; when full the oldest is dropped")
        name: str = param("probeless", doc="server name shown by Foxglove")

    def setup(self) -> None:
        p = self.params
        self.fctx = foxglove.Context()
        self.channels: dict[str, foxglove.Channel | None] = {}   # topic -> channel; None = not shown
        self.sent: dict[str, int] = {}
        self.skipped: dict[str, int] = {}
        self.failed: dict[str, int] = {}     # messages that would not decode
        self.notes = _LogNotes(self.ctx.log)
        if not is_loopback(p.host):
            self.ctx.log.warning("listening on %s: any machine that reaches it sees the graph's data "
                                 "(the Foxglove WebSocket server has no authentication)", p.host)
        try:
            self.server = foxglove.start_server(name=p.name, host=p.host, port=p.port, context=self.fctx,
                                                message_backlog_size=p.message_backlog_size)
        except RuntimeError as exc:  # the SDK's FoxgloveError: port in use, unknown host
            raise ParamError(f"cannot serve Foxglove on {p.host}:{p.port}: {exc}"
                             + (" (another bridge? set port: 0 for any free port)" if "in use" in str(exc) else ""),
                             node_id=self.ctx.node_id, key="port") from None
        self._advertise_known()
        self.ctx.log.info("Foxglove: open connection ws://%s:%d", _url_host(p.host), self.server.port)

    def _advertise_known(self) -> None:
        """Channels for every input whose type the plan knows, so clients see them before any message."""
        plan = getattr(self.ctx, "plan", None) or {}
        inputs = plan.get("nodes", {}).get(self.ctx.node_id, {}).get("inputs", [])
        hidden = []
        for inp in inputs:
            if inp.get("type_name") and "topic" in inp:
                if self._channel(inp["topic"], inp["type_name"]) is None:
                    hidden.append(f"{inp['topic']} ({inp['type_name']})")
        if hidden:
            self.ctx.log.info("not shown in Foxglove (no Foxglove equivalent): %s", ", ".join(hidden))

    def _channel(self, topic: str, type_name: str) -> foxglove.Channel | None:
        if topic not in self.channels:
            schema = SCHEMA_OF_TYPE.get(type_name)
            self.channels[topic] = None if schema is None else foxglove.Channel(
                topic, schema=foxglove.Schema(name=schema, encoding="jsonschema", data=schema_json(schema)),
                message_encoding="json", context=self.fctx)
        return self.channels[topic]

    def on_input(self, name: str, msg: RawMessage) -> None:
        known = msg.topic in self.channels
        channel = self._channel(msg.topic, msg.type_name)
        if channel is None:
            if not known:
                self.ctx.log.info("not shown in Foxglove: %s (%s has no Foxglove equivalent)", msg.topic,
                                  msg.type_name)
            return
        if not channel.has_sinks():
            self.skipped[msg.topic] = self.skipped.get(msg.topic, 0) + 1
            return
        try:
            with self.ctx.timed("encode"):
                decoded = wire.decode([msg.topic.encode(), *msg.frames])[2]
                _, doc = to_foxglove(msg.type_name, decoded, msg.topic, self.notes)
                data = encode(doc)
        except SchemaError as exc:  # e.g. a recording of another schema version: the viewer goes on
            self.failed[msg.topic] = self.failed.get(msg.topic, 0) + 1
            if self.failed[msg.topic] == 1:
                self.ctx.log.warning("not shown in Foxglove: %s (later ones counted at the end)", exc)
            return
        channel.log(data, log_time=msg.stamp_ns)
        self.sent[msg.topic] = self.sent.get(msg.topic, 0) + 1

    def close(self) -> None:
        if not hasattr(self, "server"):
            return  # setup failed before the server started
        self.server.stop()
        for topic, channel in sorted(self.channels.items()):
            if channel is not None:
                failed = f", {self.failed[topic]} not decodable" if topic in self.failed else ""
                self.ctx.log.info("%s: %d sent, %d skipped (no subscriber)%s", topic, self.sent.get(topic, 0),
                                  self.skipped.get(topic, 0), failed)


def _url_host(host: str) -> str:
    if host in ("0.0.0.0", "::", ""):
        return "127.0.0.1"  # listening everywhere: this machine's loopback reaches it
    return f"[{host}]" if ":" in host else host
