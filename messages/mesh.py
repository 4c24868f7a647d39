"""3D geometry data: coloured point clouds and triangle meshes, in the frame of ``header.frame_id``.

Optional per-point/per-vertex arrays (normals, colours, uvs) are "absent" when they have 0 rows,
otherwise they must have one row per point/vertex. Float colours are linear RGB in [0, 1];
uint8 colours are sRGB 0..255. Triangles wind counter-clockwise seen from the front (OpenGL).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from probeless.errors import SchemaError
from probeless.messages.base import Message, array, message
from probeless.messages.header import Header


def _empty(cols: int):
    return lambda: np.zeros((0, cols), dtype=np.float32)


def _optional_rows(obj: object, name: str, rows: int, of: str) -> None:
    """Raise SchemaError unless field ``name`` has 0 rows or ``rows`` rows."""
    n = len(getattr(obj, name))
    if n not in (0, rows):
        raise SchemaError(f"{type(obj).__name__}.{name}: has {n} rows, expected 0 (absent) or {rows} (one per {of})")


@message("mesh/PointCloud", version=1)
@dataclass(frozen=True)
class PointCloud(Message):
    """An unordered set of 3D points with a colour each and optional normals."""

    header: Header      # stamp = capture time; frame_id = frame the points are expressed in
    points: np.ndarray = array("float32", ("n", 3))                # positions (x, y, z) [m, header.frame_id]
    colors: np.ndarray = array(("uint8", "float32"), ("n", 3))     # RGB per point [uint8 sRGB | float linear 0..1]
    # unit normals, 0 rows = none [-, header.frame_id]
    normals: np.ndarray = array("float32", (None, 3), default_factory=_empty(3))
    # when each point was last fused from a frame, 0 rows = all at header.stamp_ns [ns, same clock as header]
    stamps_ns: np.ndarray = array("int64", (None,), default_factory=lambda: np.zeros(0, np.int64))

    def validate(self) -> None:
        _optional_rows(self, "normals", len(self.points), "point")
        _optional_rows(self, "stamps_ns", len(self.points), "point")

    def __len__(self) -> int:
        return len(self.points)


@message("mesh/HdrPointCloud", version=1)
@dataclass(frozen=True)
class HdrPointCloud(Message):
    """A point cloud with unbounded linear radiance per point: an LDR cloud expanded to HDR (paper 001, §4).

    "Cloud units": the LDR colours' linear scale (1 = LDR white); an over-exposed point's radiance is
    ``alpha x`` the HDR photo's radiance, ``alpha`` the photo's matched exposure (:mod:`probeless.hdr`).
    """

    header: Header      # stamp = time the expansion ran; frame_id = frame the points are expressed in
    points: np.ndarray = array("float32", ("n", 3))                # positions (x, y, z) [m, header.frame_id]
    radiance: np.ndarray = array("float32", ("n", 3))              # linear RGB radiance, >= 0, unbounded [cloud units]
    # unit normals, 0 rows = none [-, header.frame_id]
    normals: np.ndarray = array("float32", (None, 3), default_factory=_empty(3))
    # the LDR colours before expansion, 0 rows = none [float linear 0..1]
    ldr_colors: np.ndarray = array("float32", (None, 3), default_factory=_empty(3))

    def validate(self) -> None:
        n = len(self.points)
        _optional_rows(self, "normals", n, "point")
        _optional_rows(self, "ldr_colors", n, "point")
        for name in ("radiance", "ldr_colors"):
            a = getattr(self, name)
            if not np.isfinite(a).all():
                raise SchemaError(f"HdrPointCloud.{name}: has {int((~np.isfinite(a)).sum())} NaN or infinite values")
            if (a < 0).any():
                raise SchemaError(f"HdrPointCloud.{name}: has {int((a < 0).sum())} negative values "
                                  f"(min {float(a.min()):g})")

    def __len__(self) -> int:
        return len(self.points)


@message("mesh/TriangleMesh", version=1)
@dataclass(frozen=True)
class TriangleMesh(Message):
    """An indexed triangle mesh with optional per-vertex colours, normals and texture coordinates."""

    header: Header      # stamp = time the mesh was built; frame_id = frame of the vertices
    vertices: np.ndarray = array("float32", ("v", 3))              # positions (x, y, z) [m, header.frame_id]
    triangles: np.ndarray = array(("int32", "uint32"), ("t", 3))   # vertex indices, counter-clockwise front [index]
    # RGB, 0 rows = none [uint8 sRGB | float linear 0..1]
    vertex_colors: np.ndarray = array(("float32", "uint8"), (None, 3), default_factory=_empty(3))
    # unit normals, 0 rows = none [-, header.frame_id]
    vertex_normals: np.ndarray = array("float32", (None, 3), default_factory=_empty(3))
    # texture coords (u right, v up, OpenGL), 0 rows = none [0..1]
    uvs: np.ndarray = array("float32", (None, 2), default_factory=_empty(2))

    def validate(self) -> None:
        nv = len(self.vertices)
        for name in ("vertex_colors", "vertex_normals", "uvs"):
            _optional_rows(self, name, nv, "vertex")
        if self.triangles.size and (self.triangles.min() < 0 or self.triangles.max() >= nv):
            raise SchemaError(f"TriangleMesh.triangles: index out of range [0, {nv}): "
                              f"min {self.triangles.min()}, max {self.triangles.max()}")
