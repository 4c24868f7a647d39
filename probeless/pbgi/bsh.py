"""Bounding sphere hierarchy (BSH) of a coloured point cloud for point-based GI (paper 001, §5.1 and §5.4).

:func:`build_bsh` runs the paper's stages, each timed in :class:`BshReport` (its Table 1):

* **input** -- validation (float64 copies, normals made unit) and the default voxel size;
* **morton** -- the cloud's bounding cube (min corner, side = largest extent) is cut into voxels of side ``voxel``
  (default: the point spacing, see :func:`point_spacing`; at most 2^21 per axis) and every point gets the 64-bit
  Morton code of its cell (21 bits per axis, x bits at 3k+2, y at 3k+1, z at 3k);
* **sort**, **leaves** -- the codes are sorted and each non-empty cell becomes one leaf: mean position (the sphere
  centre; radius: its farthest point), mean colour, mean normal renormalised, and the minimal cone of its normals;
* **karras** -- inner nodes by Karras (2012): L leaves give L - 1 inner nodes, built in parallel;
* **propagate** -- bottom-up: count-weighted colour mean, the minimal sphere enclosing both child spheres (so a parent
  contains its children and every point under it), the minimal cone enclosing both child cones (half-angle pi:
  all directions);
* **prune** -- a node whose *colour variation* is below ``tc`` and whose *normal agreement* is above ``tn`` becomes a
  leaf (a cluster) and its sub-tree is dropped. The paper measures colour variation as the average distance of the
  points' colours from the node colour; here it is the root-mean-square distance (sqrt of the summed per-channel
  population variances: it propagates bottom-up exactly, and bounds the average distance from above, so this prunes
  no more than the paper's rule). A variance (squared units) would prune far more: a cluster with 2 % saturated red
  points in a grey wall has variance ~0.004 < 0.01 but RMS distance ~0.09. Normal agreement: cos of the normal
  cone's half-angle (the paper: the average dot product, which is never smaller). Not in the paper: a cluster's
  bounding radius must also be at most ``max_radius`` -- a uniform wall would otherwise collapse into one sphere
  metres wide that a receiver 30 cm away sits inside and cannot refine (at 32² micro-buffers a node is splatted
  whole once it subtends 4 texels: 2.6 cm at 30 cm, hence the default 3 cm);
* **linearise** -- the pruned tree in depth-first order as :data:`NODE_DTYPE` records (the paper's 40-byte node).

Node numbering of the full binary tree (:class:`Bsh` arrays of length ``2L - 1``): inner node ``i`` is ``i`` (root
0), leaf ``j`` (the j-th sorted code) is ``L - 1 + j``. ``left``/``right`` (length ``L - 1``) give the children.

GPU layout (:data:`NODE_DTYPE`, 40 bytes, 10 little-endian 32-bit words): sphere centre (3 f32), radius (f32,
rounded up so the f32 sphere still contains the f64 one), mean colour (3 f32: HDR values need floats), normal cone
(u32: octahedral axis 12 + 12 bits, half-angle 8 bits in units of pi/255 rounded up and widened by the axis's
quantisation error, so the packed cone stays conservative; see :func:`unpack_cone`), ``skip`` (u32: slot after the
node's sub-tree) and ``right`` (u32: right child slot, 0xFFFFFFFF for a leaf; the left child is the next slot). The
paper stores two child indices; here the left one is implicit, which frees a word for ``skip``, so a shader can walk
a cut without a stack -- ``i = 0; while i < n: if node i is inner and refine(i): i += 1 else: use(i); i = skip[i]``
-- while ``right`` keeps the paper's pair-based (geometry shader) refinement possible. Declare it in GLSL as ten
scalar members (``float cx, cy, cz, r, red, green, blue; uint cone, skip, right;``): a ``vec3`` member would make
std430 pad the stride to 48 bytes.
"""

from __future__ import annotations

import math
import numbers
import time
from dataclasses import dataclass, field

import numpy as np

from probeless.errors import PbgiError
from probeless.pbgi import bsh_kernels as _k

NODE_DTYPE = np.dtype([("center", "<f4", (3,)), ("radius", "<f4"), ("color", "<f4", (3,)),
                       ("cone", "<u4"), ("skip", "<u4"), ("right", "<u4")])
NO_CHILD = 0xFFFFFFFF
MAX_CLUSTER_RADIUS = 0.03  # [m] largest pruned cluster (see the module docstring)
STAGES = ("input", "morton", "sort", "leaves", "karras", "propagate", "prune", "linearise")


@dataclass
class BshReport:
    """Counts and per-stage seconds of one build (``times`` keyed by :data:`STAGES`)."""
    n_points: int
    n_leaves: int  # non-empty voxels
    n_nodes: int  # before clustering: 2 n_leaves - 1
    n_nodes_pruned: int  # after clustering: records in Bsh.nodes
    n_clusters: int  # leaves of the pruned tree
    voxel: float
    times: dict = field(default_factory=dict)
    spacing: float = 0.0  # the cloud's point spacing [m] (point_spacing) when the voxel was derived from it

    @property
    def total(self) -> float:
        return float(sum(self.times.values()))


@dataclass
class Bsh:
    """The hierarchy: GPU records ``nodes`` plus the full binary tree's per-node arrays (float64)."""
    nodes: np.ndarray  # NODE_DTYPE, pruned, depth-first
    ids: np.ndarray  # tree node id of each record
    codes: np.ndarray  # sorted unique leaf codes (L,)
    left: np.ndarray
    right: np.ndarray
    parent: np.ndarray  # (2L - 1,), -1 at the root
    count: np.ndarray  # points under each node
    position: np.ndarray  # mean point position
    center: np.ndarray
    radius: np.ndarray
    color: np.ndarray  # mean colour
    color_dev: np.ndarray  # RMS distance of the points' colours from the node colour (colour units)
    normal: np.ndarray  # mean normal, renormalised
    axis: np.ndarray  # normal cone
    angle: np.ndarray
    cluster: np.ndarray  # inner nodes turned into leaves by the pruning (L - 1,)
    point_leaf: np.ndarray  # node id of each input point's leaf
    report: BshReport


def _err(msg: str) -> PbgiError:
    return PbgiError(f"build_bsh: {msg}")


def _check_cloud(points, colors, normals) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    out = []
    for name, a in (("points", points), ("colors", colors), ("normals", normals)):
        a = np.asarray(a)
        if a.ndim != 2 or a.shape[1] != 3:
            raise _err(f"'{name}' must have shape (N, 3), got {a.shape}")
        if a.shape[0] == 0:
            raise _err(f"'{name}' is empty (the cloud needs at least one point)")
        if out and a.shape[0] != out[0].shape[0]:
            raise _err(f"'{name}' has {a.shape[0]} rows but 'points' has {out[0].shape[0]}")
        if not np.issubdtype(a.dtype, np.number):
            raise _err(f"'{name}' must be numeric, got {a.dtype}")
        a = np.ascontiguousarray(a, dtype=np.float64)
        if not np.isfinite(a).all():
            raise _err(f"'{name}' has NaN or infinite values (first at row {int(np.argmin(np.isfinite(a).all(1)))})")
        out.append(a)
    nrm = out[2]
    ln = np.sqrt(np.einsum("ij,ij->i", nrm, nrm))
    if (ln < 1e-12).any():
        raise _err(f"'normals' has zero-length vectors (first at row {int(np.argmax(ln < 1e-12))})")
    out[2] = nrm / ln[:, None]
    return out[0], out[1], out[2]


SPACING_NEIGHBOURS = 16
# Default voxel = 0.45 x the point spacing, so every point of a grid or a scan has a leaf of its own (the paper's one
# point per leaf). Not 1 or 1/2: a regular grid's points then lie on voxel faces, rounding merges neighbours and
# leaves holes (decals room, GGX 0.1 error vs Mitsuba: 0.33 at 1 and at 1/2, 0.16 at 0.45; `probeless eval pbgi`).
VOXEL_PER_SPACING = 0.45


def point_spacing(points: np.ndarray, sample: int = 50_000, seed: int = 0, k: int = SPACING_NEIGHBOURS) -> float:
    """Typical distance between neighbouring points of a surface cloud [m]: the side of the square each point stands
    for, sqrt(area per point). For each of at most ``sample`` random points, the disk out to its ``k``-th nearest
    other point (a k-d tree of the whole cloud) holds k points, so area per point = pi r_k^2 / k; the median over
    the sample is returned. Regular grids, jittered grids and random points all come within ~3 % (the nearest
    neighbour alone reads a jittered grid 35 % and random points 50 % short; a tree of the sample alone, scaled
    back, read a 1 cm grid as 4-5 mm). 0.0 for fewer than two points."""
    from scipy.spatial import cKDTree

    p = np.asarray(points, np.float64)
    n = p.shape[0]
    if n < 2:
        return 0.0
    k = min(int(k), n - 1)
    sub = p if n <= sample else p[np.random.default_rng(seed).choice(n, sample, replace=False)]
    d, _ = cKDTree(p, balanced_tree=False, compact_nodes=False).query(sub, k=k + 1)
    return float(np.median(d[:, k]) * math.sqrt(math.pi / k))


def pack_cone(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Cones (unit axes (M, 3), half-angles (M,)) as u32: octahedral x (bits 0-11), y (12-23), angle (24-31);
    the packed cone contains the given one."""
    a = np.asarray(axis, np.float64)
    p = a[:, :2] / np.abs(a).sum(1, keepdims=True)
    neg = a[:, 2] < 0
    sx = np.where(p[:, 0] >= 0, 1.0, -1.0)
    sy = np.where(p[:, 1] >= 0, 1.0, -1.0)
    fold = np.stack([(1 - np.abs(p[:, 1])) * sx, (1 - np.abs(p[:, 0])) * sy], 1)
    p = np.where(neg[:, None], fold, p)
    q = np.clip(np.rint((p + 1) * 0.5 * 4095), 0, 4095).astype(np.uint32)
    dec = _decode_oct(q[:, 0], q[:, 1])
    err = np.arccos(np.clip((dec * a).sum(1), -1, 1)) + 1e-6
    qa = np.clip(np.ceil(np.minimum(np.asarray(angle) + err, math.pi) / math.pi * 255), 0, 255).astype(np.uint32)
    return q[:, 0] | (q[:, 1] << 12) | (qa << 24)


def _decode_oct(qx, qy) -> np.ndarray:
    x = qx / 4095 * 2 - 1
    y = qy / 4095 * 2 - 1
    z = 1 - np.abs(x) - np.abs(y)
    neg = z < 0
    fx = (1 - np.abs(y)) * np.where(x >= 0, 1.0, -1.0)
    fy = (1 - np.abs(x)) * np.where(y >= 0, 1.0, -1.0)
    v = np.stack([np.where(neg, fx, x), np.where(neg, fy, y), z], 1)
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def unpack_cone(cone: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(unit axes (M, 3), half-angles (M,)) of packed cones (:func:`pack_cone`)."""
    c = np.asarray(cone, np.uint32).reshape(-1)
    return _decode_oct(c & 0xFFF, (c >> 12) & 0xFFF), ((c >> 24) & 0xFF) * (math.pi / 255)


def build_bsh(points, colors, normals, *, voxel: float | None = None, tc: float = 0.01, tn: float = 0.98,
              max_radius: float = MAX_CLUSTER_RADIUS) -> Bsh:
    """The BSH of a cloud ((N, 3) points, colours, normals; normals need not be unit). See the module docstring."""
    t = {s: 0.0 for s in STAGES}
    t0 = time.perf_counter()
    pts, col, nrm = _check_cloud(points, colors, normals)
    for name, v in (("tc", tc), ("tn", tn)):
        if not (isinstance(v, numbers.Real) and math.isfinite(v)):
            raise _err(f"'{name}' must be a finite number, got {v!r}")
    if not (isinstance(max_radius, numbers.Real) and max_radius >= 0):  # inf: no cap (the paper's rule alone)
        raise _err(f"'max_radius' must be a number >= 0 (inf: no cap), got {max_radius!r}")
    lo = pts.min(0)
    side = float((pts.max(0) - lo).max())
    vmin = side / ((1 << _k.BITS) - 1)  # the smallest voxel whose cells fit 21 bits
    spacing = 0.0
    if voxel is None:
        spacing = point_spacing(pts)
        voxel = max(VOXEL_PER_SPACING * spacing, vmin, 1e-12)
    elif not (isinstance(voxel, numbers.Real) and math.isfinite(voxel) and voxel > 0):
        raise _err(f"'voxel' must be a positive finite number, got {voxel!r}")
    elif voxel < vmin:
        raise _err(f"'voxel' {voxel!r} is too small: 2^21 cells of it do not span the cloud's extent {side!r} "
                   f"(use at least {vmin!r})")
    t1 = time.perf_counter()
    t["input"] = t1 - t0
    codes = _k.morton_codes(pts, lo, float(voxel))
    t2 = time.perf_counter()
    perm = np.argsort(codes)
    scodes = codes[perm]
    t3 = time.perf_counter()
    first = np.empty(scodes.shape[0], bool)
    first[0] = True
    np.not_equal(scodes[1:], scodes[:-1], out=first[1:])
    starts = np.append(np.flatnonzero(first), scodes.shape[0]).astype(np.int64)
    nl = starts.shape[0] - 1
    m = 2 * nl - 1
    count = np.empty(m, np.int64)
    pos, cen, cmean, cm2, nmean, ax = (np.empty((m, 3)) for _ in range(6))
    rad, ang = np.empty(m), np.empty(m)
    o = nl - 1  # leaves are rows o..m-1
    _k.make_leaves(pts, col, nrm, perm, starts, count[o:], pos[o:], rad[o:], cmean[o:], cm2[o:], nmean[o:], ax[o:],
                   ang[o:])
    cen[o:] = pos[o:]
    ucodes = scodes[starts[:-1]]
    point_leaf = np.empty(pts.shape[0], np.int64)
    point_leaf[perm] = np.repeat(np.arange(o, m), np.diff(starts))
    t4 = time.perf_counter()
    left, right, parent = _k.karras(ucodes)
    t5 = time.perf_counter()
    order = _k.preorder(left, right, nl)
    _k.propagate(left, right, order, count, pos, cen, rad, cmean, cm2, nmean, ax, ang)
    ln = np.linalg.norm(nmean, axis=1, keepdims=True)
    nmean = np.where(ln > 1e-12, nmean / np.maximum(ln, 1e-300), ax)
    t6 = time.perf_counter()
    cvar = np.sqrt(cm2.sum(1) / count)
    cluster = (cvar[:o] < tc) & (np.cos(ang[:o]) > tn) & (rad[:o] <= max_radius)
    t7 = time.perf_counter()
    ids, skip, rlin = _k.linearise(left, right, order, cluster)
    nodes = np.empty(ids.shape[0], NODE_DTYPE)
    c32 = cen[ids].astype(np.float32)
    slack = np.linalg.norm(cen[ids] - c32, axis=1)
    nodes["center"] = c32
    nodes["radius"] = np.nextafter((rad[ids] + slack).astype(np.float32), np.float32(np.inf))
    nodes["color"] = cmean[ids]
    nodes["cone"] = pack_cone(ax[ids], ang[ids])
    nodes["skip"] = skip
    nodes["right"] = np.where(rlin < 0, NO_CHILD, rlin)
    t8 = time.perf_counter()
    t.update(morton=t2 - t1, sort=t3 - t2, leaves=t4 - t3, karras=t5 - t4, propagate=t6 - t5, prune=t7 - t6,
             linearise=t8 - t7)
    rep = BshReport(n_points=pts.shape[0], n_leaves=nl, n_nodes=m, n_nodes_pruned=int(ids.shape[0]),
                    n_clusters=int((rlin < 0).sum()), voxel=float(voxel), times=t, spacing=float(spacing))
    return Bsh(nodes=nodes, ids=ids, codes=ucodes, left=left, right=right, parent=parent, count=count, position=pos,
               center=cen, radius=rad, color=cmean, color_dev=cvar, normal=nmean, axis=ax, angle=ang,
               cluster=cluster, point_leaf=point_leaf, report=rep)


def traverse(nodes: np.ndarray, refine) -> tuple[np.ndarray, np.ndarray]:
    """Stack-less walk of linearised ``nodes`` (reference for the shaders): ``refine(i, node) -> bool`` is asked of
    every visited inner node. Returns (visited slots in visiting order, the cut: the slots used, not refined)."""
    visited, used = [], []
    i, n = 0, nodes.shape[0]
    while i < n:
        visited.append(i)
        node = nodes[i]
        if int(node["right"]) != NO_CHILD and refine(i, node):
            i += 1
        else:
            used.append(i)
            i = int(node["skip"])
    return np.asarray(visited, np.int64), np.asarray(used, np.int64)


def cut(tree: Bsh, predicate) -> np.ndarray:
    """Slots of the cut of ``tree.nodes`` where ``predicate(i, node)`` (refine?) first says no, or leaves."""
    return traverse(tree.nodes, predicate)[1]


def synthetic_room(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A room-like cloud: n points on the six inner faces of a 6 x 4 x 3 m box (2 mm noise), with inward normals
    (slightly perturbed) and per-face colours with a 0.5 m checker pattern on two walls and colour noise."""
    rng = np.random.default_rng(seed)
    size = np.array([6.0, 4.0, 3.0])
    area = np.array([size[1] * size[2], size[0] * size[2], size[0] * size[1]]).repeat(2)
    face = rng.choice(6, n, p=area / area.sum())
    ax_, hi = face // 2, face % 2
    pts = rng.random((n, 3)) * size
    pts[np.arange(n), ax_] = hi * size[ax_]
    pts += rng.normal(0, 0.002, (n, 3))
    nrm = np.zeros((n, 3))
    nrm[np.arange(n), ax_] = 1 - 2 * hi
    nrm += rng.normal(0, 0.02, (n, 3))
    base = np.array([[0.8, 0.7, 0.6], [0.6, 0.6, 0.65], [0.7, 0.5, 0.4], [0.5, 0.6, 0.5], [0.4, 0.3, 0.2],
                     [0.9, 0.9, 0.9]])
    col = base[face]
    checker = (np.floor(pts / 0.5).astype(np.int64).sum(1) % 2 == 0) & (face < 2)
    col[checker] *= 0.3
    col += rng.normal(0, 0.01, (n, 3))
    return pts, col, nrm


def time_build(n: int = 1_000_000, seed: int = 0, repeat: int = 3) -> BshReport:
    """Report of the fastest of ``repeat`` builds on :func:`synthetic_room` (n, seed), after a small warm-up build
    (numba compile excluded)."""
    build_bsh(*synthetic_room(2000, seed + 1))
    cloud = synthetic_room(n, seed)
    best = None
    for _ in range(repeat):
        rep = build_bsh(*cloud).report
        if best is None or rep.total < best.total:
            best = rep
    return best
