"""``probeless bag import``: a ROS bag -> a probeless MCAP recording (see :mod:`probeless.bag.ros_source`).

The output is written with :class:`~probeless.bag.writer.BagWriter` on the rig topics of
``launch/sources/recording.yaml``, so ``probeless bag info/play``, ``launch --replay`` and
``source:=recording bag:=OUT.mcap`` work on it. It is written next to ``OUT`` and renamed when
complete: a failed import leaves no half file behind.
"""

from __future__ import annotations

import json
import os
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable

from probeless import wire
from probeless.bag.ros_source import RosBag
from probeless.bag.writer import BagWriter
from probeless.errors import BagError, SchemaError
from probeless.progress import progress as progress_bar

IMPORT_META = "probeless.ros_import"   # metadata record: source, preset, maps, skipped topics


@dataclass
class ImportSummary:
    """What an import wrote (probeless topic -> count) and skipped (ROS topic -> why)."""

    written: Counter = field(default_factory=Counter)
    skipped: dict[str, str] = field(default_factory=dict)
    start_ns: int | None = None
    end_ns: int | None = None


def import_bag(src: str | Path, out: str | Path, *, preset: str | None = None, maps: Iterable[str] = (),
               start_s: float = 0.0, duration_s: float = 0.0, force: bool = False,
               progress: bool = False) -> ImportSummary:
    """Convert the ROS bag ``src`` into the probeless recording ``out``; BagError naming what is wrong."""
    out = Path(out)
    if out.exists() and not force:
        raise BagError(f"{out} exists (use --force to overwrite)")
    if start_s < 0 or duration_s < 0:
        raise BagError(f"--start and --duration must be >= 0, got {start_s} and {duration_s}")
    tmp = out.with_name(out.name + ".partial")
    summary = ImportSummary()
    with RosBag(src, preset, maps) as bag:
        summary.skipped = dict(bag.skipped)
        if bag.message_count == 0:
            named = f"preset {preset}" if preset else "no preset"
            raise BagError(f"{src}: the bag holds no message on the topics that {named}"
                           + (" and --map" if maps else "") + " name"
                           + (f" (skipped: {', '.join(sorted(bag.skipped))})" if bag.skipped else ""))
        start = bag.start_ns + round(start_s * 1e9)
        end = start + round(duration_s * 1e9) if duration_s else None
        meta = {IMPORT_META: {"source": str(Path(src).resolve()), "preset": preset or "",
                              "maps": json.dumps(list(maps)), "skipped": json.dumps(summary.skipped)}}
        try:
            with BagWriter(tmp, force=True, metadata=meta) as writer, \
                    progress_bar(bag.message_count, f"import {Path(src).name}", progress) as tick:
                for topic, log_ns, msg in bag.messages(start, end):
                    try:
                        frames = wire.encode(topic, msg, "rig", log_ns, seq=summary.written[topic])
                    except SchemaError as exc:
                        raise BagError(f"{src}: {topic}: {exc}") from None
                    writer.write_frames(frames, log_time_ns=log_ns)
                    summary.written[topic] += 1
                    summary.start_ns = log_ns if summary.start_ns is None else min(summary.start_ns, log_ns)
                    summary.end_ns = log_ns if summary.end_ns is None else max(summary.end_ns, log_ns)
                    tick()
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise
    os.replace(tmp, out)
    return summary
