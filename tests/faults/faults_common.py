"""Helpers of the fault-injection suite: write a graph, launch it as a real CLI process with a timeout."""

from __future__ import annotations

import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

TESTS_DIR = Path(__file__).resolve().parent
ROOT = TESTS_DIR.parent.parent


def node_env() -> dict:
    """Environment of node processes: the test nodes (tests/faults/injectors.py, tests/nodes_for_tests.py)."""
    paths = [str(TESTS_DIR), str(TESTS_DIR.parent), os.environ.get("PYTHONPATH", "")]
    return {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in paths if p)}


def write_graph(tmp_path: Path, text: str, name: str = "graph.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def launch_graph(path: Path, *args: str, timeout_s: float = 120.0) -> tuple[int, str]:
    """``probeless launch PATH ARGS`` in a subprocess; (exit code, output). Fails the test on a hang."""
    proc = subprocess.Popen([sys.executable, "-m", "probeless.cli", "launch", str(path), *args], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=node_env(),
                            start_new_session=True)
    out = finish(proc, timeout_s, f"probeless launch {path}")
    return proc.returncode, out


def finish(proc: subprocess.Popen, timeout_s: float = 90.0, what: str = "launch") -> str:
    """The output of ``proc`` once it ends; kills its process group and fails the test after ``timeout_s``."""
    try:
        out, _ = proc.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, _ = proc.communicate()
        raise AssertionError(f"{what} hung for more than {timeout_s} s:\n{out}") from None
    return out


def free_ports(n: int, stride: int = 8) -> int:
    """A base port with ``n * stride`` free ports above it (each node binds two)."""
    for _ in range(50):
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            base = s.getsockname()[1]
        if base + n * stride < 65000 and all(_free(base + i) for i in range(n * stride)):
            return base
    raise RuntimeError("no free port range")


def _free(port: int) -> bool:
    with socket.socket() as s:
        try:
            s.bind(("127.0.0.1", port))
            return True
        except OSError:
            return False


def rate_hz(arrivals_ns: list[int], t0_ns: int, t1_ns: int) -> float:
    """Messages per second that arrived in [t0, t1) (wall-clock arrival times [ns])."""
    return sum(t0_ns <= t < t1_ns for t in arrivals_ns) / ((t1_ns - t0_ns) / 1e9)


def start_launch(path: Path, *args: str, env: dict | None = None) -> subprocess.Popen:
    """``probeless launch PATH ARGS`` in the background, in its own process group, output piped."""
    return subprocess.Popen([sys.executable, "-m", "probeless.cli", "launch", str(path), *args], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env or node_env(),
                            start_new_session=True)


class RunningGraph:
    """A ``probeless launch`` in the background whose output is read as it comes: wait for a line, then stop it
    with SIGINT (a clean stop: every node's close runs)."""

    def __init__(self, path: Path, *args: str, env: dict | None = None):
        self.proc = start_launch(path, *args, env=env)
        self.lines: list[str] = []
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self) -> None:
        for line in self.proc.stdout:
            self.lines.append(line)

    @property
    def output(self) -> str:
        return "".join(self.lines)

    def wait_for(self, pattern: str, timeout_s: float = 60.0) -> re.Match:
        """The first match of ``pattern`` in the output; fails the test if the graph ends or times out first."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            m = re.search(pattern, self.output)
            if m:
                return m
            if self.proc.poll() is not None:
                self.reader.join(5)
                break
            time.sleep(0.05)
        self.stop()
        raise AssertionError(f"no {pattern!r} in the graph's output:\n{self.output}")

    def wait_started(self, timeout_s: float = 60.0) -> None:
        """Until the launcher says the graph is starting (every node ready)."""
        self.wait_for(r"(?m)^\[launch\].*starting$", timeout_s)

    def stop(self, timeout_s: float = 60.0) -> str:
        """SIGINT, then the whole output (SIGKILL of the group after ``timeout_s``)."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
        try:
            self.proc.wait(timeout_s)
        except subprocess.TimeoutExpired:
            os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait()
        self.reader.join(5)
        return self.output
