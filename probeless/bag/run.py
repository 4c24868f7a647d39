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


def prepare_graph(ns: argparse.Namespace, overrides: dict) -> tuple[Graph, str | None]:
    """Load a graph and apply ``--replay``/``--record``; returns (graph, clock node or None)."""
    graph = load_checked(ns.graph, overrides)
    clock = None
    if getattr(ns, "replay", None):
        remap = parse_remaps(tuple(ns.remap))
        replace = ns.replace.split(",") if ns.replace else None
        replaced = add_player(graph, ns.replay, recorded_types(ns.replay), replace=replace, remap=remap,
                              params=_player_params(ns))
        print(f"[launch] replaying {ns.replay} in place of: {', '.join(replaced)}", file=sys.stderr)
        clock = PLAYER_ID
    if getattr(ns, "record", None):
        _refuse_overwrite(ns.record, ns.force)
        add_recorder(graph, ns.record, topics=getattr(ns, "topics", None) or None, params=_recorder_params(ns))
    return graph, clock


def cmd_record(ns: argparse.Namespace, overrides: dict) -> int:
    _refuse_overwrite(ns.output, ns.force)
    if ns.graph:
        graph = load_checked(ns.graph, overrides)
        add_recorder(graph, ns.output, topics=None if ns.all else ns.topics or None, params=_recorder_params(ns))
        return Launcher(graph, duration=ns.duration).run()
    from probeless.bag.attach import record_running_graph

    return record_running_graph(ns.output, None if ns.all else ns.topics, _recorder_params(ns),
                                graph_dir=ns.graph_dir, duration=ns.duration)


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
    replace = ns.replace.split(",") if ns.replace else None
    replaced = add_player(graph, ns.bag, recorded_types(ns.bag), replace=replace,
                          params={"lockstep": True, "rate": 0.0})
    print(f"[test] replaying {ns.bag} in place of: {', '.join(replaced)}", file=sys.stderr)
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
