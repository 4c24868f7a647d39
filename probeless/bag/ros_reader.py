"""Open a ROS bag with ``rosbags``' AnyReader, tolerating message definitions it cannot parse.

rosbags refuses a whole bag when one embedded definition does not parse: rosbag2 MCAP files store
service events (``*/srv/*_Event``, rosbag2 ≥ Iron) with a ``ros2msg`` schema holding the ``---``
separators of a service, which ``get_types_from_msg`` rejects. Probeless converts none of those types,
so :func:`open_any_reader` first tries the library as it is and, only when that fails on a definition,
reopens the bag registering every definition that parses and naming the others in ``unparsed``
(msgtype -> reason); those connections are then listed as skipped, never read.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from probeless.errors import BagError


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())[:200]


def _tolerant_class() -> type:
    from rosbags.highlevel import AnyReader
    from rosbags.interfaces import MessageDefinitionFormat
    from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore

    def types_of(conn: Any) -> dict:
        data = conn.msgdef.data
        if conn.msgdef.format == MessageDefinitionFormat.MSG:
            return get_types_from_msg(data, conn.msgtype)
        sep = "=" * 80 + "\n"
        parts = [p.split("\n", 1)[1] for p in data.split(sep)[1:]] if data.startswith(sep + "IDL: ") else [data]
        out: dict = {}
        for idl in parts:
            out.update(get_types_from_idl(idl))
        return out

    class TolerantAnyReader(AnyReader):
        """AnyReader registering the definitions that parse; ``unparsed``: msgtype -> why not."""

        unparsed: dict[str, str]

        def _open(self) -> None:
            for reader in self.readers:
                self.stack.enter_context(reader)
            conns = [c for r in self.readers for c in r.connections]
            defined = [c for c in conns if c.msgdef.format != MessageDefinitionFormat.NONE]
            typs: dict = {}
            self.unparsed = {}
            if not defined and self.default_typestore is not None:
                typs.update(self.default_typestore.fielddefs)
            for conn in defined:
                try:
                    typs.update(types_of(conn))
                except Exception as exc:   # rosbags' TypesysError and parser errors
                    self.unparsed[conn.msgtype] = f"rosbags cannot parse its definition ({_one_line(exc)})"
            store = get_typestore(Stores.EMPTY)
            store.register(typs)
            self.connections, self.typestore = conns, store

    return TolerantAnyReader


def open_any_reader(path: Path, default_typestore: Any) -> tuple[Any, dict[str, str]]:
    """An open AnyReader on ``path`` and {msgtype: why it cannot be decoded}; BagError for an unreadable bag."""
    from rosbags.highlevel import AnyReader

    try:
        reader = AnyReader([path], default_typestore=default_typestore)
        reader.open()
        return reader, {}
    except Exception as exc:  # rosbags raises its own ReaderError, ValueError, KeyError ... on bad files
        first = exc
    try:
        reader = _tolerant_class()([path], default_typestore=default_typestore)
        reader.open()
    except Exception:
        raise BagError(f"{path}: not a readable ROS bag ({type(first).__name__}: {_one_line(first)})") from None
    if not reader.unparsed:   # the first failure was not about a definition: report it
        reader.close()
        raise BagError(f"{path}: not a readable ROS bag ({type(first).__name__}: {_one_line(first)})")
    return reader, reader.unparsed
