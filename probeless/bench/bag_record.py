"""Measurement 1 of ``probeless bench bag`` (:mod:`probeless.bench.bag`): the recorder against a raw mcap writer.

``bench_camera_source`` recorded by the real ``bag_recorder`` (``add_recorder``), and the same messages
through a bare ``mcap.writer.Writer`` in this process, to a file written the way the recorder writes its
own; also the graph helpers the other measurements use.
"""

from __future__ import annotations

import inspect
import json
import os
import resource
import sys
import time
from pathlib import Path

CAMERA_TOPICS = ("camera/rgb", "camera/depth", "camera/fisheye")
RATE_HZ = 30.0
# Seconds both sides of the max-rate comparison wait, after the previous run's file was deleted,
# before they write (see "Cold memory" in probeless.bench.bag's docstring).
COLD_MEMORY_S = 3.0


def load_graph(tmp: Path, name: str, text: str):
    from probeless.launch.launcher import load_checked

    path = tmp / f"{name}.yaml"
    path.write_text(text)
    return load_checked(str(path), {})


def launch_graph(graph, what: str, clock_node: str | None = None) -> float:
    """Run a graph to its end; its wall time [s]. RuntimeError when it fails."""
    from probeless.launch.launcher import Launcher

    t0 = time.monotonic()
    code = Launcher(graph, out=sys.stderr, ready_timeout=60.0, clock_node=clock_node).run()
    if code != 0:
        raise RuntimeError(f"{what}: graph failed (exit code {code})")
    return time.monotonic() - t0


def unlink(path: Path) -> None:
    try:
        path.unlink()
    except FileNotFoundError:
        pass


# -- 1. record -------------------------------------------------------------------------------------
CAMERA_YAML = """\
description: recording benchmark camera (probeless bench bag)
nodes:
  - id: camera
    node: bench_camera_source
    outputs: [rgb, depth, fisheye]
    params: {{ticks: {ticks}, rate_hz: {rate}, max_rate: {max_rate}, out_path: {out}}}
"""


def _check_recording(path: Path, published: dict[str, int]) -> dict:
    """Counts, payload bytes, first log time and sequence continuity of a camera recording."""
    from probeless.bag.reader import BagReader
    from probeless.bag.writer import INCOMPLETE

    with BagReader(path) as reader:
        topics = reader.topics()
        incomplete = reader.metadata().get(INCOMPLETE, {})
        seqs: dict[str, list[int]] = {t: [] for t in topics}
        for m in reader.messages(in_file_order=True):
            seqs[m.topic].append(m.sequence)
        first_ns = reader.start_ns
    recorded = {t: topics[t].count if t in topics else 0 for t in CAMERA_TOPICS}
    gaps = {t: sum(1 for i, s in enumerate(seqs.get(t, [])) if s != i) for t in CAMERA_TOPICS}
    lossless = (recorded == published and not any(gaps.values()) and not incomplete
                and set(topics) == set(CAMERA_TOPICS))
    return {"recorded": recorded, "published": published, "seq_errors": gaps, "incomplete": incomplete,
            "lossless": bool(lossless), "bytes": sum(topics[t].bytes for t in topics),
            "file_bytes": path.stat().st_size, "first_ns": first_ns, "closed_ns": path.stat().st_mtime_ns}


def run_ours_record(tmp: Path, compression: str, ticks: int, max_rate: bool, tag: str,
                    cold_s: float = COLD_MEMORY_S) -> dict:
    from probeless.launch.replay import add_recorder

    out = tmp / f"camera-{tag}.json"
    bag = tmp / f"camera-{tag}.mcap"
    graph = load_graph(tmp, f"camera-{tag}", CAMERA_YAML.format(ticks=ticks, rate=RATE_HZ,
                                                           max_rate=str(max_rate).lower(),
                                                           out=json.dumps(str(out))))
    add_recorder(graph, str(bag), topics=list(CAMERA_TOPICS),
                 params={"compression": compression, "command": "probeless bench bag"})
    os.sync()  # start from a clean page cache: no run pays for the previous run's writeback
    if max_rate:
        time.sleep(cold_s)  # the same cold memory as the raw writer's (module docstring)
    ru0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    try:
        wall = launch_graph(graph, f"record ({compression}, {tag})")
        ended_ns = time.time_ns()  # the launcher returned: the recorder fsynced and exited
        ru = resource.getrusage(resource.RUSAGE_CHILDREN)
        src = json.loads(out.read_text())
        fig = _check_recording(bag, {f"camera/{k}": v for k, v in src["published"].items()})
    finally:
        unlink(bag)
    # first message received -> launcher returned: includes the recorder's fsync and process teardown
    span = (ended_ns - fig["first_ns"]) / 1e9
    fig.update(wall_s=wall, record_s=span, mb_per_s=fig["bytes"] / 1e6 / span if span > 0 else float("nan"),
               publish_s=(src["last_ns"] - src["first_ns"]) / 1e9, missed_ticks=src["missed_ticks"],
               ticks=src["ticks"], close_lag_s=(fig["closed_ns"] - src["last_ns"]) / 1e9,
               cpu_s=(ru.ru_utime - ru0.ru_utime) + (ru.ru_stime - ru0.ru_stime), sys_s=ru.ru_stime - ru0.ru_stime,
               minor_faults=ru.ru_minflt - ru0.ru_minflt)
    fig["messages"] = sum(fig["recorded"].values())
    return fig


def raw_payloads(ticks: int) -> tuple[list[tuple[str, bytes]], dict]:
    """The camera messages as the recorder stores them: msgpack-framed ``[meta, buffers...]``."""
    from probeless import wire
    from probeless.bag.format import pack_payload
    from probeless.datasets.synthetic_frames import camera_frames, camera_message

    sizes = {"rgb": (640, 480), "depth": (640, 480), "fisheye": (1024, 1024)}
    frames = {k: camera_frames(k, *sizes[k], 8) for k in sizes}
    seq = {k: 0 for k in sizes}
    out = []
    now = time.time_ns()
    for i in range(ticks):
        for kind in ("rgb", "depth", "fisheye"):
            if kind == "fisheye" and i % 2:
                continue
            msg = camera_message(kind, frames[kind][i % 8], now)
            topic = f"camera/{kind}"
            out.append((topic, pack_payload(wire.encode(topic, msg, "camera", now, seq=seq[kind])[1:])))
            seq[kind] += 1
    types = {f"camera/{k}": (camera_message(k, frames[k][0], 0)) for k in sizes}
    return out, {t: (type(m).TYPE_NAME, type(m).VERSION, type(m)) for t, m in types.items()}


class _AppendStream:
    """The write/tell stream mcap's Writer needs, appending through the recorder's own file output
    (:class:`~probeless.bag.directio.AppendFile`: page cache bypassed where the file system allows)."""

    def __init__(self, fd: int):
        from probeless.bag.directio import AppendFile

        self.out = AppendFile(fd)

    def write(self, data) -> int:
        return self.out.write([data])

    def tell(self) -> int:
        return self.out.pos


def run_raw_record(tmp: Path, compression: str, payloads: list[tuple[str, bytes]], types: dict, tag: str,
                   cold_s: float = COLD_MEMORY_S) -> dict:
    """The same messages through a bare mcap Writer, as fast as possible, in this process."""
    from mcap.writer import CompressionType, Writer

    from probeless.bag.format import MESSAGE_ENCODING, PROFILE, SCHEMA_ENCODING
    from probeless.bag.schema import json_schema
    from probeless.bag.writer import BagWriter

    chunk_size = inspect.signature(BagWriter.__init__).parameters["chunk_size"].default
    ctype = {"none": CompressionType.NONE, "lz4": CompressionType.LZ4}[compression]
    path = tmp / f"raw-{tag}.mcap"
    seq: dict[str, int] = {}
    os.sync()  # start from a clean page cache, like the recorder's runs
    time.sleep(cold_s)  # and from memory as cold as the recorder's (module docstring)
    try:
        ru0 = resource.getrusage(resource.RUSAGE_SELF)
        t0 = time.perf_counter()
        with open(path, "xb", buffering=0) as f:
            stream = _AppendStream(f.fileno())
            w = Writer(stream, chunk_size=chunk_size, compression=ctype, enable_crcs=True)
            w.start(profile=PROFILE, library="raw")
            channels, schemas = {}, {}
            for topic, payload in payloads:
                cid = channels.get(topic)
                if cid is None:
                    name, version, cls = types[topic]
                    if name not in schemas:
                        schemas[name] = w.register_schema(name=name, encoding=SCHEMA_ENCODING, data=json.dumps(
                            json_schema(cls), separators=(",", ":")).encode())
                    cid = channels[topic] = w.register_channel(topic=topic, message_encoding=MESSAGE_ENCODING,
                                                               schema_id=schemas[name],
                                                               metadata={"type": name, "version": str(version)})
                s = seq.get(topic, 0)
                now = time.time_ns()
                w.add_message(cid, log_time=now, data=payload, publish_time=now, sequence=s)
                seq[topic] = s + 1
            w.finish()
            direct = stream.out.direct
            stream.out.close()
            os.fsync(f.fileno())  # timed to the same point as the recorder: data on disk
        span = time.perf_counter() - t0
        ru = resource.getrusage(resource.RUSAGE_SELF)
        size = path.stat().st_size
    finally:
        unlink(path)
    nbytes = sum(len(p) for _, p in payloads)
    return {"bytes": nbytes, "file_bytes": size, "record_s": span, "mb_per_s": nbytes / 1e6 / span,
            "messages": len(payloads), "cpu_s": (ru.ru_utime - ru0.ru_utime) + (ru.ru_stime - ru0.ru_stime),
            "sys_s": ru.ru_stime - ru0.ru_stime, "minor_faults": ru.ru_minflt - ru0.ru_minflt,
            "direct_io": direct}
