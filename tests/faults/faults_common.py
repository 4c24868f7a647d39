"""Helpers of the fault-injection suite: write a graph, launch it as a real CLI process with a timeout."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
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
