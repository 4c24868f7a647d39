"""Compare two recordings message by message, for golden-file regression tests."""

from __future__ import annotations

from typing import Any

import numpy as np

from probeless.bag.reader import BagReader
from probeless.messages.base import Struct, schema_of

MAX_DIFFS = 40
MAX_PER_TOPIC = 3


def compare_recordings(actual: str, golden: str, *, atol: float = 1e-6, rtol: float = 0.0) -> list[str]:
    """Readable differences between two recordings (empty when they match).

    Per topic: the same type, the same number of messages, and message by message (in recorded
    order) equal fields; float arrays and floats may differ by ``atol + rtol * |golden|``.
    Envelope publish times and log times are not compared.
    """
    a, g = BagReader(actual), BagReader(golden)
    ta, tg = a.topics(), g.topics()
    diffs = [f"topic {t}: missing from the outputs" for t in sorted(tg.keys() - ta.keys())]
    diffs += [f"topic {t}: not in the golden recording" for t in sorted(ta.keys() - tg.keys())]
    for topic in sorted(ta.keys() & tg.keys()):
        if ta[topic].type_name != tg[topic].type_name:
            diffs.append(f"topic {topic}: type {ta[topic].type_name}, golden {tg[topic].type_name}")
            continue
        if ta[topic].count != tg[topic].count:
            diffs.append(f"topic {topic}: {ta[topic].count} message(s), golden {tg[topic].count}")
        differing = 0
        for i, (ma, mg) in enumerate(zip(a.messages(topic), g.messages(topic))):
            found = compare_values(a.decode(ma), g.decode(mg), "", atol, rtol)
            differing += bool(found)
            if found and differing <= MAX_PER_TOPIC:
                diffs += [f"topic {topic}: message {i}: {d}" for d in found]
        if differing > MAX_PER_TOPIC:
            diffs.append(f"topic {topic}: ... {differing - MAX_PER_TOPIC} more differing message(s) "
                         f"({differing} of {min(ta[topic].count, tg[topic].count)} in all)")
    return diffs[:MAX_DIFFS] + (["(further differences not shown)"] if len(diffs) > MAX_DIFFS else [])


def compare_values(x: Any, y: Any, path: str, atol: float, rtol: float) -> list[str]:
    """Differences between two field values (recursing into structs and tuples)."""
    if type(x) is not type(y):
        return [f"{path or 'message'}: type {type(x).__name__}, golden {type(y).__name__}"]
    if isinstance(x, Struct):
        out = []
        for spec in schema_of(type(x)):
            out += compare_values(getattr(x, spec.name), getattr(y, spec.name), _join(path, spec.name), atol, rtol)
        return out
    if isinstance(x, tuple):
        if len(x) != len(y):
            return [f"{path}: {len(x)} item(s), golden {len(y)}"]
        return [d for i, (u, v) in enumerate(zip(x, y)) for d in compare_values(u, v, f"{path}[{i}]", atol, rtol)]
    if isinstance(x, np.ndarray):
        return _compare_arrays(x, y, path, atol, rtol)
    if isinstance(x, float):
        return [] if abs(x - y) <= atol + rtol * abs(y) else [f"{path}: {x!r}, golden {y!r}"]
    return [] if x == y else [f"{path}: {x!r}, golden {y!r}"]


def _compare_arrays(x: np.ndarray, y: np.ndarray, path: str, atol: float, rtol: float) -> list[str]:
    if x.dtype != y.dtype or x.shape != y.shape:
        return [f"{path}: {x.dtype}{list(x.shape)}, golden {y.dtype}{list(y.shape)}"]
    if x.dtype.kind in "fc":
        bad = ~np.isclose(x, y, atol=atol, rtol=rtol, equal_nan=True)
    else:
        bad = x != y
    if not bad.any():
        return []
    where = tuple(int(i) for i in np.argwhere(bad)[0])
    err = np.abs(x.astype(np.float64) - y.astype(np.float64))
    return [f"{path}: {int(bad.sum())} of {x.size} element(s) differ, max abs diff {float(err.max()):.6g} "
            f"(first at {where}: {x[where].item()!r}, golden {y[where].item()!r})"]


def _join(path: str, name: str) -> str:
    return f"{path}.{name}" if path else name


def content_digest(path: str, skip_diagnostics: bool = True) -> str:
    """SHA-256 over every message in file order: topic, log and publish times, sequence, payload bytes.

    File metadata (run directory, pids, command line) is left out, and so are ``*/diagnostics``
    topics by default (they hold measured timings): two lockstep replays of the same recording
    through the same graph have the same digest.
    """
    import hashlib

    h = hashlib.sha256()
    reader = BagReader(path)
    for m in reader.messages(in_file_order=True) if _supports_file_order(reader) else reader.messages():
        if skip_diagnostics and m.topic.endswith("/diagnostics"):
            continue
        h.update(m.topic.encode() + b"\0")
        h.update(f"{m.log_time_ns}:{m.publish_time_ns}:{m.sequence}".encode())
        for frame in m.frames[1:]:
            h.update(bytes(frame))
    return h.hexdigest()


def _supports_file_order(reader: BagReader) -> bool:
    import inspect

    return "in_file_order" in inspect.signature(reader.messages).parameters
