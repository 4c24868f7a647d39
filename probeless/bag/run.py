"""``probeless bag record|play``, ``probeless test`` and the ``launch --record/--replay`` options."""

from __future__ import annotations

import argparse
import shlex
import sys
import tempfile
from pathlib import Path

from probeless.bag.compare import compare_recordings
from probeless.bag.reader import BagReader
from probeless.bag.schema import check_schemas
from probeless.errors import BagError
from probeless.launch.graph import Graph
from probeless.launch.launcher import Launcher, load_checked
from probeless.launch.replay import PLAYER_ID, add_player, add_player_node, add_recorder, parse_remaps
from probeless.launch.validate import validate
from probeless.provenance import redact_argv


def add_replay_options(p: argparse.ArgumentParser, prefix: str = "") -> None:
    """Playback options shared by ``bag play`` and ``launch --replay``."""
    p.add_argument("--rate", type=float, default=1.0, help="playback speed; 0 = as fast as possible without loss")
    p.add_argument("--loop", action="store_true", help="start again at the end")
    p.add_argument("--lockstep", action="store_true", help="deterministic: wait for the graph after each message")
    p.add_argument(f"--{prefix}start", dest="start", type=float, default=0.0, metavar="S",
                   help="skip the first S seconds of the recording")
    p.add_argument(f"--{prefix}duration", dest="play_duration", type=float, default=0.0, metavar="D",
                   help="play only D seconds")
    p.add_argument("--remap", action="append", default=[], metavar="FROM:=TO", help="rename a topic")


def add_record_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--compression", choices=("lz4", "zstd", "none"), default="lz4")
    p.add_argument("--max-size", type=float, default=0.0, metavar="MB", help="split files at this size")
    p.add_argument("--max-duration", type=float, default=0.0, metavar="S", help="split files after S seconds")
    p.add_argument("--force", action="store_true", help="overwrite an existing recording")


def _player_params(ns: argparse.Namespace) -> dict:
    return {"rate": ns.rate, "loop": ns.loop, "lockstep": ns.lockstep, "start_s": ns.start,
            "duration_s": ns.play_duration}


def _recorder_params(ns: argparse.Namespace) -> dict:
    return {"compression": ns.compression, "max_size_mb": ns.max_size, "max_duration_s": ns.max_duration,
            "force": ns.force, "command": " ".join(shlex.quote(a) for a in redact_argv(sys.argv))}


def _refuse_overwrite(path: str, force: bool) -> None:
    if Path(path).exists() and not force:
        raise BagError(f"{path} exists; use --force to overwrite it")


def recorded_types(bag: str) -> dict[str, str]:
    """topic -> message type of a recording; BagError for types or schema versions this build lacks."""
    reader = BagReader(bag)
    if reader.truncated:
        print(f"warning: {bag}: {reader.truncation_note}", file=sys.stderr)
    topics = reader.topics()
    foreign = {t: i.message_encoding for t, i in topics.items() if i.foreign}
    if foreign:
        named = ", ".join(f"{t} ({e})" for t, e in sorted(foreign.items()))
        if len(foreign) == len(topics):
            raise BagError(f"{bag}: cannot play topic(s) of other encodings: {named}; bag play and --replay "
                           "publish probeless (msgpack) messages only (bag export --format foxglove copies them)")
        print(f"warning: {bag}: not playing topic(s) of other encodings: {named}", file=sys.stderr)
        topics = {t: i for t, i in topics.items() if t not in foreign}
    check_schemas(bag, {t: (i.type_name, i.version) for t, i in topics.items()})
    return {t: info.type_name for t, info in topics.items()}


def recorded_nodes(bag: str) -> tuple[dict[str, str], dict[str, dict]]:
    """(node id -> ``node:`` type, node id -> params) of the graph that made a recording (its stored plan);
    empty when it has none."""
    import json

    from probeless.bag.info import GRAPH

    with BagReader(bag) as reader:
        meta = reader.metadata().get(GRAPH) or {}
    try:
        nodes = json.loads(meta.get("plan") or "{}").get("nodes") or {}
        nodes = {str(nid): n for nid, n in nodes.items() if isinstance(n, dict) and n.get("node")}
        return ({nid: str(n["node"]) for nid, n in nodes.items()},
                {nid: n["params"] for nid, n in nodes.items() if isinstance(n.get("params"), dict)})
    except (ValueError, AttributeError, TypeError):
        return {}, {}


def replay_into(graph: Graph, bag: str, ns: argparse.Namespace, params: dict, tag: str) -> list[str]:
    """Swap the recorded nodes for a player (``--replace``/``--keep`` of ``ns``); prints, before anything
    starts, what comes from the recording and what runs live (and why)."""
    replace = ns.replace.split(",") if getattr(ns, "replace", None) else None
    keep = ns.keep.split(",") if getattr(ns, "keep", None) else None
    notes: list[str] = []
    types, node_params = recorded_nodes(bag)
    replaced = add_player(graph, bag, recorded_types(bag), replace=replace,
                          remap=parse_remaps(tuple(getattr(ns, "remap", ()) or ())), params=params,
                          recorded_nodes=types, recorded_params=node_params, keep=keep, notes=notes)
    print(f"[{tag}] replaying {bag}:", file=sys.stderr)
    for line in notes:
        print(f"[{tag}]   {line}", file=sys.stderr)
    return replaced


def prepare_graph(ns: argparse.Namespace, overrides: dict) -> tuple[Graph, str | None]:
    """Load a graph and apply ``--replay``/``--record``; returns (graph, clock node or None)."""
    graph = load_checked(ns.graph, overrides)
    clock = None
    if getattr(ns, "replay", None):
        replay_into(graph, ns.replay, ns, _player_params(ns), "launch")
        clock = PLAYER_ID
    if getattr(ns, "record", None):
        _refuse_overwrite(ns.record, ns.force)
        add_recorder(graph, ns.record, topics=getattr(ns, "topics", None) or None, params=_recorder_params(ns))
    return graph, clock


def cmd_record(ns: argparse.Namespace, overrides: dict) -> int:
    _refuse_overwrite(ns.output, ns.force)
    _no_stdin()
    if ns.graph and not _names_run(ns.graph):
        _note_running(ns.graph)
        graph = load_checked(ns.graph, overrides)
        add_recorder(graph, ns.output, topics=None if ns.all else ns.topics or None, params=_recorder_params(ns))
        code = Launcher(graph, duration=ns.duration).run()
    else:
        from probeless.bag.attach import record_running_graph

        code = record_running_graph(ns.output, None if ns.all else ns.topics, _recorder_params(ns),
                                    graph_dir=ns.graph, duration=ns.duration)
    report_written(ns.output)
    return code


def _names_run(spec: str) -> bool:
    """Whether ``bag record --graph SPEC`` names a running graph (a run id or run directory) to attach to,
    rather than a graph file to launch."""
    from probeless.runtime.runs import runs_base

    as_dir = Path(spec) if "/" in spec else runs_base() / spec
    return (as_dir / "graph.json").is_file() or not Path(spec).is_file()


def _note_running(path: str) -> None:
    from probeless.runtime.runs import resolve_runs

    for g in resolve_runs(path):
        print(f"note: {path} is already running as {g.run_id}; this launches another instance "
              f"(to record the running one: --graph {g.run_id})", file=sys.stderr)


def _no_stdin() -> None:
    """A recorder never reads the terminal: detach stdin, so a background ``bag record`` that inherited the
    shell's stdin behaves exactly like one started with ``</dev/null``."""
    import os

    try:
        fd = os.open(os.devnull, os.O_RDONLY)
        os.dup2(fd, 0)
        os.close(fd)
    except OSError:
        pass


def report_written(path: str, out=None) -> int:
    """Print ``N messages written to FILE(s)`` (counted in the written files) and return N."""
    from probeless.bag.writer import recording_paths

    out = out or sys.stdout
    try:
        files = recording_paths(path)
    except BagError:
        print(f"0 messages written (no recording was created at {path})", file=out)
        return 0
    count = 0
    for f in files:
        try:
            with BagReader(f) as reader:
                count += sum(t.count for t in reader.topics().values())
        except BagError as exc:
            print(f"warning: {exc}", file=sys.stderr)
    print(f"{count} messages written to {', '.join(map(str, files))}", file=out)
    return count


def cmd_play(ns: argparse.Namespace) -> int:
    types = recorded_types(ns.bag)
    remap = parse_remaps(tuple(ns.remap))
    chosen = ns.topics or sorted(types)
    unknown = [t for t in chosen if t not in types]
    if unknown:
        raise BagError(f"{ns.bag}: no topic(s) {unknown} in the recording (has: {sorted(types)})")
    params = {"path": ns.bag, "topics": chosen, "remap": list(ns.remap), **_player_params(ns)}
    graph = Graph(file=ns.bag)
    add_player_node(graph, params, {remap.get(t, t): types[t] for t in chosen})
    errors = validate(graph)
    if errors:
        raise errors[0]
    return Launcher(graph, clock_node=PLAYER_ID).run()


def cmd_test(ns: argparse.Namespace, overrides: dict) -> int:
    """Lockstep replay of ``--bag`` through the graph, outputs recorded and compared to ``--golden``."""
    graph = load_checked(ns.graph, overrides)
    replay_into(graph, ns.bag, ns, {"lockstep": True, "rate": 0.0}, "test")
    with tempfile.TemporaryDirectory(prefix="probeless-test-") as tmp:
        out = str(Path(tmp) / "outputs.mcap")
        topics = add_recorder(graph, out, diagnostics=False, skip={PLAYER_ID})
        code = Launcher(graph, clock_node=PLAYER_ID, out=sys.stderr).run()
        if code != 0:
            print(f"error: the graph failed (exit code {code})", file=sys.stderr)
            return code
        golden = Path(ns.golden)
        if ns.update_golden or not golden.exists():
            if golden.exists() and not ns.update_golden:
                raise BagError(f"{golden} exists; use --update-golden to replace it")
            golden.write_bytes(Path(out).read_bytes())
            print(f"wrote golden recording {golden} ({len(topics)} topic(s))")
            return 0
        diffs = compare_recordings(out, str(golden), atol=ns.tolerance, rtol=ns.rtol)
    if diffs:
        print(f"FAILED: outputs differ from {golden}:")
        for line in diffs:
            print(f"  {line}")
        return 1
    print(f"PASSED: {len(topics)} topic(s) match {golden}")
    return 0
