"""`probeless keys generate` and what `probeless check` says about TCP, CURVE and key files."""

from __future__ import annotations

import stat
from pathlib import Path

import pytest
import zmq
import zmq.auth

from probeless.cli import main
from probeless.launch.graph import parse_graph
from probeless.launch.launcher import load_checked
from probeless.launch.secure import curve_plan
from probeless.runtime.keys import key_name

NODES = """
nodes:
  - id: camera
    node: pattern_source
    host: {cam_host}
    inputs: {{tick: timer/hz/10}}
    params: {{count: 5}}
  - id: sink
    node: summary_sink
    host: gpu
    inputs: {{image: {{source: camera/image, policy: block}}}}
"""


def graph_file(tmp_path: Path, cam_address: str = "127.0.0.1", security: str = "", cam_host: str = "cam") -> Path:
    path = tmp_path / "g.yaml"
    path.write_text(f"args:\n  keys: {{default: keys}}\nhosts:\n"
                    f"  cam: {{address: '{cam_address}', port_base: 7400}}\n"
                    f"  gpu: {{address: 127.0.0.1, port_base: 7500}}\n"
                    + NODES.format(cam_host=cam_host) + security)
    return path


def generate(tmp_path: Path, *names: str) -> Path:
    keys = tmp_path / "keys"
    args = ["keys", "generate", str(keys)] + (["--hosts", ",".join(names)] if names else [])
    assert main(args) == 0
    return keys


def test_keys_generate_writes_valid_pairs_with_private_modes(tmp_path, capsys):
    keys = generate(tmp_path, "cam", "gpu")
    out = capsys.readouterr().out.splitlines()
    assert out == [f"wrote {keys}/public/cam.key", f"wrote {keys}/private/cam.key_secret",
                   f"wrote {keys}/public/gpu.key", f"wrote {keys}/private/gpu.key_secret"]
    assert stat.S_IMODE((keys / "private").stat().st_mode) == 0o700
    for name in ("cam", "gpu"):
        secret_path = keys / "private" / f"{name}.key_secret"
        assert stat.S_IMODE(secret_path.stat().st_mode) == 0o600
        public, secret = zmq.auth.load_certificate(secret_path)
        assert zmq.curve_public(secret) == public                       # a real pair (libzmq derives it)
        assert zmq.auth.load_certificate(keys / "public" / f"{name}.key") == (public, None)
    assert sorted(p.name for p in (keys / "public").iterdir()) == ["cam.key", "gpu.key"]
    assert not list((keys / "private").glob("tmp*"))                     # no leftovers of the private temp dir


def test_keys_generate_refuses_to_overwrite_a_secret_without_force(tmp_path, capsys):
    keys = generate(tmp_path)
    before = (keys / "private" / "graph.key_secret").read_bytes()
    assert main(["keys", "generate", str(keys)]) == 2
    assert f"{keys}/private/graph.key_secret: secret key exists; use --force" in capsys.readouterr().err
    assert (keys / "private" / "graph.key_secret").read_bytes() == before
    assert main(["keys", "generate", str(keys), "--force"]) == 0
    assert (keys / "private" / "graph.key_secret").read_bytes() != before


def test_check_warns_about_plain_tcp_once_per_host(tmp_path, capsys):
    path = graph_file(tmp_path)
    assert main(["check", str(path)]) == 0
    captured = capsys.readouterr()
    warnings = captured.err.splitlines()
    assert len(warnings) == 2
    assert warnings[0].startswith(f"warning: {path}:10: node 'camera': key 'host': host 'cam' binds plain TCP")
    assert warnings[1].startswith(f"warning: {path}:15: node 'sink': key 'host': host 'gpu' binds plain TCP")
    assert "2 warning(s)" in captured.out


@pytest.mark.parametrize(("address", "endpoint"), [("0.0.0.0", "0.0.0.0"), ("*", "*"), ("::", "[::]")])
def test_check_refuses_every_interface_without_curve(tmp_path, capsys, address, endpoint):
    path = graph_file(tmp_path, cam_address=address)
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {path}:10: node 'camera': key 'host': binds tcp://{endpoint}:7400 on every "
                          f"network interface without CURVE")
    assert "1 error(s)" in err


def test_literal_host_on_every_interface_is_refused_too(tmp_path, capsys):
    path = graph_file(tmp_path, cam_host="'0.0.0.0:7600'")
    assert main(["check", str(path)]) == 2
    assert "binds tcp://0.0.0.0:7600 on every network interface" in capsys.readouterr().err


def test_curve_block_with_keys_is_clean_and_picks_each_hosts_pair(tmp_path, capsys):
    keys = generate(tmp_path, "cam")
    generate(tmp_path)    # the default pair, used by hosts without their own (gpu)
    path = graph_file(tmp_path, cam_address="0.0.0.0", security="security:\n  curve: {keys: $(arg keys)}\n")
    capsys.readouterr()
    assert main(["check", str(path)]) == 0
    assert capsys.readouterr().err == ""
    graph = load_checked(str(path), {})
    assert graph.curve_keys == keys.resolve()
    nodes = {"camera": {"endpoint": "tcp://0.0.0.0:7400", "lossy_endpoint": "tcp://0.0.0.0:7401"},
             "sink": {"endpoint": "tcp://127.0.0.1:7500"}, "local": {"endpoint": "ipc:///run/2.pub"}}
    assert curve_plan(graph, nodes) == {
        "keys": str(keys.resolve()), "key_names": {"camera": "cam", "sink": "graph"},
        "servers": {"tcp://0.0.0.0:7400": "cam", "tcp://0.0.0.0:7401": "cam", "tcp://127.0.0.1:7500": "graph"}}
    assert key_name(keys, None) == "graph"


def test_missing_key_directory_names_the_graph_line(tmp_path, capsys):
    path = graph_file(tmp_path, security="security:\n  curve: {keys: nowhere}\n")
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {path}:18: key 'security.curve.keys': CURVE key directory "
                          f"{tmp_path / 'nowhere'} not found")


def test_missing_or_exposed_key_files_are_named(tmp_path, capsys):
    keys = generate(tmp_path, "cam", "gpu")
    (keys / "public" / "gpu.key").unlink()
    (keys / "private" / "cam.key_secret").chmod(0o644)
    path = graph_file(tmp_path, security="security:\n  curve: {keys: keys}\n")
    capsys.readouterr()
    assert main(["check", str(path)]) == 2
    lines = capsys.readouterr().err.splitlines()
    assert lines[0].startswith(f"error: {keys}/private/cam.key_secret: secret key file is accessible by others")
    assert lines[1].startswith(f"error: {keys}/public/gpu.key: key file unreadable: No such file or directory")
    assert lines[2] == "2 error(s)"


def test_garbage_key_file_is_named(tmp_path, capsys):
    keys = generate(tmp_path)
    (keys / "public" / "graph.key").write_text("metadata\n    hello = \"world\"\n")
    path = graph_file(tmp_path, security="security:\n  curve: {keys: keys}\n")
    capsys.readouterr()
    assert main(["check", str(path)]) == 2
    assert f"error: {keys}/public/graph.key: " in capsys.readouterr().err


@pytest.mark.parametrize("block, words", [
    ("security: {curve: {}}\n", "'security' must be {curve: {keys: DIR}}"),
    ("security: {tls: {keys: k}}\n", "'security' must be {curve: {keys: DIR}}"),
    ("security: curve\n", "'security' must be {curve: {keys: DIR}}"),
])
def test_malformed_security_block(tmp_path, block, words):
    graph = parse_graph(graph_file(tmp_path, security=block))
    assert [e.message for e in graph.errors] == [words + " (DIR from `probeless keys generate DIR`)"]
    assert graph.errors[0].line == 17 and graph.errors[0].key == "security"


def test_security_in_an_include_is_an_error(tmp_path):
    (tmp_path / "sub.yaml").write_text("security: {curve: {keys: k}}\nnodes: []\n")
    path = tmp_path / "top.yaml"
    path.write_text("include:\n  - {file: sub.yaml}\nnodes: []\n")
    errors = parse_graph(path).errors
    assert len(errors) == 1 and errors[0].file == str(tmp_path / "sub.yaml") and errors[0].line == 1
    assert "belongs in the top-level graph file" in errors[0].message


def test_ipc_only_graph_has_no_security_findings(tmp_path, capsys):
    path = tmp_path / "local.yaml"
    path.write_text(NODES.replace("    host: {cam_host}\n", "").replace("    host: gpu\n", "")
                    .replace("{{", "{").replace("}}", "}"))
    assert main(["check", str(path)]) == 0
    assert capsys.readouterr().err == ""


def test_launch_stops_before_starting_anything_on_a_missing_key(tmp_path, capsys):
    keys = generate(tmp_path, "cam", "gpu")
    (keys / "private" / "gpu.key_secret").unlink()
    path = graph_file(tmp_path, security="security:\n  curve: {keys: keys}\n")
    capsys.readouterr()
    assert main(["launch", str(path), "--duration", "1"]) == 2
    captured = capsys.readouterr()
    assert captured.err.startswith(f"error: {keys}/private/gpu.key_secret: key file unreadable: No such file")
    assert "[launch]" not in captured.out
