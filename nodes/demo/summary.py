"""Summary sink: counts frames, measures latency and rate, writes a JSON summary and the last frame."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from probeless.errors import NodeError
from probeless.messages.sensor import Image
from probeless.runtime import Node, param
from probeless.runtime.params import writable_dir_problem

MAX_LATENCY_MS = 86_400_000.0  # a "latency" beyond a day means the stamps are not on this clock (scene time)


def summary_line(path: Any, summary: dict) -> str:
    """``wrote PATH: 90 frames, 30.0 Hz, latency p50 3.01 ms`` (n/a where a figure is unknown)."""
    def fmt(value: Any, spec: str) -> str:
        return "n/a" if value is None else format(value, spec)
    return (f"wrote {path}: {summary['frames']} frames, {fmt(summary['rate_hz'], '.1f')} Hz, "
            f"latency p50 {fmt(summary['latency_ms_p50'], '.2f')} ms")


def summarize(stamps_ns: list[int], latencies_ms: list[float], seqs: list[int]) -> dict:
    """Frame count, rate from stamps, latency percentiles and seq gaps of a received stream.

    Latency is left out (None) when the stamps are on another clock than the node's (e.g. a
    synthetic scene's time from 0), where now - stamp means nothing.
    """
    out = {"frames": len(stamps_ns), "seq_gaps": 0, "rate_hz": 0.0,
           "latency_ms_p50": None, "latency_ms_p99": None}
    if len(seqs) > 1:
        out["seq_gaps"] = int(sum(max(0, b - a - 1) for a, b in zip(seqs, seqs[1:])))
    if len(stamps_ns) > 1:
        span = (stamps_ns[-1] - stamps_ns[0]) / 1e9
        out["rate_hz"] = (len(stamps_ns) - 1) / span if span > 0 else 0.0
    if latencies_ms and max(abs(x) for x in latencies_ms) < MAX_LATENCY_MS:
        p50, p99 = np.percentile(latencies_ms, [50, 99])
        out["latency_ms_p50"], out["latency_ms_p99"] = float(p50), float(p99)
    return out


class SummarySink(Node):
    """Writes ``summary.json`` and ``last_frame.png`` to ``out_dir`` when the stream ends."""

    INPUTS = {"image": Image}

    @dataclass(frozen=True)
    class Params:
        out_dir: str = param("out/demo", check=writable_dir_problem,
                             doc="directory for summary.json and last_frame.png (created; relative to the "
                                 "working folder)")

    def setup(self) -> None:
        self.stamps: list[int] = []
        self.latencies: list[float] = []
        self.seqs: list[int] = []
        self.last: np.ndarray | None = None

    def on_input(self, name: str, msg: Image) -> None:
        self.stamps.append(msg.header.stamp_ns)
        self.seqs.append(msg.header.seq)
        self.latencies.append((self.ctx.now_ns() - msg.header.stamp_ns) / 1e6)  # recorded time on replay
        self.last = msg.data

    def close(self) -> None:
        out = Path(self.params.out_dir)
        summary = summarize(self.stamps, self.latencies, self.seqs)
        try:
            out.mkdir(parents=True, exist_ok=True)
            (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
        except OSError as exc:  # became unwritable since `check`: one line, not a traceback
            raise NodeError(f"cannot write {out / 'summary.json'}: {exc.strerror or exc}") from None
        if self.last is not None and not cv2.imwrite(str(out / "last_frame.png"),
                                                     cv2.cvtColor(self.last, cv2.COLOR_RGB2BGR)):
            raise NodeError(f"cannot write {out / 'last_frame.png'}")
        self.ctx.log.info("%s", summary_line(out / "summary.json", summary))
