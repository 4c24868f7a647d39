"""A stalled Foxglove viewer never slows the graph (real processes, a real WebSocket client that stops reading).

The experiment of tests/faults/test_stalled_subscriber.py with a viewer in place of a SIGSTOPped sink: a
30 Hz 640x480 camera feeds a sink and the foxglove_bridge (``policy: latest``). A client subscribes to
the image channel, then stops reading for 6 s (10 s for the report, as docs/viewers.md quotes; a tiny
receive buffer, the client library's queue of one frame): the server's per-client queue fills and drops
its oldest messages. The sink keeps >= 0.95x its rate from before the viewer came, the bridge's memory
stays bounded, and once it reads again the viewer gets fresh frames with a gap where the server dropped.

With PROBELESS_FOXGLOVE_REPORT=FILE the figures are written to that JSON file.
"""

from __future__ import annotations

import asyncio
import json
import os
import socket
import threading
import time
from pathlib import Path

import psutil
import pytest
from faults.faults_common import rate_hz
from test_foxglove_bridge import Graph, advertisements, connect, message_data, subscribe

# the server's per-client queue (8 messages) fills in 0.3 s: a 6 s stall is 20x that and 180 frames long;
# the report (docs/viewers.md) is measured over the 10 s stall it quotes
FPS, AFTER_S = 30, 2.0
BEFORE_S, STALL_S = (3.0, 10.0) if os.environ.get("PROBELESS_FOXGLOVE_REPORT") else (2.0, 6.0)
WIDTH, HEIGHT = 640, 480


def _graph(tmp: Path) -> Path:
    path = tmp / "graph.yaml"
    path.write_text(f"""nodes:
  - id: src
    node: pattern_source
    inputs: {{tick: timer/hz/{FPS}}}
    params: {{width: {WIDTH}, height: {HEIGHT}}}
  - id: sink
    node: nodes_for_tests:ArrivalLog
    inputs: {{image: {{source: src/image, policy: latest}}}}
    params: {{out: {tmp}/sink.json}}
  - id: fox
    node: foxglove_bridge
    inputs: {{image: {{source: src/image, policy: latest}}}}
    params: {{port: 0}}
  - id: watch
    node: nodes_for_tests:ArrivalLog
    inputs: {{diag: {{source: fox/diagnostics, policy: drop_oldest, queue_size: 100}}}}
    params: {{out: {tmp}/watch.json}}
""")
    return path


class RssSampler(threading.Thread):
    """Resident memory of one process, sampled every 0.25 s until stopped."""

    def __init__(self, pid: int):
        super().__init__(daemon=True)
        self.proc, self.samples, self.done = psutil.Process(pid), [], threading.Event()

    def run(self) -> None:
        while not self.done.wait(0.25):
            try:
                self.samples.append((time.time_ns(), self.proc.memory_info().rss))
            except psutil.NoSuchProcess:
                return


def _bridge_pid(graph: Graph) -> int:
    for child in psutil.Process(graph.proc.pid).children(recursive=True):
        if child.cmdline()[-1:] == ["fox"]:
            return child.pid
    raise AssertionError("no bridge process")


async def _stalled_viewer(port: int) -> dict:
    """Subscribe, stop reading for STALL_S, then read again for AFTER_S: times and what arrived after."""
    sock = socket.socket()
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)   # the kernel holds little for us
    sock.connect(("127.0.0.1", port))
    async with connect(port, sock=sock, max_queue=1) as ws:    # the library stops reading after one frame
        channels = await advertisements(ws, {"src/image"})
        t_stall = time.time_ns()
        await subscribe(ws, {1: channels["src/image"]["id"]})
        await asyncio.sleep(STALL_S)
        t_resume = time.time_ns()
        stamps = []
        async with asyncio.timeout(AFTER_S + 30):
            while time.time_ns() < t_resume + AFTER_S * 1e9:
                frame = await ws.recv()
                if isinstance(frame, bytes):
                    stamps.append(message_data(frame)[1])
    return {"t_stall": t_stall, "t_resume": t_resume, "stamps": stamps}


@pytest.mark.graph
@pytest.mark.slow
def test_a_stalled_foxglove_viewer_never_slows_the_graph(tmp_path):
    graph = Graph(_graph(tmp_path))
    try:
        port = graph.bridge_port()
        graph.wait_for(r"\[launch\] .* starting")
        sampler = RssSampler(_bridge_pid(graph))
        sampler.start()
        time.sleep(BEFORE_S + 1.0)  # a steady baseline, no viewer
        viewer = asyncio.run(_stalled_viewer(port))
        sampler.done.set()
    finally:
        out = graph.stop()
    assert graph.proc.returncode == 0, out
    arrivals = [t for _, t in json.loads((tmp_path / "sink.json").read_text())["log"]["image"]]
    t_stall, t_resume = viewer["t_stall"], viewer["t_resume"]
    baseline = rate_hz(arrivals, arrivals[0] + int(0.5e9), t_stall)
    during = rate_hz(arrivals, t_stall + int(0.2e9), t_resume)
    bridge_in = json.loads((tmp_path / "watch.json").read_text())["status"]["fox"]["image"]
    sent = int(next(line for line in out.splitlines() if "src/image:" in line and " sent" in line)
               .split("src/image:")[1].split()[0])
    rss = [r for t, r in sampler.samples if t >= t_stall]
    stamps = viewer["stamps"]
    gaps = [b - a for a, b in zip(stamps, stamps[1:])]
    figures = {"sink_hz_before": round(baseline, 2), "sink_hz_while_viewer_stalled": round(during, 2),
               "ratio": round(during / baseline, 3), "bridge_sent": sent,
               "bridge_input": bridge_in, "viewer_received_after_resume": len(stamps),
               "viewer_largest_stamp_gap_s": round(max(gaps) / 1e9, 2) if gaps else None,
               "bridge_rss_mb_at_stall": round(rss[0] / 1e6, 1), "bridge_rss_mb_max": round(max(rss) / 1e6, 1),
               "bridge_rss_mb_end": round(rss[-1] / 1e6, 1)}
    if os.environ.get("PROBELESS_FOXGLOVE_REPORT"):
        Path(os.environ["PROBELESS_FOXGLOVE_REPORT"]).write_text(json.dumps(figures, indent=1))
    assert baseline > 0.5 * FPS, (figures, out)
    assert during >= 0.95 * baseline, figures
    # the server dropped for the stalled viewer: it converted frames the viewer never got, the viewer's
    # frames after the stall jump over the stalled seconds, and the bridge's memory did not grow with them
    assert sent > FPS * STALL_S * 0.5, figures
    assert stamps and len(stamps) < sent, figures
    assert max(gaps) > 0.5 * STALL_S * 1e9, figures
    assert max(rss) - rss[0] < 200e6, figures
