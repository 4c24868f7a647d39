"""Where to render the unlighted views from: cameras that see the over-exposed areas (paper 001, §4.1).

The paper lets a user pick the rendering positions "to see the most important overexposed areas".
This module picks them automatically (or takes them from the caller, :func:`views_from_positions`):

1. :func:`saturated_clusters`: the over-exposed points (LDR luminance > ``threshold``, 0.9 as the
   paper's t_l) grouped into connected clusters on a voxel grid (voxels sharing a face, edge or
   corner are connected), largest first.
2. :func:`place_views`, for each of the ``n_views`` largest clusters: candidate directions from the
   cluster centre, in order of preference: the cluster's mean normal (when normals are given,
   turned toward the cloud centroid), the direction to the cloud centroid, then 64 directions evenly
   spread over the sphere sorted by their angle to the preferred one. Along each direction, distances
   from ``fit`` (the cluster fits in a ``fill`` fraction of the field of view) out to ``max_distance``
   and then back in to ``min_distance``; the first position that is (a) inside the cloud's bounding
   box shrunk by the clearance, (b) in free space: no point within ``clearance`` (default 3
   median spacings, at least 5 cm) and (c) has an unblocked line of sight to the cluster centre: no
   point within ``1.5`` median spacings of the segment, except the last ``clearance + cluster
   radius`` before the centre (the cluster's own surface) is chosen. A cluster with no such position
   is skipped, so fewer than ``n_views`` views may come back.

Over-exposed means CIE Y of the linear LDR colour above the threshold
(:func:`probeless.hdr.transfer.overexposed`): float colours are taken as linear 0..1, uint8 colours as
sRGB codes and decoded first.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from probeless.color import from_srgb8
from probeless.errors import HdrError
from probeless.hdr.splat import check_cloud, pinhole_size, point_spacing
from probeless.hdr.transfer import overexposed


@dataclasses.dataclass(frozen=True, eq=False)
class SaturatedCluster:
    """One connected group of over-exposed points: ``indices`` (rows in the cloud), ``centre`` (3,) mean
    position [m], ``radius`` [m] (largest distance of a member from the centre), ``normal`` (3,) unit
    mean normal (None without normals, or when the normals cancel out)."""

    indices: np.ndarray
    centre: np.ndarray
    radius: float
    normal: np.ndarray | None

    @property
    def size(self) -> int:
        """Number of points."""
        return len(self.indices)


def linear_colors(ldr_colors: np.ndarray) -> np.ndarray:
    """(N, 3) float32 linear LDR colours: uint8 sRGB codes are decoded, floats are taken as linear 0..1."""
    c = np.asarray(ldr_colors)
    return from_srgb8(c) if c.dtype == np.uint8 else c.astype(np.float32)


def median_spacing(points: np.ndarray, sample: int = 20000, seed: int = 0) -> float:
    """Median of :func:`~probeless.hdr.splat.point_spacing` over at most ``sample`` points (their neighbours
    found in the whole cloud)."""
    p = np.asarray(points, np.float64)
    if len(p) < 2:
        return 1e-3
    idx = np.random.default_rng(seed).choice(len(p), min(sample, len(p)), replace=False)
    d, _ = cKDTree(p).query(p[idx], k=min(9, len(p)), workers=-1)
    s = d[:, 1:].mean(axis=1)
    s = s[s > 0]
    return float(np.median(s)) if len(s) else 1e-3


def saturated_clusters(points: np.ndarray, ldr_colors: np.ndarray, threshold: float = 0.9,
                       voxel: float | None = None, normals: np.ndarray | None = None,
                       min_points: int = 10) -> list[SaturatedCluster]:
    """Clusters of over-exposed points (luminance > ``threshold``), largest first.

    ``voxel`` [m]: the grid the clusters are connected on (default 3 median point spacings, so gaps
    of about two spacings still join); ``normals`` (N, 3) optional; clusters of fewer than
    ``min_points`` points are dropped.
    """
    p, c, _ = check_cloud(points, ldr_colors, None, "saturated_clusters")
    if normals is not None:
        n = np.asarray(normals, np.float64)
        if n.shape != p.shape or not np.isfinite(n).all():
            raise HdrError(f"saturated_clusters: normals must be finite (N, 3) like points {p.shape}, got {n.shape}")
    if not np.isfinite(threshold):
        raise HdrError(f"saturated_clusters: threshold must be finite, got {threshold!r}")
    sat = np.flatnonzero(overexposed(linear_colors(ldr_colors), threshold))
    if len(sat) == 0:
        return []
    if voxel is None:
        voxel = 3.0 * median_spacing(p)
    if not (np.isfinite(voxel) and voxel > 0):
        raise HdrError(f"saturated_clusters: voxel must be > 0, got {voxel!r}")
    q = p[sat].astype(np.float64)
    keys = np.floor(q / voxel).astype(np.int64)
    cells, inv = np.unique(keys, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    pairs = cKDTree(cells.astype(np.float64)).query_pairs(r=np.sqrt(3.0) + 1e-6, output_type="ndarray")
    m = len(cells)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(m, m)) if len(pairs) else \
        coo_matrix((m, m))
    _, cell_label = connected_components(graph, directed=False)
    label = cell_label[inv]
    out = []
    for lab in np.unique(label):
        members = sat[label == lab]
        if len(members) < min_points:
            continue
        pts = p[members].astype(np.float64)
        centre = pts.mean(axis=0)
        normal = None
        if normals is not None:
            nm = np.asarray(normals, np.float64)[members]
            # unoriented normals: align each with the first principal one before averaging
            ref = nm[0]
            nm = nm * np.where(nm @ ref < 0, -1.0, 1.0)[:, None]
            mean = nm.mean(axis=0)
            if np.linalg.norm(mean) > 1e-6:
                normal = mean / np.linalg.norm(mean)
        radius = float(np.max(np.linalg.norm(pts - centre, axis=1)))
        out.append(SaturatedCluster(members, centre, radius, normal))
    out.sort(key=lambda cl: -cl.size)
    return out


def camera_looking_at(position, target, fov_deg: float = 90.0, size=(1024, 1024),
                      up=(0.0, 0.0, 1.0)) -> tuple[np.ndarray, np.ndarray]:
    """(K (3, 3), world_from_camera (4, 4)) of an OpenCV pinhole at ``position`` looking at ``target``.

    ``fov_deg``: horizontal field of view; square pixels, principal point at the image centre (pixel
    centres at integers). The image's up is ``up`` (the world's z, :mod:`probeless.geom.cube`), or
    the world's y when looking along ``up``.
    """
    pos, tgt = np.asarray(position, np.float64), np.asarray(target, np.float64)
    if pos.shape != (3,) or tgt.shape != (3,) or not (np.isfinite(pos).all() and np.isfinite(tgt).all()):
        raise HdrError(f"camera_looking_at: position and target must be 3 finite numbers, got {position!r}, "
                       f"{target!r}")
    if not 0 < fov_deg < 180:
        raise HdrError(f"camera_looking_at: fov_deg must be in (0, 180), got {fov_deg!r}")
    w, h = pinhole_size(size)
    z = tgt - pos
    if np.linalg.norm(z) < 1e-9:
        raise HdrError("camera_looking_at: position and target coincide")
    z /= np.linalg.norm(z)
    u = np.asarray(up, np.float64)
    x = np.cross(z, u)
    if np.linalg.norm(x) < 1e-6:
        x = np.cross(z, np.array([0.0, 1.0, 0.0]))
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    pose = np.eye(4)
    pose[:3, :3] = np.stack([x, y, z], axis=1)
    pose[:3, 3] = pos
    f = (w / 2.0) / np.tan(np.radians(fov_deg) / 2.0)
    K = np.array([[f, 0.0, (w - 1) / 2.0], [0.0, f, (h - 1) / 2.0], [0.0, 0.0, 1.0]])
    return K, pose


def views_from_positions(positions, look_ats) -> list[tuple[np.ndarray, np.ndarray]]:
    """Explicit views: [(position (3,), look_at (3,))], validated (finite, distinct, as many of each)."""
    p = np.asarray(positions, np.float64).reshape(-1, 3) if np.size(positions) else np.zeros((0, 3))
    t = np.asarray(look_ats, np.float64).reshape(-1, 3) if np.size(look_ats) else np.zeros((0, 3))
    if len(p) != len(t) or np.shape(positions)[-1:] != (3,) or np.shape(look_ats)[-1:] != (3,):
        raise HdrError(f"views_from_positions: positions {np.shape(positions)} and look_ats {np.shape(look_ats)} "
                       f"must be (V, 3) each")
    if not (np.isfinite(p).all() and np.isfinite(t).all()):
        raise HdrError("views_from_positions: positions and look_ats must be finite")
    if (np.linalg.norm(p - t, axis=1) < 1e-9).any():
        raise HdrError("views_from_positions: a position coincides with its look_at")
    return [(p[i].copy(), t[i].copy()) for i in range(len(p))]


def sphere_directions(n: int = 64) -> np.ndarray:
    """(n, 3) unit directions evenly spread over the sphere (Fibonacci lattice)."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    r = np.sqrt(1.0 - z * z)
    phi = np.pi * (3.0 - np.sqrt(5.0)) * i
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def place_views(points: np.ndarray, ldr_colors: np.ndarray, n_views: int, *, normals: np.ndarray | None = None,
                threshold: float = 0.9, voxel: float | None = None, fov_deg: float = 90.0, fill: float = 0.5,
                clearance: float | None = None, min_distance: float = 0.3, max_distance: float | None = None,
                min_points: int = 10) -> list[tuple[np.ndarray, np.ndarray]]:
    """[(position (3,), look_at (3,))] of up to ``n_views`` cameras, one per over-exposed cluster, largest
    first (the rule in the module docstring). ``look_at`` is the cluster centre.

    ``fill``: fraction of the field of view the cluster's diameter should span; ``clearance`` [m]:
    free space around the camera; ``max_distance`` [m]: default the bounding box diagonal.
    """
    p, _, _ = check_cloud(points, ldr_colors, None, "place_views")
    if not isinstance(n_views, (int, np.integer)) or n_views < 1:
        raise HdrError(f"place_views: n_views must be an integer >= 1, got {n_views!r}")
    if not 0 < fov_deg < 180 or not 0 < fill <= 1:
        raise HdrError(f"place_views: need 0 < fov_deg < 180 and 0 < fill <= 1, got {fov_deg!r}, {fill!r}")
    clusters = saturated_clusters(p, ldr_colors, threshold, voxel, normals, min_points)
    if not clusters:
        return []
    q = p.astype(np.float64)
    tree = cKDTree(q)
    spacing = median_spacing(q)
    clear = max(3.0 * spacing, 0.05) if clearance is None else float(clearance)
    lo, hi = q.min(axis=0), q.max(axis=0)
    diag = float(np.linalg.norm(hi - lo))
    dmax = diag if max_distance is None else float(max_distance)
    centroid = q.mean(axis=0)
    tan_half = np.tan(np.radians(fov_deg) / 2.0)
    step = max(spacing, diag / 400.0)
    blocked_r = 1.5 * spacing

    def usable(pos: np.ndarray, target: np.ndarray, keep: float) -> bool:
        if ((pos < lo + clear) | (pos > hi - clear)).any():
            return False
        if tree.query(pos)[0] < clear:
            return False
        length = float(np.linalg.norm(target - pos))
        if length <= keep:
            return True
        t = np.arange(0.0, length - keep, step * 0.5)
        samples = pos + (target - pos)[None] * (t / length)[:, None]
        return bool((tree.query(samples, workers=-1)[0] >= blocked_r).all())

    out = []
    for cl in clusters[:n_views]:
        preferred = []
        if cl.normal is not None:
            nrm = cl.normal if cl.normal @ (centroid - cl.centre) >= 0 else -cl.normal
            preferred.append(nrm)
        to_c = centroid - cl.centre
        if np.linalg.norm(to_c) > 1e-9:
            preferred.append(to_c / np.linalg.norm(to_c))
        main = preferred[0] if preferred else np.array([0.0, 0.0, 1.0])
        others = sphere_directions(64)
        others = others[np.argsort(-(others @ main))]
        fit = max(min_distance, cl.radius / (fill * tan_half))
        dists = np.concatenate([np.arange(fit, dmax + 1e-9, step * 4), np.arange(fit, min_distance, -step * 4)[1:]])
        keep = clear + cl.radius
        chosen = None
        for d in [*preferred, *others]:
            for dist in dists:
                pos = cl.centre + d * dist
                if usable(pos, cl.centre, keep):
                    chosen = pos
                    break
            if chosen is not None:
                break
        if chosen is not None:
            out.append((chosen, cl.centre.copy()))
    return out


__all__ = ["SaturatedCluster", "camera_looking_at", "linear_colors", "median_spacing", "place_views",
           "point_spacing", "saturated_clusters", "sphere_directions", "views_from_positions"]
