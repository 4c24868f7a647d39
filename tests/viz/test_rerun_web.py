"""The Rerun web viewer in a real browser (Debian's headless Chromium), served by a running graph's rerun_sink.

- The lounge pipeline with ``viewer:=rerun``: the viewer page loads, connects to the sink's gRPC server and
  receives data; the screenshot goes to ``out/viz/rerun_lounge.png`` for a person to look at (the README's).
- A stalled viewer (the whole browser SIGSTOPped: it stops reading) does not lower the graph's frame rate.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from browser import page_at, rerun_viewer_url, wait_for
from faults.faults_common import finish, free_ports, node_env, rate_hz
from locations import REPO

SHOT = REPO / "out" / "viz" / "rerun_lounge.png"


def _launch(*args: str, cwd: Path = REPO, env: dict | None = None) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-u", "-m", "probeless.cli", "launch", *args], cwd=cwd,
                            env={**node_env(), **(env or {})},
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)


def _wait_line(proc: subprocess.Popen, needle: str, timeout_s: float, seen: list[str]) -> str:
    """Read the launcher's output until a line holds ``needle`` (kept in ``seen``)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if not line and proc.poll() is not None:
            break
        seen.append(line)
        if needle in line:
            return line
    raise AssertionError(f"no line with {needle!r} in {timeout_s:g} s:\n{''.join(seen)[-4000:]}")


# the augmented frame's panel in the default layout at 1600x900 (probeless/viz/blueprint.py): rows, columns
AUGMENTED_PANEL = (slice(64, 247), slice(1040, 1286))


def _wait_responsive(page, timeout_s: float, answer_s: float = 1.0) -> None:
    """Wait until the page's main thread answers a script within ``answer_s`` twice in a row: the viewer is no
    longer busy taking in and drawing the run it was sent (a catching-up viewer takes tens of seconds)."""
    deadline, quick = time.monotonic() + timeout_s, 0
    while quick < 2 and time.monotonic() < deadline:
        t0 = time.monotonic()
        page.evaluate("1")
        quick = quick + 1 if time.monotonic() - t0 < answer_s else 0
        page.wait_for_timeout(250)


def _screenshot_with_frames(page, timeout_s: float):
    """Screenshots until the augmented frame's panel shows an image (not the empty panel), or the deadline."""
    import cv2

    deadline = time.monotonic() + timeout_s
    while True:
        page.screenshot(path=str(SHOT), timeout=240_000)          # the software renderer is slow
        shot = cv2.imread(str(SHOT))
        if shot is None or shot.shape[:2] != (900, 1600) or float(shot[AUGMENTED_PANEL].std()) > 20.0 \
                or time.monotonic() > deadline:
            return shot
        _wait_responsive(page, 30)


@pytest.mark.graph
@pytest.mark.slow
@pytest.mark.timeout(480)
def test_web_viewer_loads_connects_and_shows_the_lounge_pipeline(tmp_path):
    """The page loads, connects to the sink and decodes data while the graph runs (then the browser is stopped
    until the run ends); the screenshot is taken while the sink, its inputs ended, keeps serving
    (PROBELESS_RERUN_LINGER_S) and the viewer has caught up; then Ctrl-C ends the lingering sink and the graph
    exits cleanly. A 512² atlas without the mask topics (the viewer's atlas tab shows the atlas) and 2 messages
    a second per topic (PROBELESS_RERUN_MAX_HZ) keep the run and what the software-rendered viewer takes in
    small."""
    web = free_ports(1, stride=4)
    grpc = web + 2
    rrd = tmp_path / "run.rrd"
    proc = _launch("launch/probeless.yaml", "viewer:=rerun", "seconds:=1", f"out_dir:={tmp_path}",
                   "atlas_size:=512", "mask_every:=0",
                   f"rerun_port:={web}", f"rerun_grpc_port:={grpc}", f"viewer_rrd:={rrd}",
                   env={"PROBELESS_RERUN_LINGER_S": "600", "PROBELESS_RERUN_MAX_HZ": "2"})
    seen: list[str] = []
    try:
        _wait_line(proc, f"http://127.0.0.1:{web}/", 120, seen)     # the sink says where the viewer is
        with page_at(rerun_viewer_url(web, grpc)) as (page, console, browser):
            wait_for(console, r"Web app started", 90, page)
            wait_for(console, rf"Streaming messages from gRPC endpoint.*port: {grpc}", 60, page)
            wait_for(console, r"re_sorbet", 120, page)              # record batches arrived and were decoded
            # the software renderer takes a core while it draws: the browser waits (stopped, as in the test
            # below) until the run is over, then takes in what the sink's server kept for it
            os.killpg(browser.pid, signal.SIGSTOP)
            try:
                _wait_line(proc, "serving the run to web viewers for 600 s more", 300, seen)
            finally:
                os.killpg(browser.pid, signal.SIGCONT)
            _wait_responsive(page, 45)                               # the viewer catches up (under load it
            # never answers quickly: the software renderer keeps its thread busy, so the wait is bounded)
            page.mouse.click(1500, 700)                              # focus the canvas, then pause on the
            page.keyboard.press("Space")                             # latest frame so its JPEGs get decoded
            _wait_responsive(page, 20)
            SHOT.parent.mkdir(parents=True, exist_ok=True)
            shot = _screenshot_with_frames(page, 45)
        t_int = time.monotonic()
        os.killpg(proc.pid, signal.SIGINT)                           # Ctrl-C ends the sink's lingering
        log = "".join(seen) + finish(proc, 120, "launch probeless.yaml viewer:=rerun")
        stopped_s = time.monotonic() - t_int
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 0, log[-4000:]
    assert stopped_s < 30, log[-4000:]                               # not the 600 s linger
    assert "messages logged on" in log and rrd.stat().st_size > 0, log[-4000:]   # the sink's summary at close
    assert shot is not None and shot.shape[:2] == (900, 1600)
    assert float(shot.std()) > 20.0, "the screenshot is blank"


FPS, BEFORE_S, STOP_S = 30, 4.0, 10.0


@pytest.mark.graph
@pytest.mark.slow
@pytest.mark.timeout(300)
def test_a_stalled_viewer_does_not_slow_the_graph(tmp_path):
    """pattern_source at 30 Hz -> a sink that logs arrivals and the rerun_sink serving a connected web viewer;
    the browser is stopped for 10 s (it stops reading): the other sink keeps >= 0.95x its rate."""
    web = free_ports(1, stride=4)
    grpc = web + 2
    frames = int(FPS * (BEFORE_S + STOP_S + 30))
    graph = tmp_path / "g.yaml"
    graph.write_text(f"""nodes:
  - id: src
    node: pattern_source
    inputs: {{tick: timer/hz/{FPS}}}
    params: {{width: 640, height: 480, count: {frames}}}
  - id: running
    node: nodes_for_tests:ArrivalLog
    inputs: {{image: {{source: src/image, policy: latest}}}}
    params: {{out: {tmp_path}/running.json}}
  - id: rerun
    node: rerun_sink
    inputs: {{all: {{source: "src/*", policy: latest}}}}
    params: {{serve: true, web_port: {web}, grpc_port: {grpc}, memory_limit: 64MiB}}
""")
    proc = _launch(str(graph))
    seen: list[str] = []
    figures = {}
    try:
        _wait_line(proc, f"http://127.0.0.1:{web}/", 120, seen)
        with page_at(rerun_viewer_url(web, grpc)) as (page, console, browser):
            wait_for(console, rf"Streaming messages from gRPC endpoint.*port: {grpc}", 90, page)
            wait_for(console, r"re_sorbet", 60, page)
            page.wait_for_timeout(BEFORE_S * 1000)
            t_stop = time.time_ns()
            os.killpg(browser.pid, signal.SIGSTOP)                    # the viewer stops reading
            time.sleep(STOP_S)
            t_cont = time.time_ns()
            os.killpg(browser.pid, signal.SIGCONT)
        os.killpg(proc.pid, signal.SIGINT)                            # end the run: the sinks write their logs
        out = seen + [finish(proc, 120, "launch stalled-viewer graph")]
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    arrivals = [t for _, t in json.loads((tmp_path / "running.json").read_text())["log"]["image"]]
    before = rate_hz(arrivals, t_stop - int(BEFORE_S * 1e9), t_stop)
    during = rate_hz(arrivals, t_stop + int(0.2e9), t_cont)
    figures = {"running_sink_hz_before": round(float(before), 2), "running_sink_hz_while_viewer_stopped":
               round(float(during), 2), "ratio": round(float(during / before), 3)}
    if os.environ.get("PROBELESS_VIEWER_REPORT"):
        Path(os.environ["PROBELESS_VIEWER_REPORT"]).write_text(json.dumps({"rerun_stalled_viewer": figures}))
    assert before > 0.5 * FPS, ("".join(out)[-3000:], figures)
    assert during >= 0.95 * before, figures

