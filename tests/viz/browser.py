"""A real browser for the viewer tests: Debian's headless Chromium, driven over CDP by playwright.

Chromium is started here (its own process group, so a test can SIGSTOP the whole browser: a viewer client
that stops reading) with the flags this machine's closed network needs, and playwright connects to it.
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import signal
import subprocess
import tempfile
import time
from typing import Iterator

CHROMIUM = "/usr/bin/chromium"
FLAGS = ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--enable-unsafe-swiftshader", "--use-angle=swiftshader", "--remote-debugging-port=0",
         "--window-size=1600,900"]


def rerun_viewer_url(web_port: int, grpc_port: int) -> str:
    """The web viewer page, pointed at a rerun_sink's gRPC server."""
    return f"http://127.0.0.1:{web_port}/?url=rerun%2Bhttp://127.0.0.1:{grpc_port}/proxy"


@contextlib.contextmanager
def chromium() -> Iterator[tuple[subprocess.Popen, str]]:
    """(process, CDP websocket URL) of a fresh headless Chromium; killed with its group on exit."""
    assert os.path.exists(CHROMIUM), f"{CHROMIUM} not found: `make setup` installs Debian's chromium package"
    profile = tempfile.mkdtemp(prefix="probeless-chromium-")
    proc = subprocess.Popen([CHROMIUM, *FLAGS, f"--user-data-dir={profile}", "about:blank"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        ws, seen, deadline = None, [], time.monotonic() + 60
        while ws is None and time.monotonic() < deadline and proc.poll() is None:
            line = proc.stderr.readline()
            seen.append(line)
            m = re.search(r"DevTools listening on (ws://\S+)", line)
            ws = m.group(1) if m else None
        assert ws, f"chromium did not start: {''.join(seen)[-2000:]}"
        yield proc, ws
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGCONT)
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
        shutil.rmtree(profile, ignore_errors=True)


@contextlib.contextmanager
def page_at(url: str) -> Iterator[tuple[object, list[str], subprocess.Popen]]:
    """(playwright page at ``url``, its console messages as they come, the browser process)."""
    from playwright.sync_api import sync_playwright

    with chromium() as (proc, ws), sync_playwright() as p:
        browser = p.chromium.connect_over_cdp(ws)
        context = browser.contexts[0] if browser.contexts else browser.new_context()
        page = context.new_page()
        page.set_viewport_size({"width": 1600, "height": 900})
        console: list[str] = []
        page.on("console", lambda m: console.append(m.text))
        page.goto(url, timeout=60_000)
        yield page, console, proc


def wait_for(console: list[str], pattern: str, timeout_s: float, page=None) -> str:
    """The first console message matching ``pattern`` within ``timeout_s`` (the page's event loop keeps
    running while we wait); AssertionError listing what the page said otherwise."""
    rx, deadline = re.compile(pattern), time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        hit = next((m for m in console if rx.search(m)), None)
        if hit is not None:
            return hit
        if page is not None:
            page.wait_for_timeout(250)
        else:
            time.sleep(0.25)
    said = "\n".join(m[:200] for m in console if "wgpu" not in m and "\n" not in m)[-3000:]
    raise AssertionError(f"no console message matching {pattern!r} in {timeout_s:g} s; the page said:\n{said}")
