"""Recordings never store environment variables or secrets: fake tokens in the environment, in secret-looking
launch args and, through substitutions, in node params must not appear anywhere in the recorded file."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from faults_common import launch_graph, node_env, write_graph

from probeless.bag.reader import BagReader
from probeless.bag.writer import BagWriter
from probeless.provenance import REDACTED, recording_metadata, redact, redact_argv

GH_TOKEN = "ghp_FAKEfake0123456789abcdefFAKEfake0123"
AWS_SECRET = "wJalrFAKEK7MDENGbPxRfiCYFAKEKEY0123"
ARG_TOKEN = "tok-FAKE-4242-aaaa-bbbb"
ARG_PASSWORD = "hunter2-FAKE-pw"
SECRETS = (GH_TOKEN, AWS_SECRET, ARG_TOKEN, ARG_PASSWORD)


def test_redact_argv_hides_values_of_secret_looking_names_only():
    argv = ["probeless", "launch", "g.yaml", f"token:={ARG_TOKEN}", f"db_password:={ARG_PASSWORD}", "fps:=30",
            "--api-key", "k-123456", f"--auth={GH_TOKEN}", "--author", "Ada", "--record", "run.mcap"]
    assert redact_argv(argv) == ["probeless", "launch", "g.yaml", "token:=REDACTED", "db_password:=REDACTED",
                                 "fps:=30", "--api-key", "REDACTED", "--auth=REDACTED", "--author", "Ada",
                                 "--record", "run.mcap"]


def test_redact_takes_secrets_out_of_nested_values_and_strings():
    plan = {"args": {"token": ARG_TOKEN, "fps": 30},
            "nodes": {"cam": {"params": {"url": f"rtsp://cam?key={AWS_SECRET}", "password": "pw",
                                         "nested": {"Access_Key": "AKIAFAKE", "size": [1, 2]}}}},
            "note": f"made with {ARG_TOKEN}"}
    out = redact(plan, env={"AWS_SECRET_ACCESS_KEY": AWS_SECRET, "HOME": "/root", "SHORT_TOKEN": "abc"})
    assert out == {"args": {"token": REDACTED, "fps": 30},
                   "nodes": {"cam": {"params": {"url": f"rtsp://cam?key={REDACTED}", "password": REDACTED,
                                                "nested": {"Access_Key": REDACTED, "size": [1, 2]}}}},
                   "note": f"made with {REDACTED}"}


def test_recording_metadata_has_no_environment(monkeypatch):
    monkeypatch.setenv("PROBELESS_TEST_TOKEN", GH_TOKEN)
    meta = recording_metadata({"file": "g.yaml", "args": {"token": ARG_TOKEN}, "nodes": {}},
                              f"probeless launch g.yaml token:={ARG_TOKEN}", "1.0")
    assert sorted(meta) == ["command", "git_revision", "graph_file", "plan", "version"]
    assert meta["command"] == "probeless launch g.yaml token:=REDACTED"
    assert json.loads(meta["plan"])["args"] == {"token": REDACTED}
    assert not any(s in json.dumps(meta) for s in SECRETS)
    assert os.environ["HOME"] not in json.dumps(meta)


def test_the_writer_never_stores_environment_secrets_in_any_metadata(tmp_path, monkeypatch):
    monkeypatch.setenv("AWS_SECRET_ACCESS_KEY", AWS_SECRET)
    path = tmp_path / "m.mcap"
    with BagWriter(path, metadata={"extra": {"from_a_caller": f"s3://bucket?secret={AWS_SECRET}"}}) as w:
        w.add_metadata("later", {"k": AWS_SECRET})
    assert AWS_SECRET.encode() not in path.read_bytes()
    assert BagReader(path).metadata()["extra"]["from_a_caller"] == f"s3://bucket?secret={REDACTED}"


GRAPH = """
args:
  token: ""
  password: ""
nodes:
  - id: src
    node: nodes_for_tests:Ticker
    inputs: {{tick: timer/hz/50}}
    params: {{count: 20, pid_file: "{tmp}/src-$(arg token)-$(env AWS_SECRET_ACCESS_KEY)"}}
  - id: sink
    node: nodes_for_tests:Recorder
    inputs: {{image: {{source: src/image, policy: block}}}}
    params: {{out: "{tmp}/sink.json", pid_file: "{tmp}/sink-$(arg password)"}}
"""


@pytest.mark.graph
@pytest.mark.slow
@pytest.mark.timeout(300)
def test_launch_record_stores_no_secret_from_env_args_or_params(tmp_path, monkeypatch, short_run_dir):
    monkeypatch.setenv("PROBELESS_RUN_DIR", str(short_run_dir))
    monkeypatch.setenv("PROBELESS_TEST_TOKEN", GH_TOKEN)
    monkeypatch.setenv("AWS_SECRET_ACCESS_KEY", AWS_SECRET)
    g = write_graph(tmp_path, GRAPH.format(tmp=tmp_path))
    out = tmp_path / "run.mcap"
    code, log = launch_graph(g, "--record", str(out), f"token:={ARG_TOKEN}", f"password:={ARG_PASSWORD}")
    assert code == 0, log
    # the secrets did reach the nodes' params (the pid files are named with them) ...
    assert (tmp_path / f"src-{ARG_TOKEN}-{AWS_SECRET}").exists()
    assert (tmp_path / f"sink-{ARG_PASSWORD}").exists()
    # ... yet no byte of the recording holds any of them
    data = out.read_bytes()
    assert [s for s in SECRETS if s.encode() in data] == []
    reader = BagReader(out)
    assert len(list(reader.messages("src/image"))) == 20  # the recording itself is complete
    graph = reader.metadata()["probeless.graph"]
    assert f"token:={REDACTED}" in graph["command"] and f"password:={REDACTED}" in graph["command"]
    plan = json.loads(graph["plan"])
    assert plan["args"]["token"] == REDACTED and plan["args"]["password"] == REDACTED
    assert plan["nodes"]["sink"]["params"]["pid_file"] == f"{tmp_path}/sink-{REDACTED}"
    info = subprocess.run([sys.executable, "-m", "probeless.cli", "bag", "info", str(out)], capture_output=True,
                          text=True, timeout=60, env=node_env())
    assert info.returncode == 0 and not any(s in info.stdout for s in SECRETS)
