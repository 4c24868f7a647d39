"""Reading LDR point clouds and writing/reading HDR ones (paper 001, §4).

* :func:`read_cloud`: a PLY or PCD file through Open3D, colours returned **linear**. A PLY's colours are read
  by their declared type (:func:`ply_colour_encoding`): ``uchar`` codes are sRGB (as scanners and Open3D's own
  datasets write them) and decoded with :func:`probeless.color.from_srgb8`; ``float``/``double`` colours are
  linear as stored (an HDR PLY of ``probeless hdr expand``, a renderer's export: a lamp of 20 stays 20); any
  other type or a mixture is refused naming the property. A PCD's colours (Open3D: 0..1) are taken as sRGB.
* :func:`write_hdr_ply` / :func:`read_hdr_ply`: a binary little-endian PLY whose vertices have float32
  ``x y z`` [m], optional float32 ``nx ny nz`` and float32 ``red green blue`` holding the **linear,
  unbounded** radiance (cloud units). Written by hand with numpy: Open3D would clip colours to 0..1.
  Open3D opens the file (it reads float colours as they are), and the round trip is bit-exact.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from probeless.color import srgb_to_linear
from probeless.errors import HdrError

CLOUD_SUFFIXES = (".ply", ".pcd")


def read_cloud(path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(points (N, 3) float32 [m], linear colours (N, 3) float32, normals (N, 3) float32 or None).

    8-bit and PCD colours come out as linear 0..1; float PLY colours as stored (module docstring). Raises
    :class:`HdrError` naming the file when it is missing, of another type, unreadable, empty or without colours.
    """
    p = Path(path)
    if p.suffix.lower() not in CLOUD_SUFFIXES:
        raise HdrError(f"{p}: unknown point cloud type {p.suffix!r}, expected one of {', '.join(CLOUD_SUFFIXES)}")
    if not p.is_file():
        raise HdrError(f"{p}: point cloud file not found")
    if p.suffix.lower() == ".ply":
        return _read_ply(p, ply_colour_encoding(p))
    import open3d as o3d

    from probeless.progress import stdout_to_stderr

    with stdout_to_stderr():
        pcd = o3d.io.read_point_cloud(str(p))
    points = np.asarray(pcd.points, dtype=np.float32)
    if len(points) == 0:
        raise HdrError(f"{p}: no points (empty or unreadable point cloud)")
    if not pcd.has_colors():
        raise HdrError(f"{p}: the point cloud has no colours")
    if not np.isfinite(points).all():
        raise HdrError(f"{p}: points have NaN or infinite coordinates")
    colors = np.asarray(pcd.colors, dtype=np.float32)
    colors = srgb_to_linear(np.clip(colors, 0.0, 1.0)).astype(np.float32)
    normals = np.asarray(pcd.normals, dtype=np.float32) if pcd.has_normals() else None
    return np.ascontiguousarray(points), np.ascontiguousarray(colors), normals


def require_ldr(path, colors: np.ndarray) -> None:
    """:class:`HdrError` naming ``path`` and the count when linear ``colors`` go above 1: an HDR cloud where an LDR
    one is expected (float PLY colours are radiance as stored, so :func:`read_cloud` passes them through)."""
    over = int((colors > 1.0).any(axis=1).sum())
    if over:
        raise HdrError(f"{path}: {over} point(s) have linear colours above 1 (up to {float(colors.max()):.4g}): "
                       f"an HDR cloud, where an LDR one (8-bit, or float 0..1) is expected")


PLY_LINEAR = {"float": "float", "float32": "float", "double": "double", "float64": "double"}
PLY_SRGB = {"uchar": "uchar", "uint8": "uchar"}
COLOUR_PROPERTIES = ("red", "green", "blue")


def ply_colour_encoding(path) -> str:
    """``"linear"`` (float or double red, green, blue) or ``"srgb"`` (uchar) from a PLY header; :class:`HdrError`
    naming the file and the property when the colours are missing, of another type (ushort, int, ...: no
    convention says what they mean) or of mixed kinds."""
    p = Path(path)
    props = _ply_vertex_properties(p)
    kinds = {}
    for name in COLOUR_PROPERTIES:
        if name not in props:
            have = ", ".join(f"{t} {n}" for n, t in props.items())
            raise HdrError(f"{p}: the point cloud has no colours: vertex property '{name}' missing (has: {have})")
        t = props[name]
        if t not in PLY_LINEAR and t not in PLY_SRGB:
            raise HdrError(f"{p}: colour property '{name}' is '{t}', which is ambiguous: expected float or double "
                           f"(linear radiance) or uchar (8-bit sRGB)")
        kinds[name] = "linear" if t in PLY_LINEAR else "srgb"
    if len(set(kinds.values())) > 1:
        odd = next(n for n in COLOUR_PROPERTIES if kinds[n] != kinds["red"])
        raise HdrError(f"{p}: colour property '{odd}' is '{props[odd]}' but 'red' is '{props['red']}': mixed "
                       f"colour types are ambiguous (all float/double: linear radiance, all uchar: sRGB)")
    return kinds["red"]


def _ply_vertex_properties(p: Path) -> dict:
    """{name: type} of the scalar properties of a PLY's ``vertex`` element."""
    with open(p, "rb") as f:
        head = f.read(1 << 16)
    end = head.find(b"end_header")
    if not head.startswith(b"ply") or end < 0:
        raise HdrError(f"{p}: not a PLY file (no 'ply' ... 'end_header' header)")
    props, element = {}, None
    for line in head[:end].decode("ascii", "replace").splitlines():
        w = line.split()
        if w[:1] == ["element"]:
            element = w[1] if len(w) > 1 else None
        elif w[:1] == ["property"] and element == "vertex" and len(w) == 3:
            props[w[2]] = w[1]
    return props


def _read_ply(p: Path, encoding: str) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Open3D's tensor reader keeps the stored colour type (the legacy reader divides every type by 255)."""
    import open3d as o3d

    from probeless.color import from_srgb8
    from probeless.progress import stdout_to_stderr

    with stdout_to_stderr():
        pcd = o3d.t.io.read_point_cloud(str(p))
    if "positions" not in pcd.point or len(pcd.point.positions) == 0:
        raise HdrError(f"{p}: no points (empty or unreadable point cloud)")
    if "colors" not in pcd.point:
        raise HdrError(f"{p}: the point cloud's colours could not be read")
    points = pcd.point.positions.numpy().astype(np.float32)
    raw = pcd.point.colors.numpy()
    colors = from_srgb8(raw.astype(np.uint8)) if encoding == "srgb" else raw.astype(np.float32)
    normals = pcd.point.normals.numpy().astype(np.float32) if "normals" in pcd.point else None
    for name, a in (("points", points), ("colours", colors), ("normals", normals)):
        if a is not None and not np.isfinite(a).all():
            raise HdrError(f"{p}: {name} have NaN or infinite values")
    if encoding == "linear" and (colors < 0).any():
        raise HdrError(f"{p}: negative colour values ({int((colors < 0).any(axis=1).sum())} point(s)); linear "
                       f"radiance must be >= 0")
    return (np.ascontiguousarray(points), np.ascontiguousarray(np.asarray(colors, np.float32)),
            None if normals is None else np.ascontiguousarray(normals))


def _vertex_dtype(normals: bool) -> np.dtype:
    names = ["x", "y", "z"] + (["nx", "ny", "nz"] if normals else []) + ["red", "green", "blue"]
    return np.dtype([(n, "<f4") for n in names])


def write_hdr_ply(path, points: np.ndarray, radiance: np.ndarray, normals: np.ndarray | None = None) -> Path:
    """Write the HDR cloud as a binary little-endian PLY (layout in the module docstring); returns the path.

    ``points`` (N, 3) [m], ``radiance`` (N, 3) linear >= 0 [cloud units], ``normals`` (N, 3) or None.
    """
    pts = np.asarray(points, np.float32)
    rad = np.asarray(radiance, np.float32)
    if pts.ndim != 2 or pts.shape[1] != 3 or rad.shape != pts.shape:
        raise HdrError(f"write_hdr_ply: points {pts.shape} and radiance {rad.shape} must be (N, 3) each")
    if not np.isfinite(rad).all() or (rad < 0).any():
        raise HdrError("write_hdr_ply: radiance must be finite and >= 0")
    nrm = None if normals is None else np.asarray(normals, np.float32)
    if nrm is not None and nrm.shape != pts.shape:
        raise HdrError(f"write_hdr_ply: normals {nrm.shape} must be like points {pts.shape}")
    dt = _vertex_dtype(nrm is not None)
    v = np.empty(len(pts), dt)
    v["x"], v["y"], v["z"] = pts.T
    if nrm is not None:
        v["nx"], v["ny"], v["nz"] = nrm.T
    v["red"], v["green"], v["blue"] = rad.T
    header = ["ply", "format binary_little_endian 1.0",
              "comment probeless HDR point cloud: red green blue = linear radiance [cloud units]",
              f"element vertex {len(pts)}"] + [f"property float {n}" for n in dt.names] + ["end_header"]
    out = Path(path)
    with open(out, "wb") as f:
        f.write(("\n".join(header) + "\n").encode("ascii"))
        f.write(v.tobytes())
    return out


def read_hdr_ply(path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(points (N, 3) float32, radiance (N, 3) float32, normals or None) of a :func:`write_hdr_ply` file."""
    p = Path(path)
    if not p.is_file():
        raise HdrError(f"{p}: HDR point cloud file not found")
    data = p.read_bytes()
    end = data.find(b"end_header\n")
    if not data.startswith(b"ply\n") or end < 0:
        raise HdrError(f"{p}: not a PLY file")
    lines = data[:end].decode("ascii", "replace").splitlines()
    if "format binary_little_endian 1.0" not in lines:
        raise HdrError(f"{p}: expected a binary little-endian PLY")
    n = None
    props = []
    for line in lines:
        w = line.split()
        if w[:2] == ["element", "vertex"]:
            n = int(w[2])
        elif w[:1] == ["element"] and n is not None:
            raise HdrError(f"{p}: unexpected element after the vertices: {line!r}")
        elif w[:1] == ["property"] and len(w) == 3:
            if w[1] not in ("float", "float32"):
                raise HdrError(f"{p}: property {w[2]} is {w[1]}, expected float")
            props.append(w[2])
    has_normals = "nx" in props
    dt = _vertex_dtype(has_normals)
    if n is None or props != list(dt.names):
        raise HdrError(f"{p}: vertex properties {props} are not those of an HDR cloud {list(dt.names)}")
    body = data[end + len(b"end_header\n"):]
    if len(body) < n * dt.itemsize:
        raise HdrError(f"{p}: truncated ({len(body)} bytes of vertex data, expected {n * dt.itemsize})")
    v = np.frombuffer(body, dt, count=n)
    pts = np.stack([v["x"], v["y"], v["z"]], axis=1)
    rad = np.stack([v["red"], v["green"], v["blue"]], axis=1)
    nrm = np.stack([v["nx"], v["ny"], v["nz"]], axis=1) if has_normals else None
    return pts, rad, nrm
