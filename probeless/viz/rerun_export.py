"""``probeless bag export --format rerun``: a recording as a Rerun ``.rrd`` file, with the default layout.

Every message goes through :class:`probeless.viz.rerun_logger.RerunLogger` (entity tree there), in log-time
order per file; a chunk that fails its CRC is skipped with a warning counting the messages it held, and
channels of other writers (not probeless-encoded) are skipped, named "not decodable: <encoding>".
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import rerun as rr

from probeless.bag.export import ExportSummary, export_sources, open_readers
from probeless.bag.foreign import not_decodable
from probeless.bag.format import MESSAGE_ENCODING
from probeless.errors import BagError
from probeless.progress import progress as progress_bar
from probeless.viz.blueprint import default_blueprint
from probeless.viz.rerun_logger import RerunLogger

APPLICATION_ID = "probeless"


def _fill(summary: ExportSummary, logger: RerunLogger) -> None:
    summary.written.update(logger.logged)
    for topic, n in logger.skipped.items():
        summary.skipped[topic] = summary.skipped.get(topic, 0) + n
        summary.schemas.setdefault(topic, f"skipped: {logger.reasons.get(topic, '')}")
    for topic, names in logger.archetypes.items():
        summary.schemas[topic] = "rerun " + ", ".join(sorted(names))


def export_rerun(src: str | Path | Sequence[str | Path], out: str | Path, *, force: bool = False,
                 topics: Sequence[str] | None = None, progress: bool = False) -> ExportSummary:
    """Write a recording (file, parts, or split set) to the Rerun file ``out``; the per-topic counts."""
    sources, out = export_sources(src, out, force)
    if not out.parent.is_dir():
        raise BagError(f"cannot write {out}: no directory {out.parent}")
    summary = ExportSummary()
    readers, total = open_readers(sources, topics, summary)
    stream = rr.RecordingStream(APPLICATION_ID)
    try:
        stream.save(out)
        stream.send_blueprint(default_blueprint())
        logger = RerunLogger(stream, blueprint=default_blueprint)
        with progress_bar(total, f"export {out.name}", progress) as tick:
            for r in readers:
                for ch, rec in r.records(topics=topics, on_corrupt=summary.warnings.append):
                    tick()
                    if ch.message_encoding != MESSAGE_ENCODING:
                        not_decodable(ch, summary)
                        continue
                    m = r.message_of(ch, rec)
                    if not logger.handles(m.type_name):
                        logger.skip(m.topic, f"{m.type_name} has no Rerun mapping")
                        continue
                    logger.log(m.topic, r.decode(m))
        stream.flush()
        _fill(summary, logger)
    finally:
        stream.disconnect()
        for r in readers:
            r.close()
    return summary
