"""Poisson filling of the points left without a valid HDR colour (paper 001, §4.2, Eq. 2-3).

``Omega``: the points without a valid HDR colour; ``dOmega``: their valid neighbours; ``N_p``: the
``k`` nearest neighbours of ``p`` (k = 16 in the paper); ``H``, ``L``: HDR and LDR colours (linear,
the cloud's units). For every ``p`` in ``Omega``::

    |N_p| H(p) - sum_{q in N_p, Omega} H(q) = sum_{q in N_p, dOmega} H(q) + sum_{q in N_p} (L(p) - L(q))

i.e. the graph Laplacian of ``H`` equals that of ``L`` on ``Omega``, with the valid values as the
Dirichlet boundary. The kNN relation is not symmetric; by default we symmetrise it (``q in N_p`` if
either is among the other's k nearest), which makes the matrix symmetric and the notion of a
component unambiguous. ``symmetric=False`` keeps the paper's directed graph (row ``p`` uses the
``k`` nearest of ``p`` only). A point of ``Omega`` that cannot reach a valid point along edges
through ``Omega`` has no boundary value (its system is singular): it keeps its LDR colour and its
component is counted as unanchored.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph
from scipy.sparse.linalg import spsolve
from scipy.spatial import cKDTree

from probeless.errors import HdrError
from probeless.hdr.exposure import luminance

K = 16
"""Neighbours per point in the paper (§4.2)."""


def _array(a, what: str, shape1: int | None = 3) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64)
    if a.ndim != 2 or (shape1 is not None and a.shape[1] != shape1):
        raise HdrError(f"{what}: expected an (N, {shape1 or 'D'}) array, got shape {a.shape}")
    if not np.isfinite(a).all():
        raise HdrError(f"{what}: has NaN or infinite values")
    return a


def knn_graph(points: np.ndarray, k: int = K) -> np.ndarray:
    """(N, k') int64: the ``k' = min(k, N - 1)`` nearest other points of each of the (N, D) points.

    By ``scipy.spatial.cKDTree``, nearest first; a point is never its own neighbour, even where
    points coincide (then the ids among equal distances are in the tree's order).
    """
    pts = _array(points, "points", None)
    n = pts.shape[0]
    if n < 2:
        raise HdrError(f"knn_graph: need at least 2 points, got {n}")
    if k < 1:
        raise HdrError(f"knn_graph: k must be >= 1, got {k}")
    kk = min(int(k), n - 1)
    _, idx = cKDTree(pts).query(pts, k=kk + 1)
    idx = np.asarray(idx, dtype=np.int64).reshape(n, kk + 1)
    own = idx == np.arange(n)[:, None]
    drop = np.where(own.any(axis=1), own.argmax(axis=1), kk)  # self, or the farthest if self was pushed out
    keep = np.ones_like(idx, dtype=bool)
    keep[np.arange(n), drop] = False
    return idx[keep].reshape(n, kk)


def adjacency(neighbours: np.ndarray, symmetric: bool = True) -> sparse.csr_matrix:
    """(N, N) 0/1 CSR matrix, row ``p`` = ``N_p``: the kNN ids of :func:`knn_graph`, symmetrised or not."""
    n, k = neighbours.shape
    a = sparse.csr_matrix((np.ones(n * k), (np.repeat(np.arange(n), k), neighbours.ravel())), shape=(n, n))
    if symmetric:
        a = a.maximum(a.T)
    a.data[:] = 1.0
    return a.tocsr()


@dataclass(frozen=True)
class PoissonReport:
    """Counts of :func:`poisson_fill`: points solved for, points of ``Omega`` left with their LDR
    colour, connected components of ``Omega`` (on the undirected graph restricted to it), and those
    of them with a point left LDR; ``clipped_negative``: solved channel values below 0 set to 0."""

    filled: int
    left_ldr: int
    components: int
    unanchored_components: int
    clipped_negative: int

    def as_dict(self) -> dict:
        return asdict(self)


def _anchored(a: sparse.csr_matrix, omega: np.ndarray) -> np.ndarray:
    """bool (N,): points of ``omega`` that reach a non-``omega`` point along edges of ``a`` through ``omega``."""
    n = a.shape[0]
    rows = a.multiply(omega[:, None]).tocsr()  # edges p -> q with p in Omega
    seeds = omega & (rows @ (~omega).astype(np.float64) > 0)
    inner = rows.multiply(omega[None, :]).tocsr()  # p -> q both in Omega
    # reverse reachability from the seeds: a virtual node n with an edge to each seed in the transpose
    t = sparse.vstack([sparse.hstack([inner.T, sparse.csr_matrix((n, 1))]),
                       sparse.hstack([sparse.csr_matrix(seeds.astype(np.float64)[None]), sparse.csr_matrix((1, 1))])])
    order = csgraph.breadth_first_order(t.tocsr(), n, directed=True, return_predecessors=False)
    out = np.zeros(n + 1, dtype=bool)
    out[order] = True
    return out[:n] & omega


def poisson_fill(points: np.ndarray, hdr: np.ndarray, ldr: np.ndarray, valid: np.ndarray, k: int = K,
                 mode: str = "rgb", *, symmetric: bool = True):
    """Eq. 2-3 on the kNN graph: ``(filled (N, 3) float32, PoissonReport)``.

    ``points``: (N, 3) positions; ``hdr``, ``ldr``: (N, 3) linear colours in the cloud's units (``hdr``
    read on valid points only); ``valid``: (N,) bool, ``Omega = ~valid``. ``rgb`` solves one system
    per channel (one LU factorisation, ``spsolve`` with 3 right-hand sides); ``lum`` solves for the
    CIE Y of ``H`` from the Y of ``L`` and gives each point its LDR chromaticity at that Y (grey where
    the LDR colour is black). Valid points are returned unchanged; unanchored points of ``Omega`` keep
    their LDR colour. The solution of Eq. 2 can dip below 0 where the LDR gradient is steep: such
    values are clipped to 0 and counted.
    """
    pts = _array(points, "points")
    n = pts.shape[0]
    l_ = _array(ldr, "ldr")
    v = np.asarray(valid)
    if v.shape != (n,) or v.dtype != bool:
        raise HdrError(f"valid: expected a bool array of shape ({n},), got {v.dtype} {v.shape}")
    if l_.shape[0] != n:
        raise HdrError(f"ldr: {l_.shape[0]} points, points has {n}")
    h = np.asarray(hdr, dtype=np.float64)
    if h.shape != (n, 3):
        raise HdrError(f"hdr: expected shape ({n}, 3), got {h.shape}")
    if not np.isfinite(h[v]).all():
        raise HdrError("hdr: NaN or infinite values on valid points")
    if mode not in ("rgb", "lum"):
        raise HdrError(f"mode: expected 'rgb' or 'lum', got {mode!r}")
    out = np.where(v[:, None], h, l_)
    omega = ~v
    if not omega.any():
        return out.astype(np.float32), PoissonReport(0, 0, 0, 0, 0)

    a = adjacency(knn_graph(pts, k), symmetric)
    n_comp, labels = csgraph.connected_components(a[omega][:, omega], directed=False)
    unknown = _anchored(a, omega)
    comp_left = np.unique(labels[~unknown[omega]])

    if mode == "rgb":
        hv, lv = out, l_
    else:
        hv, lv = luminance(out)[:, None].astype(np.float64), luminance(l_)[:, None].astype(np.float64)
    au = a[unknown]  # rows of the unknowns
    deg = np.asarray(au.sum(axis=1)).ravel()
    known = ~unknown
    # RHS: values of the neighbours that are not unknowns (valid, or left LDR) + sum_q (L(p) - L(q))
    rhs = au[:, known] @ hv[known] + deg[:, None] * lv[unknown] - au @ lv
    m = (sparse.diags(deg) - au[:, unknown]).tocsc()
    sol = np.asarray(spsolve(m, rhs)).reshape(-1, hv.shape[1]) if unknown.any() else np.zeros((0, hv.shape[1]))
    neg = int((sol < 0).sum())
    sol = np.maximum(sol, 0.0)
    if mode == "rgb":
        out[unknown] = sol
    else:
        yl = luminance(l_[unknown]).astype(np.float64)
        ratio = np.divide(sol[:, 0], yl, out=np.zeros_like(yl), where=yl > 0)
        out[unknown] = np.where((yl > 0)[:, None], l_[unknown] * ratio[:, None], sol)
    report = PoissonReport(filled=int(unknown.sum()), left_ldr=int(omega.sum() - unknown.sum()),
                           components=int(n_comp), unanchored_components=int(comp_left.size),
                           clipped_negative=neg)
    return out.astype(np.float32), report
