"""The one exception hierarchy of probeless.

Every error a user can trigger derives from :class:`ProbelessError`, so a CLI
can print it without a traceback and exit non-zero.
"""

from __future__ import annotations


class ProbelessError(Exception):
    """Base class of every probeless error."""


class SchemaError(ProbelessError):
    """A message does not match its declared schema (bad type, dtype, shape, size)."""


class GraphError(ProbelessError):
    """A launch graph is invalid. Carries where: file, line, node id and key."""

    def __init__(self, message: str, *, file: str | None = None, line: int | None = None,
                 node_id: str | None = None, key: str | None = None):
        self.message = message
        self.file = file
        self.line = line
        self.node_id = node_id
        self.key = key
        super().__init__(self.format())

    def format(self) -> str:
        where = ""
        if self.file:
            where = f"{self.file}:{self.line}" if self.line else self.file
        parts = [p for p in (where,
                             f"node '{self.node_id}'" if self.node_id else "",
                             f"key '{self.key}'" if self.key else "") if p]
        prefix = ": ".join(parts)
        return f"{prefix}: {self.message}" if prefix else self.message


class ParamError(GraphError):
    """A node parameter is bad: unknown, missing, of the wrong type, out of range, a missing file, or
    against a node's own rule (``param(check=...)``). Reported by ``probeless check`` and, should a
    node still find one at run time, raised by the node; never SchemaError/ValueError for a param."""


class GraphErrors(ProbelessError):
    """Several graph errors found in one validation pass."""

    def __init__(self, errors: list[GraphError]):
        self.errors = list(errors)
        super().__init__("\n".join(e.format() for e in self.errors))


class NodeError(ProbelessError):
    """A node failed at run time (setup, callback or close)."""


class TransportError(ProbelessError):
    """A socket could not be bound or connected, or the bus is shut down."""


class BagError(ProbelessError):
    """A recording cannot be read or written (not MCAP, corrupt, truncated, would overwrite, ...)."""


class SceneError(ProbelessError):
    """A synthetic scene file is invalid; the message names the file and the key at fault."""


class CalibrationError(ProbelessError):
    """A camera calibration file or calibration run is invalid or failed."""


class DatasetError(ProbelessError):
    """A dataset folder, image or video file is missing, malformed or of an unknown format."""


class DeviceError(ProbelessError):
    """A live camera could not be opened or stopped delivering frames."""


class GeometryError(ProbelessError):
    """Bad geometric input: a floorplan that is not a simple counter-clockwise polygon, a viewpoint outside it."""


class HdrError(ProbelessError):
    """HDR expansion of a point cloud: a bad cloud, photo, view or field (paper 001, §4)."""


class PbgiError(ProbelessError):
    """Point-based global illumination: a bad cloud, hierarchy or render setting (paper 001, §5)."""


class SweepError(ProbelessError):
    """A sweep file is invalid (unknown key, missing file, bad argument) or a sweep cannot run.
    Carries where: file, line and key, formatted like :class:`GraphError` (``file:line: key 'k': message``)."""

    def __init__(self, message: str, *, file: str | None = None, line: int | None = None, key: str | None = None):
        self.message = message
        self.file = file
        self.line = line
        self.key = key
        super().__init__(self.format())

    def format(self) -> str:
        where = (f"{self.file}:{self.line}" if self.line else self.file) if self.file else ""
        parts = [p for p in (where, f"key '{self.key}'" if self.key else "") if p]
        return f"{': '.join(parts)}: {self.message}" if parts else self.message
