"""Point cloud messages and files as the arrays :func:`~probeless.pbgi.bsh.build_bsh` takes (paper 001, §5).

Colours: a ``mesh/PointCloud``'s uint8 colours are sRGB codes, decoded to linear with :mod:`probeless.color`; float
colours are linear 0..1 already; a ``mesh/HdrPointCloud`` carries linear radiance (cloud units). All three are the
cloud's linear radiance for PBGI (a surface seen by the camera reflects what the camera measured).

Normals: when the cloud has none (the SLAM model, most scans), they are estimated with Open3D from the
:data:`NORMAL_NEIGHBOURS` nearest neighbours and turned to face ``orient_towards``. A scan does not say which side of
a surface was seen; the default, the cloud's centroid, is inside a scanned room, so normals face into the room where
the virtual objects stand (a point facing away from an object is culled as back-facing, so a wrong side would
darken the object). Pass the scanner's position, or an object's, when the centroid is not inside the room.
"""

from __future__ import annotations

import numpy as np

from probeless.errors import HdrError, PbgiError
from probeless.hdr.views import linear_colors
from probeless.messages.mesh import HdrPointCloud, PointCloud

NORMAL_NEIGHBOURS = 16


def estimate_normals(points: np.ndarray, orient_towards=None, k: int = NORMAL_NEIGHBOURS) -> np.ndarray:
    """(N, 3) float64 unit normals of ``points`` (N, 3) [m] by Open3D's KNN plane fit over ``k`` neighbours, each
    flipped to face ``orient_towards`` (3,) [m, same frame; None: the centroid]."""
    import open3d as o3d

    p = np.asarray(points, np.float64)
    target = p.mean(axis=0) if orient_towards is None else np.asarray(orient_towards, np.float64)
    if target.shape != (3,) or not np.isfinite(target).all():
        raise PbgiError(f"orient_towards: expected 3 finite numbers, got {orient_towards!r}")
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(p))
    pcd.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(knn=int(k)))
    pcd.orient_normals_towards_camera_location(target)
    n = np.asarray(pcd.normals, np.float64)
    bad = ~(np.linalg.norm(n, axis=1) > 0.5)  # a point without enough distinct neighbours
    if bad.any():
        d = target - p[bad]
        n[bad] = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
    return n


def _finite(name: str, a: np.ndarray) -> None:
    if not np.isfinite(a).all():
        bad = int((~np.isfinite(a)).any(axis=1).sum())
        raise PbgiError(f"cloud: '{name}' has NaN or infinite values ({bad} point(s))")


def cloud_arrays(msg: PointCloud | HdrPointCloud, orient_towards=None, *, estimate: bool = True
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(points (N, 3) float64 [m], radiance (N, 3) float32 linear, normals (N, 3) float64 unit) of a cloud message,
    in its frame. Missing normals are estimated (module docstring), or with ``estimate=False`` left out ((0, 3):
    for a use without a BSH). :class:`PbgiError`: "empty cloud", or NaNs naming the field."""
    if len(msg) == 0:
        raise PbgiError("empty cloud")
    if isinstance(msg, HdrPointCloud):
        name, colors = "radiance", np.asarray(msg.radiance, np.float32)
    else:
        name, colors = "colors", linear_colors(msg.colors)
    points = np.asarray(msg.points, np.float64)
    _finite("points", points)
    _finite(name, colors)
    if len(msg.normals) == 0:
        return points, colors, estimate_normals(points, orient_towards) if estimate else np.zeros((0, 3))
    normals = np.asarray(msg.normals, np.float64)
    _finite("normals", normals)
    return points, colors, normals


def read_cloud_file(path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(points (N, 3) float32 [m], linear radiance (N, 3) float32, normals or None) of a .ply/.pcd file.

    A PLY's colours are read by their declared type (:func:`probeless.hdr.io.ply_colour_encoding`):
    ``float``/``double`` are linear radiance as stored (an HDR PLY of ``probeless hdr expand``, a renderer's
    export), ``uchar`` are sRGB codes; any other type, or a mixture, is refused naming the property. A PCD's
    colours are taken as sRGB (:func:`probeless.hdr.io.read_cloud`). :class:`PbgiError` names the file."""
    from probeless.hdr.io import read_cloud

    try:
        return read_cloud(path)
    except HdrError as exc:
        raise PbgiError(str(exc)) from None
