"""Rerun sink: logs every topic it is wired to as Rerun archetypes (entity tree: probeless/viz/rerun_logger.py).

Sinks, any together: ``serve`` (a gRPC server on 127.0.0.1:``grpc_port`` holding the data, and the web viewer's
pages on ``web_port``, which the SDK binds on all interfaces; the URL to open is logged at INFO), ``spawn`` (the
native viewer, needs a display; on ``grpc_port`` or, when serving too, ``grpc_port + 1``), ``rrd`` (a file).
The default layout is sent at setup. Logging is asynchronous in the SDK; ``max_hz`` bounds the work per topic so
the sink never slows the graph, and a message that cannot be logged is counted as skipped, never raised.
"""

from __future__ import annotations

import os
import socket
import sys
import time
import urllib.parse
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import rerun as rr

from probeless import wire
from probeless.errors import ParamError, TransportError
from probeless.runtime import Node, param
from probeless.runtime.receiver import RawMessage
from probeless.viz.blueprint import default_blueprint
from probeless.viz.rerun_logger import RerunLogger


def _pairs_problem(pairs: tuple[str, ...]) -> str | None:
    bad = [p for p in pairs if p.count("=") != 1 or not all(p.split("="))]
    return f"pairs must be 'mesh_topic=atlas_topic', got {bad}" if bad else None


def _sink_problem(serve: bool, params) -> str | None:
    if not (serve or params.spawn or params.rrd):
        return "no sink chosen: set serve: true, spawn: true or rrd: FILE"
    return None


def check_port_free(port: int, param_name: str) -> None:
    """TransportError naming the param when 127.0.0.1:``port`` cannot be bound (Rerun's gRPC server only logs it)."""
    with socket.socket() as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind(("127.0.0.1", port))
        except OSError as exc:
            raise TransportError(f"rerun_sink {param_name} {port}: cannot listen: {exc.strerror or exc}") from None


def has_display() -> bool:
    """Whether a native viewer can open a window here (on Linux: an X11 or Wayland display is set)."""
    return not sys.platform.startswith("linux") or bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def web_viewer_url(web_port: int, grpc_url: str) -> str:
    """The web viewer's address with the gRPC server to read from in its query."""
    return f"http://127.0.0.1:{web_port}/?url={urllib.parse.quote(grpc_url, safe=':/')}"


class RerunSink(Node):
    """Any input (one per topic, named by it) -> a Rerun recording: served, spawned and/or written."""

    INPUTS = {"*": None}
    RAW_INPUTS = True   # decode only what is logged: not what max_hz drops, not types without a mapping

    @dataclass(frozen=True)
    class Params:
        spawn: bool = param(False, doc="spawn the native Rerun viewer (needs a display)")
        serve: bool = param(False, check=_sink_problem,
                            doc="serve the web viewer (web_port) fed by a gRPC server on localhost (grpc_port)")
        web_port: int = param(9090, min=1, max=65535, doc="web viewer port (http://127.0.0.1:PORT)")
        grpc_port: int = param(9876, min=1, max=65535, doc="gRPC port the viewers read from")
        rrd: str = param("", doc="also write the recording to this .rrd file; '' = no file")
        memory_limit: str = param("512MiB", doc="buffer of the served or spawned viewer, e.g. 512MiB, 2GiB, 25%")
        open_browser: bool = param(False, doc="serve: also open the web viewer in the default browser")
        max_hz: float = param(0.0, min=0.0, doc="log at most this many messages per second per topic; 0 = all")
        linger_s: float = param(0.0, min=0.0, max=3600.0, doc="serve: keep serving this long after the inputs "
                                "end, so a web viewer still catching up reads the whole run [s]")
        jpeg_quality: int = param(0, min=0, max=100, doc="send 8-bit grey/RGB images as JPEG of this quality "
                                  "(a tenth of the bytes for the viewer); 0 = raw pixels")
        application_id: str = param("probeless", doc="Rerun application id (the viewer keys layouts by it)")
        texture_period_s: float = param(1.0, min=0.0, doc="re-texture a mesh with a new atlas at most this often [s]")
        pairs: tuple[str, ...] = param((), check=_pairs_problem,
                                       doc="mesh_topic=atlas_topic texture pairs beyond X/mesh=X/atlas")

    def setup(self) -> None:
        p = self.params
        if not (p.spawn or p.serve or p.rrd):
            raise ParamError("no sink chosen: set serve: true, spawn: true or rrd: FILE", node_id=self.ctx.node_id,
                             key="serve/spawn/rrd")
        if p.spawn and not has_display():  # the SDK would wait for a viewer that never starts, then drop the data
            raise ParamError("spawn: true needs a display (DISPLAY or WAYLAND_DISPLAY is unset); use serve: true "
                             "and open the web viewer instead", node_id=self.ctx.node_id, key="spawn")
        spec = (self.ctx.plan.get("nodes") or {}).get(self.ctx.node_id, {})
        self.topics = {i["name"]: i.get("topic", i["name"]) for i in spec.get("inputs", []) if "name" in i}
        self.stream = rr.RecordingStream(p.application_id)
        self.stream.set_sinks(*self._sinks())
        self.stream.send_blueprint(default_blueprint())
        self.logger = RerunLogger(self.stream, pairs=dict(s.split("=") for s in p.pairs),
                                  texture_period_s=p.texture_period_s, blueprint=default_blueprint,
                                  jpeg_quality=p.jpeg_quality)
        self.period = 1.0 / p.max_hz if p.max_hz > 0 else 0.0
        self.last: dict[str, float] = {}
        self.dropped: dict[str, int] = defaultdict(int)

    def _sinks(self) -> list:
        p, sinks = self.params, []
        if p.serve:
            check_port_free(p.grpc_port, "grpc_port")
            server = rr.GrpcServerSink("127.0.0.1", p.grpc_port, server_memory_limit=p.memory_limit)
            sinks.append(server)
            try:
                rr.serve_web_viewer(web_port=p.web_port, open_browser=p.open_browser, connect_to=server.uri)
            except RuntimeError as exc:
                raise TransportError(f"rerun_sink web_port {p.web_port}: {exc}") from None
            self.ctx.log.info("Rerun web viewer: %s", web_viewer_url(p.web_port, server.uri))
        if p.spawn:
            port = p.grpc_port + 1 if p.serve else p.grpc_port
            rr.spawn(port=port, connect=False, memory_limit=p.memory_limit)
            sinks.append(rr.GrpcSink(f"rerun+http://127.0.0.1:{port}/proxy"))
            self.ctx.log.info("Rerun native viewer spawned on port %d", port)
        if p.rrd:
            Path(p.rrd).parent.mkdir(parents=True, exist_ok=True)
            sinks.append(rr.FileSink(p.rrd))
            self.ctx.log.info("writing Rerun recording %s", p.rrd)
        return sinks

    def on_input(self, name: str, raw: RawMessage) -> None:
        topic = self.topics.get(name, name)
        if not self.logger.handles(raw.type_name):
            self.logger.skip(topic, f"{raw.type_name} has no Rerun mapping")
            return
        if self.period:
            now = time.monotonic()
            if now - self.last.get(topic, -1e18) < self.period:
                self.dropped[topic] += 1
                return
            self.last[topic] = now
        with self.ctx.timed("log"):
            try:
                self.logger.log(topic, wire.decode([raw.topic.encode(), *raw.frames])[2])
            except Exception as exc:  # a message the viewer cannot show must not stop the graph
                if topic not in self.logger.reasons:
                    self.ctx.log.warning("rerun: %s: cannot log %s: %s", topic, raw.type_name.rpartition("/")[2], exc)
                self.logger.skip(topic, f"error: {exc}")

    def close(self) -> None:
        logger = getattr(self, "logger", None)
        if logger is None:
            return
        try:
            self.stream.flush(timeout_sec=10.0)
        except Exception as exc:  # a viewer gone away must not fail the graph's shutdown
            self.ctx.log.warning("rerun: flush failed: %s", exc)
        dropped = sum(self.dropped.values())
        self.ctx.log.info("%s; %d dropped by max_hz", logger.summary_line(), dropped)
        if self.params.serve and self.params.linger_s > 0:
            # the web viewer reads from our gRPC server: a viewer still catching up keeps getting data
            self.ctx.log.info("serving the run to web viewers for %g s more (Ctrl-C ends it)",
                              self.params.linger_s)
            self._linger(self.params.linger_s)
        self.stream.disconnect()

    def _linger(self, seconds: float) -> None:
        """Sleep ``seconds``, ending early when the node is asked to stop (the runtime's SIGINT/SIGTERM handler
        only sets a flag: a plain sleep would outlast the launcher's kill timeout and the node be SIGKILLed)."""
        end = time.monotonic() + seconds
        while not getattr(self.ctx, "stop_requested", False) and (left := end - time.monotonic()) > 0:
            time.sleep(min(0.1, left))
