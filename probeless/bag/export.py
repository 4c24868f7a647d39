"""``probeless bag export``: recordings into formats other tools read.

* ``foxglove``: an MCAP file with Foxglove well-known schemas, JSON-encoded (schema encoding
  ``jsonschema``, message encoding ``json``), through the mapping of :mod:`probeless.bag.foxglove`
  (shared with the live ``foxglove_bridge`` node). Types without a Foxglove equivalent are skipped
  (counted per topic). Channels of other writers whose encoding Foxglove decodes itself
  (:data:`probeless.bag.foreign.PASSTHROUGH`: json, protobuf, ros1, cdr with ros2msg/ros2idl/omgidl
  schemas, flatbuffer) are copied with their schemas byte for byte; any other is skipped and named
  "not decodable: <encoding>" per topic.
* ``png-dir``: every image topic as numbered PNGs ``DIR/<topic, "/" -> "__">/000000.png`` plus a
  ``timestamps.csv``; 16-bit images and uint16 depth stay 16-bit, float32 depth becomes uint16 mm.
  Channels of other encodings are "not decodable" here.

Both skip a chunk that fails its CRC with a warning counting the messages it held.
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator, Sequence

import numpy as np
from mcap.records import Channel, Message

from probeless.bag.foreign import Passthrough, not_decodable
from probeless.bag.format import MESSAGE_ENCODING
from probeless.bag.foxglove import FOXGLOVE, SCHEMAS, _display_image, encode, reinhard, schema_json
from probeless.bag.reader import BagMessage, BagReader
from probeless.bag.writer import recording_paths
from probeless.color import to_srgb8
from probeless.errors import BagError
from probeless.progress import progress as progress_bar

FORMATS = ("foxglove", "png-dir")
__all__ = ["FORMATS", "FOXGLOVE", "SCHEMAS", "ExportSummary", "export_foxglove", "export_png_dir", "reinhard"]


@dataclass
class ExportSummary:
    """Messages written and skipped per topic, and notes on lossy conversions (one per topic and kind)."""

    written: dict[str, int] = field(default_factory=dict)
    skipped: dict[str, int] = field(default_factory=dict)
    schemas: dict[str, str] = field(default_factory=dict)   # topic -> what it was written as
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)

    def note(self, text: str) -> None:
        if text not in self.notes:
            self.notes.append(text)


# -- driving -------------------------------------------------------------------------------------


def export_sources(src: str | Path | Sequence[str | Path], out: str | Path,
                   force: bool) -> tuple[list[Path], Path]:
    """(recording files, output path) of an export to one file; BagError when ``out`` is one of the inputs or
    exists without ``force``."""
    sources, out = recording_paths(src), Path(out)
    if any(out.resolve() == p.resolve() for p in sources if out.exists()):
        raise BagError(f"{out}: output would overwrite the recording being exported")
    if out.exists() and not force:
        raise BagError(f"{out} already exists; pass --force to overwrite it")
    return sources, out


def open_readers(sources: Sequence[Path], topics: Sequence[str] | None,
                 summary: ExportSummary) -> tuple[list[BagReader], int]:
    """Readers of every file (all closed again if one fails) and the number of messages to export; truncated
    files are noted in ``summary.warnings``."""
    readers = []
    try:
        for p in sources:
            readers.append(BagReader(p))
    except BagError:
        for r in readers:
            r.close()
        raise
    total = 0
    for r in readers:
        if r.truncated:
            summary.warnings.append(f"{r.path}: {r.truncation_note}")
        total += sum(t.count for t in r.topics().values() if topics is None or t.topic in topics)
    return readers, total


def _iter(readers: list[BagReader], topics, tick,
          summary: ExportSummary) -> Iterator[tuple[BagReader, Channel, BagMessage | Message]]:
    """(reader, channel, message) in log-time order per file: a BagMessage on probeless channels, the
    raw MCAP message on others; a corrupt chunk is skipped with a warning counting what it held."""
    for r in readers:
        for ch, rec in r.records(topics=topics, on_corrupt=summary.warnings.append):
            yield r, ch, (rec if ch.message_encoding != MESSAGE_ENCODING else r.message_of(ch, rec))
            tick()


def export_foxglove(src: str | Path | Sequence[str | Path], out: str | Path, *, force: bool = False,
                    topics: Sequence[str] | None = None, progress: bool = False) -> ExportSummary:
    """Rewrite a recording (file, parts, or split set) into ``out`` with Foxglove JSON schemas."""
    from mcap.writer import CompressionType, Writer

    sources, out = export_sources(src, out, force)
    summary = ExportSummary()
    readers, total = open_readers(sources, topics, summary)
    try:
        with open(out, "wb") as f, progress_bar(total, f"export {out.name}", progress) as tick:
            writer = Writer(f, compression=CompressionType.ZSTD)
            writer.start(profile="", library="probeless bag export")
            schema_ids: dict[str, int] = {}
            channel_ids: dict[str, int] = {}
            for r in readers:
                for name, data in r.metadata().items():
                    writer.add_metadata(name, data)
            passthrough = Passthrough(writer)
            for r, ch, m in _iter(readers, topics, tick, summary):
                if ch.message_encoding != MESSAGE_ENCODING:
                    passthrough.add(r, ch, m, summary)
                    continue
                convert = FOXGLOVE.get(m.type_name)
                if convert is None:
                    summary.skipped[m.topic] = summary.skipped.get(m.topic, 0) + 1
                    summary.schemas.setdefault(m.topic, f"skipped: {m.type_name} has no Foxglove equivalent")
                    continue
                schema, doc = convert(r.decode(m), m.topic, summary)
                if m.topic not in channel_ids:
                    if schema not in schema_ids:
                        schema_ids[schema] = writer.register_schema(
                            name=schema, encoding="jsonschema", data=schema_json(schema))
                    channel_ids[m.topic] = writer.register_channel(m.topic, "json", schema_ids[schema])
                    summary.schemas[m.topic] = schema
                writer.add_message(channel_ids[m.topic], log_time=m.log_time_ns, publish_time=m.publish_time_ns,
                                   sequence=m.sequence, data=encode(doc))
                summary.written[m.topic] = summary.written.get(m.topic, 0) + 1
            writer.finish()
    except OSError as exc:
        raise BagError(f"cannot write {out}: {exc.strerror or exc}") from None
    finally:
        for r in readers:
            r.close()
    return summary


def _png_pixels(msg: Any, type_name: str, topic: str, summary: ExportSummary) -> np.ndarray:
    """BGR(A)/mono uint8 or uint16 pixels for cv2.imwrite."""
    if type_name == "sensor/DepthImage":
        if msg.data.dtype == np.uint16:
            return msg.data
        summary.note(f"{topic}: float depth written as uint16 millimetres (0 = invalid)")
        return np.clip(np.round(msg.metres() * 1000.0), 0, 65535).astype(np.uint16)
    pixels, enc = _display_image(msg, topic, summary)
    if enc == "32FC1":
        summary.note(f"{topic}: mono float written as 8-bit through the sRGB curve")
        pixels, enc = to_srgb8(pixels), "mono8"
    if enc in ("rgb8", "rgb16"):
        return pixels[..., ::-1]
    if enc == "rgba8":
        return pixels[..., [2, 1, 0, 3]]
    return pixels[..., 0] if pixels.shape[2] == 1 else pixels


def export_png_dir(src: str | Path | Sequence[str | Path], out_dir: str | Path, *, force: bool = False,
                   topics: Sequence[str] | None = None, progress: bool = False) -> ExportSummary:
    """Write every Image/DepthImage topic of a recording as numbered PNGs under ``out_dir``."""
    import cv2

    sources, out_dir = recording_paths(src), Path(out_dir)
    if out_dir.exists() and (not out_dir.is_dir() or any(out_dir.iterdir())):
        if not force:
            raise BagError(f"{out_dir} already exists and is not empty; pass --force to overwrite it")
        if out_dir.is_dir():
            shutil.rmtree(out_dir)
        else:
            out_dir.unlink()
    summary = ExportSummary()
    readers, total = open_readers(sources, topics, summary)
    csvs: dict[str, Any] = {}
    try:
        with progress_bar(total, f"export {out_dir.name}/", progress) as tick:
            for r, ch, m in _iter(readers, topics, tick, summary):
                if ch.message_encoding != MESSAGE_ENCODING:
                    not_decodable(ch, summary)
                    continue
                if m.type_name not in ("sensor/Image", "sensor/DepthImage"):
                    summary.skipped[m.topic] = summary.skipped.get(m.topic, 0) + 1
                    summary.schemas.setdefault(m.topic, f"skipped: {m.type_name} is not an image")
                    continue
                msg = r.decode(m)
                topic_dir = out_dir / m.topic.replace("/", "__")
                if m.topic not in csvs:
                    topic_dir.mkdir(parents=True, exist_ok=True)
                    csvs[m.topic] = open(topic_dir / "timestamps.csv", "w")
                    csvs[m.topic].write("index,log_time_ns,stamp_ns,seq\n")
                    summary.schemas[m.topic] = f"PNG in {topic_dir}"
                n = summary.written.get(m.topic, 0)
                name = topic_dir / f"{n:06d}.png"
                if not cv2.imwrite(str(name), np.ascontiguousarray(_png_pixels(msg, m.type_name, m.topic, summary))):
                    raise BagError(f"cannot write {name}")
                csvs[m.topic].write(f"{n},{m.log_time_ns},{msg.header.stamp_ns},{msg.header.seq}\n")
                summary.written[m.topic] = n + 1
    except OSError as exc:
        raise BagError(f"cannot write under {out_dir}: {exc.strerror or exc}") from None
    finally:
        for f in csvs.values():
            f.close()
        for r in readers:
            r.close()
    return summary
