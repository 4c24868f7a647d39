"""A run folder too long for unix socket paths is refused up front, naming the variable, and a failed bind
leaves no socket that would hang the node's shutdown."""

from __future__ import annotations

import pytest
import zmq

from probeless.errors import ProbelessError, TransportError
from probeless.launch.plan import new_run_dir
from probeless.runtime.transport import Publisher


def test_a_too_long_run_dir_is_refused_naming_the_variable(monkeypatch, tmp_path):
    long = tmp_path / ("x" * 90)
    monkeypatch.setenv("PROBELESS_RUN_DIR", str(long))
    with pytest.raises(ProbelessError, match=r"PROBELESS_RUN_DIR: .* at most 75 characters"):
        new_run_dir()
    assert not long.exists()


def test_a_short_run_dir_holds_every_socket_name(monkeypatch, short_run_dir):
    base = short_run_dir / ("y" * (75 - len(str(short_run_dir)) - 1))
    monkeypatch.setenv("PROBELESS_RUN_DIR", str(base))
    run = new_run_dir()
    ctx = zmq.Context()
    pub = Publisher(ctx, f"ipc://{run}/recorder.pub", "recorder")  # the longest names: recorder.pub/.lossy
    pub.close()
    ctx.term()


def test_a_failed_bind_leaves_the_context_free_to_terminate(tmp_path):
    ctx = zmq.Context()
    with pytest.raises(TransportError, match="cannot bind"):
        Publisher(ctx, f"ipc://{tmp_path / ('z' * 120)}/n.pub", "n")
    ctx.term()  # hung before: the socket whose bind failed stayed open
