"""The raw side of ``probeless bench bus``: two plain pyzmq processes, XPUB (XPUB_NODROP=1, the bus's SNDHWM)
-> SUB over ipc://, frames ``[topic, 17-byte header, payload]``, the payload sent with ``copy=False``; the
same two phases (burst, then paced) as the bus graph.

Equal buffering: our ``block`` input holds up to ``BLOCK_RECV_HWM`` messages in its SUB socket plus
``queue_size`` in its input queue; the raw SUB gets one RCVHWM of the same total
(:func:`subscriber_buffer`), so neither side can absorb a burst the other cannot."""

from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

GAP_S = 0.2
RUN_TIMEOUT_S = 300.0
RAW_HEADER = struct.Struct("<qqB")  # seq, stamp_ns, phase (0 = throughput, 1 = latency)
PHASES = ("tput", "lat")


def subscriber_buffer(queue_size: int) -> int:
    """Messages a ``block`` input of ``queue_size`` can hold (SUB socket RCVHWM + input queue): the raw
    subscriber's RCVHWM, so both sides buffer equally."""
    from probeless.runtime.transport import BLOCK_RECV_HWM

    return BLOCK_RECV_HWM + int(queue_size)


def _raw_pub(a: dict) -> None:
    import zmq

    from probeless.datasets.synthetic_frames import bench_image
    from probeless.runtime.transport import SEND_HWM

    ctx = zmq.Context()
    s = ctx.socket(zmq.XPUB)
    s.setsockopt(zmq.XPUB_NODROP, 1)
    s.setsockopt(zmq.SNDHWM, SEND_HWM)
    s.setsockopt(zmq.LINGER, 5000)
    s.bind(a["endpoint"])
    topic = a["topic"].encode()
    if not s.poll(60_000, zmq.POLLIN):
        raise SystemExit("raw publisher: no subscriber within 60 s")
    s.recv()  # the subscription
    data = bench_image(a["width"], a["height"])
    big = data.nbytes >= 65536
    pack = RAW_HEADER.pack

    def send(seq: int, phase: int) -> None:
        s.send(topic, zmq.SNDMORE)
        s.send(pack(seq, time.time_ns(), phase), zmq.SNDMORE)
        s.send(data, 0, copy=not big)

    seq = 0
    for _ in range(a["count"]):
        send(seq, 0)
        seq += 1
    if a["paced_count"]:
        period = 1e9 / a["rate_hz"]
        t0 = time.monotonic_ns() + int(a["gap_s"] * 1e9)
        for i in range(a["paced_count"]):
            wait = (t0 + i * period - time.monotonic_ns()) / 1e9
            if wait > 0:
                time.sleep(wait)
            send(seq, 1)
            seq += 1
    s.send_multipart([topic, b""])  # end of stream
    s.close()  # lingers until queued frames are out
    ctx.term()


def _raw_sub(a: dict) -> None:
    import zmq

    ctx = zmq.Context()
    s = ctx.socket(zmq.SUB)
    s.setsockopt(zmq.RCVHWM, int(a["rcvhwm"]))
    s.setsockopt(zmq.LINGER, 0)
    s.connect(a["endpoint"])
    s.setsockopt(zmq.SUBSCRIBE, a["topic"].encode())
    phases = {p: {"recv_ns": [], "stamp_ns": [], "seqs": []} for p in PHASES}
    shape = (a["height"], a["width"], 3)
    bad_shape = 0
    unpack = RAW_HEADER.unpack
    timeout_ms = 60_000
    while True:
        if not s.poll(timeout_ms, zmq.POLLIN):
            raise SystemExit("raw subscriber: no message within 60 s")
        frames = s.recv_multipart(copy=False)
        now = time.time_ns()
        if len(frames) == 2 and len(frames[1]) == 0:
            break
        seq, stamp, phase = unpack(frames[1].bytes)
        img = np.frombuffer(frames[2].buffer, np.uint8)
        if img.size != shape[0] * shape[1] * shape[2]:
            bad_shape += 1
        p = phases[PHASES[phase]]
        p["recv_ns"].append(now)
        p["stamp_ns"].append(stamp)
        p["seqs"].append(seq)
    s.close()
    ctx.term()
    tmp = a["out"] + ".tmp"
    Path(tmp).write_text(json.dumps({"other": 0, "bad_shape": bad_shape, "shape": list(shape), "phases": phases}))
    os.replace(tmp, a["out"])


def _raw_main(arg: str) -> None:
    a = json.loads(arg)
    (_raw_pub if a["role"] == "pub" else _raw_sub)(a)


def run_raw(cfg: tuple, tmp: Path, tag: str, rcvhwm: int) -> dict:
    """One raw run of payload ``cfg`` (name, w, h, burst, paced, rate); the SUB's RCVHWM is ``rcvhwm``."""
    name, w, h, n, m, rate = cfg
    out = tmp / f"raw-{tag}.json"
    common = {"endpoint": f"ipc://{tmp}/raw-{tag}.pub", "topic": "source/image", "width": w, "height": h}
    roles = [dict(common, role="sub", out=str(out), rcvhwm=int(rcvhwm)),
             dict(common, role="pub", count=n, paced_count=m, rate_hz=rate, gap_s=GAP_S)]
    code = "import sys; from probeless.bench.bus_raw import _raw_main; _raw_main(sys.argv[1])"
    procs = []
    for a in roles:
        err = open(tmp / f"raw-{tag}-{a['role']}.err", "w+")
        procs.append((subprocess.Popen([sys.executable, "-c", code, json.dumps(a)], stdout=subprocess.DEVNULL,
                                       stderr=err, stdin=subprocess.DEVNULL), err))
    deadline = time.monotonic() + RUN_TIMEOUT_S
    failed = []
    for (p, err), a in zip(procs, roles):
        try:
            p.wait(max(0.1, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()
        if p.returncode != 0:
            err.seek(0)
            failed.append(f"raw {a['role']} exit code {p.returncode}: {err.read().strip()[-2000:]}")
        err.close()
    if failed or not out.exists():
        raise RuntimeError("; ".join(failed) or "raw subscriber wrote no results")
    return json.loads(out.read_text())
