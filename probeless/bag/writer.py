"""Write bus messages into MCAP files, optionally split by size or duration.

Each message is stored as its wire frames (see :mod:`probeless.bag.format`); each topic is one MCAP
channel whose schema is the JSON Schema of its message type (:mod:`probeless.bag.schema`). The
file itself is written by :class:`~probeless.bag.mcapfile.McapFile` (chunks built in place,
compressed and written by a background thread).
"""

from __future__ import annotations

import errno
import json
import os
import re
from pathlib import Path
from typing import Any, Mapping, Sequence

from mcap.records import Channel, DataEnd, Footer, Metadata, Schema
from mcap.writer import MCAP0_MAGIC

from probeless.bag.chunks import COMPRESSIONS, MESSAGE_HEADER, payload_size
from probeless.bag.directio import seal
from probeless.bag.format import MESSAGE_ENCODING, PROFILE, SCHEMA_ENCODING, peek
from probeless.bag.mcapfile import McapFile, record_bytes
from probeless.bag.schema import json_schema
from probeless.errors import BagError, SchemaError
from probeless.messages.base import lookup
from probeless.provenance import redact

INCOMPLETE = "probeless.incomplete"  # metadata: what is missing from the recording (read by bag info)

DEFAULT_CHUNK_SIZE = 4 * 1024 * 1024


def _library() -> str:
    try:
        from importlib.metadata import version
        return f"probeless/{version('probeless')}"
    except Exception:  # not installed as a distribution
        return "probeless"


def split_paths(path: str | Path) -> list[Path]:
    """The existing parts ``<stem>_000.mcap``, ``<stem>_001.mcap``, ... of a split recording ``path``."""
    path = Path(path)
    pattern = re.compile(re.escape(path.stem) + r"_(\d{3,})" + re.escape(path.suffix or ".mcap") + "$")
    if not path.parent.is_dir():
        return []
    found = [(int(m.group(1)), p) for p in path.parent.iterdir() if (m := pattern.match(p.name))]
    return [p for _, p in sorted(found)]


def recording_paths(paths: str | Path | Sequence[str | Path]) -> list[Path]:
    """The files of the recordings named: each path itself, or the parts of a split recording when
    ``path`` does not exist but ``<stem>_000.mcap``... do. Raises BagError when neither exists."""
    out: list[Path] = []
    for p in [paths] if isinstance(paths, (str, Path)) else paths:
        p = Path(p)
        parts = [] if p.exists() else split_paths(p)
        if not p.exists() and not parts:
            raise BagError(f"{p}: no such file")
        out.extend(parts or [p])
    return out


def _check_metadata(name: str, data: Mapping[str, str]) -> dict[str, str]:
    """The record's strings, values of secret-looking environment variables taken out (never stored)."""
    if not isinstance(name, str) or not all(isinstance(k, str) and isinstance(v, str) for k, v in data.items()):
        raise BagError(f"metadata {name!r}: names, keys and values must all be strings")
    return redact(dict(data))


def _why(exc: OSError) -> str:
    """The reason of a failed write, saying "disk full" when it is."""
    why = exc.strerror or str(exc)
    return f"{why} (disk full)" if exc.errno in (errno.ENOSPC, errno.EDQUOT) else why


class BagWriter:
    """Records messages into one MCAP file, or into numbered parts when a split limit is given.

    Without ``max_size``/``max_duration_s`` the recording is exactly ``path``. With either, parts are
    named ``<stem>_000.mcap``, ``<stem>_001.mcap``, ...; a new part starts before a message that
    would take the current part past ``max_size`` bytes (estimated from the compressed bytes
    written, the uncompressed bytes not written yet and the size of the summary, so parts stay just
    under the limit; a single larger message gets a part of its own) or past ``max_duration_s`` of
    log time. Every part is a complete MCAP file with its own schemas, channels and the metadata
    given so far.

    ``compression`` defaults to ``"lz4"``: it is fast enough to keep up with uncompressed camera
    streams on two cores, where zstd is noticeably slower (720p RGB + uint16 depth with sensor
    noise, one core: lz4 writes 277 MB/s and reads 2.2 GB/s, zstd 188 MB/s and 1.0 GB/s, for a
    file about 25% smaller); ``"none"`` is the fastest. Files are always chunked with chunk CRCs
    and message indexes, so they seek fast and a killed recording stays readable up to its last
    written chunk. A chunk is closed once it holds more than ``chunk_size`` bytes of records
    (before compression; default 4 MiB: 1 MiB and 16 MiB recorded no faster in ``probeless bench
    bag``, and smaller chunks keep a replay's per-chunk decompression short).
    Chunks are compressed and written by a background thread; :meth:`flush` waits for them. With
    ``direct_io`` (the default) files bypass the page cache where the file system allows it
    (:mod:`probeless.bag.directio`; :attr:`direct_io` says whether the current part does).

    An existing file is never overwritten unless ``force``; with ``force`` and splitting, stale
    parts ``<stem>_NNN.mcap`` of an earlier recording are deleted first.
    """

    def __init__(self, path: str | Path, *, compression: str = "lz4", chunk_size: int = DEFAULT_CHUNK_SIZE,
                 max_size: int | None = None, max_duration_s: float | None = None, force: bool = False,
                 metadata: Mapping[str, Mapping[str, str]] | None = None, direct_io: bool = True):
        if compression not in COMPRESSIONS:
            raise BagError(f"unknown compression {compression!r}, expected one of {sorted(COMPRESSIONS)}")
        if not chunk_size > 0:
            raise BagError(f"chunk_size must be > 0 bytes, got {chunk_size}")
        if max_size is not None and max_size <= 0:
            raise BagError(f"max_size must be > 0 bytes, got {max_size}")
        if max_duration_s is not None and not max_duration_s > 0:
            raise BagError(f"max_duration_s must be > 0, got {max_duration_s}")
        self.path = Path(path)
        self._compression = compression
        self._chunk_size = int(chunk_size)
        self._max_size = max_size
        self._max_duration_ns = None if max_duration_s is None else int(max_duration_s * 1e9)
        self._split = max_size is not None or max_duration_s is not None
        self._force = force
        self._direct_io = direct_io
        self._metadata = {name: _check_metadata(name, data) for name, data in (metadata or {}).items()}
        self._topic_types: dict[str, tuple[str, int]] = {}
        self._schema_data: dict[str, bytes] = {}
        self._paths: list[Path] = []
        self._mcap: McapFile | None = None
        self._file: Any = None
        self._closed = False
        self.failed = ""        # why recording stopped early (a failed write), "" while all is well
        self.message_count = 0
        self._prepare()
        self._open_part()

    @property
    def direct_io(self) -> bool:
        """Whether the part in progress is written without the page cache."""
        return self._mcap.direct_io

    @property
    def paths(self) -> list[Path]:
        """The files written so far (the one in progress last)."""
        return list(self._paths)

    def _prepare(self) -> None:
        existing = split_paths(self.path) if self._split else [self.path] if self.path.exists() else []
        if existing and not self._force:
            raise BagError(f"{existing[0]} already exists; pass --force to overwrite it")
        if self._split:
            for old in existing:
                old.unlink()

    def _open_part(self) -> None:
        if self._split:
            name = self.path.with_name(f"{self.path.stem}_{len(self._paths):03d}{self.path.suffix or '.mcap'}")
        else:
            name = self.path
        try:
            Path(name).parent.mkdir(parents=True, exist_ok=True)
            self._file = open(name, "wb" if self._force else "xb", buffering=0)
        except FileExistsError:
            raise BagError(f"{name} already exists; pass --force to overwrite it") from None
        except OSError as exc:
            raise self._stop(f"cannot create {name}: {_why(exc)}") from None
        self._paths.append(name)
        try:
            self._mcap = McapFile(self._file, compression=self._compression, chunk_size=self._chunk_size,
                                  profile=PROFILE, library=_library(), direct_io=self._direct_io)
            for meta_name, data in self._metadata.items():
                self._mcap.add_metadata(meta_name, data)
        except OSError as exc:
            self._file.close()
            raise self._stop(f"cannot write {name}: {_why(exc)}") from None
        self._channels: dict[str, int] = {}
        self._schemas: dict[str, int] = {}
        self._part_messages = 0
        self._part_first_ns = 0
        self._registered = 0    # bytes of schema and channel records, repeated in the summary

    def _finish_part(self, extra: Mapping[str, Mapping[str, str]] | None = None) -> None:
        try:
            try:
                for meta_name, data in (extra or {}).items():
                    self._mcap.add_metadata(meta_name, data)
            except OSError as exc:
                raise self._fail(exc) from None
            try:
                self._mcap.finish()
            except OSError as exc:
                raise self._fail(exc, stopped=True) from None
            try:
                os.fsync(self._file.fileno())  # a finished recording is on disk, not only in the page cache
            except OSError as exc:
                raise BagError(f"cannot write {self._paths[-1]}: {_why(exc)}") from None
        finally:
            self._file.close()

    def _stop(self, why: str) -> BagError:
        """A new part could not be started: recording stops (the parts before are complete)."""
        self._closed = True
        self.failed = f"{why}; recording stopped"
        return BagError(self.failed)

    def _fail(self, exc: OSError, stopped: bool = False) -> BagError:
        """Stop recording after a failed write (disk full, I/O error); returns the error to raise.

        Nothing more of the recording is written: the writer thread stops (``stopped``: it has already), the
        file is cut back to its last complete record (the chunks written whole) and, where the space allows,
        sealed with an ``probeless.incomplete`` metadata record, a data end and a footer without summary, so
        every MCAP reader reads it to the end. Without room for those ~300 bytes it ends at its last complete
        record, which our reader reads as a truncated recording.
        """
        self._closed = True
        path = self._paths[-1]
        why = _why(exc)
        if not stopped:
            try:
                self._mcap.finish()  # raises the writer thread's error and stops the thread
                self.failed = f"cannot write {path}: {why}"  # it did not: the file is complete after all
                return BagError(self.failed)
            except Exception:  # noqa: BLE001 - the first error is the one reported
                pass
        note = f"recording stopped early: cannot write {path}: {why}; later messages were not recorded"
        tail = record_bytes(Metadata(name=INCOMPLETE, metadata={"recording": note}), DataEnd(data_section_crc=0),
                            Footer(summary_start=0, summary_offset_start=0, summary_crc=0)) + MCAP0_MAGIC
        sealed = seal(self._file.fileno(), self._mcap.written, tail)
        self.failed = (f"cannot write {path}: {why}; recording stopped, the file keeps its complete chunks"
                       + ("" if sealed else " (no room left for its footer)"))
        return BagError(self.failed)

    def _channel(self, topic: str, type_name: str, version: int) -> int:
        known = self._topic_types.get(topic)
        if known is not None and known != (type_name, version):
            raise BagError(f"topic {topic!r}: got {type_name} v{version}, "
                           f"but the recording has {known[0]} v{known[1]} on it")
        cid = self._channels.get(topic)
        if cid is not None:
            return cid
        if type_name not in self._schema_data:
            try:
                cls = lookup(type_name)
            except SchemaError:
                raise BagError(f"topic {topic!r}: cannot record unknown message type {type_name!r}") from None
            if cls.VERSION != version:
                raise BagError(f"topic {topic!r}: cannot record {type_name} schema version {version}, "
                               f"this build has version {cls.VERSION}")
            self._schema_data[type_name] = json.dumps(json_schema(cls), separators=(",", ":")).encode()
        schema = None
        sid = self._schemas.get(type_name)
        if sid is None:
            sid = self._schemas[type_name] = len(self._schemas) + 1
            schema = Schema(id=sid, name=type_name, encoding=SCHEMA_ENCODING, data=self._schema_data[type_name])
            self._registered += 30 + len(type_name) + len(self._schema_data[type_name])
        cid = self._channels[topic] = len(self._channels) + 1
        self._mcap.register(schema, Channel(id=cid, topic=topic, message_encoding=MESSAGE_ENCODING, schema_id=sid,
                                            metadata={"type": type_name, "version": str(version)}))
        self._topic_types[topic] = (type_name, version)
        self._registered += 60 + len(topic) + len(type_name)
        return cid

    def _should_roll(self, log_time_ns: int, size: int) -> bool:
        if self._part_messages == 0:
            return False
        if self._max_duration_ns is not None and log_time_ns - self._part_first_ns >= self._max_duration_ns:
            return True
        if self._max_size is None:
            return False
        m = self._mcap
        summary = 300 + self._registered + (m.stats.chunk_count + 1) * (90 + 10 * len(self._channels))
        if m.written + m.pending + size + summary <= self._max_size:
            return False
        m.drain()  # queued chunks count uncompressed until written: look again at what they became
        return m.written + m.pending + size + summary > self._max_size

    def write(self, topic: str, type_name: str, version: int, frames_after_topic: Sequence[Any], *,
              log_time_ns: int, publish_time_ns: int, sequence: int = 0) -> None:
        """Record one message: ``frames_after_topic`` is ``[meta, buf0, ...]`` exactly as on the wire.

        ``log_time_ns`` is the receive time, ``publish_time_ns`` the envelope's publish time and
        ``sequence`` the publisher's ``header.seq`` (stored modulo 2**32, MCAP's field is uint32;
        the exact value stays in the payload). Each frame is copied once, into the chunk in
        progress. Raises BagError for a type unknown to this build, a schema version other than
        this build's, a topic whose type changed, or a failed write.
        """
        if self._closed:
            raise BagError(self.failed or f"{self.path}: recording is closed")
        try:
            if self._split and self._should_roll(log_time_ns, MESSAGE_HEADER.size + payload_size(frames_after_topic)):
                self._finish_part()
                self._open_part()
            cid = self._channel(topic, type_name, version)
            self._mcap.add_message(cid, int(log_time_ns), int(publish_time_ns), int(sequence) & 0xFFFFFFFF,
                                   frames_after_topic)
        except OSError as exc:
            raise self._fail(exc) from None
        if self._part_messages == 0:
            self._part_first_ns = log_time_ns
        self._part_messages += 1
        self.message_count += 1

    def write_frames(self, frames: Sequence[Any], *, log_time_ns: int) -> None:
        """Record full wire frames ``[topic, meta, buf0, ...]``; type, version, publish time and
        sequence are peeked from the metadata (the array frames are not decoded)."""
        if len(frames) < 2:
            raise BagError(f"cannot record {len(frames)} frame(s), need topic and metadata")
        topic = bytes(getattr(frames[0], "bytes", frames[0])).decode("utf-8", errors="replace")
        type_name, version, _, publish_ns, _, seq = peek(frames[1])
        self.write(topic, type_name, version, frames[1:], log_time_ns=log_time_ns,
                   publish_time_ns=publish_ns, sequence=seq)

    def add_metadata(self, name: str, data: Mapping[str, str]) -> None:
        """Store a metadata record now and in every later part (strings only)."""
        if self._closed:
            raise BagError(f"{self.path}: recording is closed")
        self._metadata[name] = _check_metadata(name, data)
        try:
            self._mcap.add_metadata(name, self._metadata[name])
        except OSError as exc:
            raise self._fail(exc) from None

    def flush(self) -> None:
        """Finish the chunk in progress and wait until it is written: a crash after this loses nothing before it."""
        if not self._closed:
            try:
                self._mcap.flush()
            except OSError as exc:
                raise self._fail(exc) from None

    def close(self, extra_metadata: Mapping[str, Mapping[str, str]] | None = None) -> None:
        """Write the summary, fsync and close; ``extra_metadata`` goes into the last part only. Idempotent, but
        after a failed write it raises that failure again (the file was already cut back and sealed)."""
        if self._closed:
            if self.failed:
                raise BagError(self.failed)
            return
        self._closed = True
        extra = {name: _check_metadata(name, data) for name, data in (extra_metadata or {}).items()}
        self._finish_part(extra)

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
