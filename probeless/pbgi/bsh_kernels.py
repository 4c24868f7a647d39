"""numba kernels of :mod:`probeless.pbgi.bsh` (bounding sphere hierarchy, paper 001 §5.1).

Not a public API: the caller validates every argument. Conventions shared with the caller:

* points, colours, normals are C-contiguous float64 (N, 3); normals are unit length;
* a tree of ``L`` leaves has ``L - 1`` inner nodes (Karras 2012) and ``2L - 1`` nodes in one numbering: inner node
  ``i`` is ``i`` (the root is 0), leaf ``j`` (the j-th sorted Morton code) is ``L - 1 + j``; ``left``/``right``
  (length ``L - 1``) hold children in that numbering;
* a normal cone is a unit axis and a half-angle in [0, pi]; pi means "all directions";
* every kernel is deterministic: parallel loops write disjoint outputs and sums run in a fixed order.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import njit, prange

numba.config.THREADING_LAYER_PRIORITY = ["omp", "workqueue", "tbb"]

BITS = 21  # Morton bits per axis
_M21 = np.uint64((1 << 21) - 1)


@njit(cache=True)
def _spread(v):
    """The 21 low bits of v spread to every third bit (bit k -> bit 3k)."""
    v = v & np.uint64(0x1FFFFF)
    v = (v | (v << np.uint64(32))) & np.uint64(0x1F00000000FFFF)
    v = (v | (v << np.uint64(16))) & np.uint64(0x1F0000FF0000FF)
    v = (v | (v << np.uint64(8))) & np.uint64(0x100F00F00F00F00F)
    v = (v | (v << np.uint64(4))) & np.uint64(0x10C30C30C30C30C3)
    v = (v | (v << np.uint64(2))) & np.uint64(0x1249249249249249)
    return v


@njit(cache=True, parallel=True)
def morton_codes(pts, lo, voxel):
    """Code of each point's cell ``floor((p - lo) / voxel)`` (clamped to 21 bits): x bits at 3k+2, y 3k+1, z 3k."""
    n = pts.shape[0]
    out = np.empty(n, np.uint64)
    top = float((1 << 21) - 1)
    for i in prange(n):
        c0 = min(max(math.floor((pts[i, 0] - lo[0]) / voxel), 0.0), top)
        c1 = min(max(math.floor((pts[i, 1] - lo[1]) / voxel), 0.0), top)
        c2 = min(max(math.floor((pts[i, 2] - lo[2]) / voxel), 0.0), top)
        out[i] = ((_spread(np.uint64(c0)) << np.uint64(2)) | (_spread(np.uint64(c1)) << np.uint64(1))
                  | _spread(np.uint64(c2)))
    return out


@njit(cache=True)
def _min_cone(nrm, perm, a, b):
    """Minimal cone of the unit vectors nrm[perm[a:b]]: its axis is the point of their convex hull nearest the
    origin (Gilbert's algorithm); the half-angle is then measured exactly, so the cone always contains them."""
    k0 = perm[a]
    x0, x1, x2 = nrm[k0, 0], nrm[k0, 1], nrm[k0, 2]
    for _ in range(64):
        best = 1e300
        s = k0
        for t in range(a, b):
            k = perm[t]
            d = nrm[k, 0] * x0 + nrm[k, 1] * x1 + nrm[k, 2] * x2
            if d < best:
                best = d
                s = k
        xx = x0 * x0 + x1 * x1 + x2 * x2
        gap = xx - best
        if gap <= 1e-14 * max(xx, 1e-300):
            break
        d0, d1, d2 = x0 - nrm[s, 0], x1 - nrm[s, 1], x2 - nrm[s, 2]
        dd = d0 * d0 + d1 * d1 + d2 * d2
        if dd <= 0.0:
            break
        t = min(gap / dd, 1.0)
        x0 -= t * d0
        x1 -= t * d1
        x2 -= t * d2
    nx = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
    if nx < 1e-9:  # the origin is in the hull: no cone narrower than a half-space
        return nrm[k0, 0], nrm[k0, 1], nrm[k0, 2], math.pi
    x0 /= nx
    x1 /= nx
    x2 /= nx
    mn = 1.0
    for t in range(a, b):
        k = perm[t]
        mn = min(mn, nrm[k, 0] * x0 + nrm[k, 1] * x1 + nrm[k, 2] * x2)
    return x0, x1, x2, math.acos(max(-1.0, min(1.0, mn)))


@njit(cache=True, parallel=True)
def make_leaves(pts, col, nrm, perm, starts, count, pos, rad, cmean, cm2, nmean, axis, angle):
    """Leaf j averages the points perm[starts[j]:starts[j+1]] into the given row-j outputs: count, mean position
    (also the sphere centre), radius (farthest point), colour mean and per-channel sum of squared deviations,
    mean normal (not renormalised: the caller does it at the end), minimal normal cone."""
    nl = starts.shape[0] - 1
    for j in prange(nl):
        a = starts[j]
        b = starts[j + 1]
        m = b - a
        p0 = p1 = p2 = q0 = q1 = q2 = n0 = n1 = n2 = 0.0
        for t in range(a, b):
            k = perm[t]
            p0 += pts[k, 0]
            p1 += pts[k, 1]
            p2 += pts[k, 2]
            q0 += col[k, 0]
            q1 += col[k, 1]
            q2 += col[k, 2]
            n0 += nrm[k, 0]
            n1 += nrm[k, 1]
            n2 += nrm[k, 2]
        pos[j, 0] = p0 / m
        pos[j, 1] = p1 / m
        pos[j, 2] = p2 / m
        cmean[j, 0] = q0 / m
        cmean[j, 1] = q1 / m
        cmean[j, 2] = q2 / m
        r2 = 0.0
        v0 = 0.0
        v1 = 0.0
        v2 = 0.0
        for t in range(a, b):
            k = perm[t]
            d0, d1, d2 = pts[k, 0] - pos[j, 0], pts[k, 1] - pos[j, 1], pts[k, 2] - pos[j, 2]
            r2 = max(r2, d0 * d0 + d1 * d1 + d2 * d2)
            e0, e1, e2 = col[k, 0] - cmean[j, 0], col[k, 1] - cmean[j, 1], col[k, 2] - cmean[j, 2]
            v0 += e0 * e0
            v1 += e1 * e1
            v2 += e2 * e2
        count[j] = m
        rad[j] = math.sqrt(r2)
        cm2[j, 0] = v0
        cm2[j, 1] = v1
        cm2[j, 2] = v2
        a0, a1, a2, ang = _min_cone(nrm, perm, a, b)
        axis[j, 0] = a0
        axis[j, 1] = a1
        axis[j, 2] = a2
        angle[j] = ang
        nmean[j, 0] = n0 / m
        nmean[j, 1] = n1 / m
        nmean[j, 2] = n2 / m


@njit(cache=True)
def _clz(x):
    if x == 0:
        return 64
    n = 0
    for sh in (32, 16, 8, 4, 2, 1):
        if (x >> np.uint64(64 - sh)) == 0:
            n += sh
            x = x << np.uint64(sh)
    return n


@njit(cache=True)
def _delta(codes, i, j):
    if j < 0 or j >= codes.shape[0]:
        return -1
    return _clz(codes[i] ^ codes[j])


@njit(cache=True, parallel=True)
def karras(codes):
    """Radix tree over sorted unique codes (Karras 2012, Fig. 4): (left, right, parent) in the one numbering."""
    n = codes.shape[0]
    left = np.empty(n - 1, np.int64)
    right = np.empty(n - 1, np.int64)
    parent = np.full(2 * n - 1, -1, np.int64)
    for i in prange(n - 1):
        d = 1 if _delta(codes, i, i + 1) > _delta(codes, i, i - 1) else -1
        dmin = _delta(codes, i, i - d)
        lmax = 2
        while _delta(codes, i, i + lmax * d) > dmin:
            lmax *= 2
        l = 0
        t = lmax // 2
        while t >= 1:
            if _delta(codes, i, i + (l + t) * d) > dmin:
                l += t
            t //= 2
        j = i + l * d
        dnode = _delta(codes, i, j)
        s = 0
        div = 2
        while True:
            t = (l + div - 1) // div
            if _delta(codes, i, i + (s + t) * d) > dnode:
                s += t
            if t <= 1:
                break
            div *= 2
        g = i + s * d + min(d, 0)
        lc = g + n - 1 if min(i, j) == g else g
        rc = g + n if max(i, j) == g + 1 else g + 1
        left[i] = lc
        right[i] = rc
        parent[lc] = i
        parent[rc] = i
    return left, right, parent


@njit(cache=True)
def preorder(left, right, nl):
    """Node ids in depth-first pre-order (left before right) of the full tree."""
    m = 2 * nl - 1
    out = np.empty(m, np.int64)
    stack = np.empty(m + 1, np.int64)
    sp = 0
    stack[0] = 0
    sp = 1
    k = 0
    while sp > 0:
        sp -= 1
        v = stack[sp]
        out[k] = v
        k += 1
        if v < nl - 1:
            stack[sp] = right[v]
            stack[sp + 1] = left[v]
            sp += 2
    return out


@njit(cache=True)
def _merge_cone(a, b, ax, ang, out):
    """Minimal cone enclosing the cones a and b, into node ``out``."""
    ta = ang[a]
    tb = ang[b]
    c = ax[a, 0] * ax[b, 0] + ax[a, 1] * ax[b, 1] + ax[a, 2] * ax[b, 2]
    c = max(-1.0, min(1.0, c))
    phi = math.acos(c)
    if ta >= math.pi or tb >= math.pi:
        src, th = a, math.pi
    elif ta >= phi + tb:
        src, th = a, ta
    elif tb >= phi + ta:
        src, th = b, tb
    else:
        th = 0.5 * (phi + ta + tb)
        if th >= math.pi:
            src, th = a, math.pi
        else:
            w0 = ax[b, 0] - c * ax[a, 0]
            w1 = ax[b, 1] - c * ax[a, 1]
            w2 = ax[b, 2] - c * ax[a, 2]
            nw = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
            if nw < 1e-12:  # opposite or equal axes: any direction perpendicular to a
                if abs(ax[a, 0]) < 0.9:
                    w0, w1, w2 = 0.0, ax[a, 2], -ax[a, 1]
                else:
                    w0, w1, w2 = -ax[a, 2], 0.0, ax[a, 0]
                nw = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
            rot = th - ta
            cr = math.cos(rot)
            sr = math.sin(rot) / nw
            x0 = ax[a, 0] * cr + w0 * sr
            x1 = ax[a, 1] * cr + w1 * sr
            x2 = ax[a, 2] * cr + w2 * sr
            nx = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
            ax[out, 0] = x0 / nx
            ax[out, 1] = x1 / nx
            ax[out, 2] = x2 / nx
            ang[out] = min(th + 1e-12, math.pi)
            return
    ax[out, 0] = ax[src, 0]
    ax[out, 1] = ax[src, 1]
    ax[out, 2] = ax[src, 2]
    ang[out] = th


@njit(cache=True)
def propagate(left, right, order, count, pos, cen, rad, cmean, cm2, nmean, ax, ang):
    """Fill the inner nodes (rows 0..L-2 of every array) from their children, children first (reversed pre-order):
    count-weighted means of position, colour and normal, pooled colour deviations (Chan et al.),
    minimal sphere enclosing both child spheres, minimal cone enclosing both child cones."""
    nin = left.shape[0]
    for q in range(order.shape[0] - 1, -1, -1):
        v = order[q]
        if v >= nin:
            continue
        a = left[v]
        b = right[v]
        na = count[a]
        nb = count[b]
        n = na + nb
        count[v] = n
        wa = na / n
        wb = nb / n
        for c in range(3):
            pos[v, c] = wa * pos[a, c] + wb * pos[b, c]
            dc = cmean[b, c] - cmean[a, c]
            cmean[v, c] = cmean[a, c] + dc * wb
            cm2[v, c] = cm2[a, c] + cm2[b, c] + dc * dc * na * wb
            nmean[v, c] = wa * nmean[a, c] + wb * nmean[b, c]
        # sphere
        d0, d1, d2 = cen[b, 0] - cen[a, 0], cen[b, 1] - cen[a, 1], cen[b, 2] - cen[a, 2]
        d = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        if rad[a] >= d + rad[b]:
            src = a
        elif rad[b] >= d + rad[a]:
            src = b
        else:
            src = -1
            r = 0.5 * (d + rad[a] + rad[b])
            f = (r - rad[a]) / d
            cen[v, 0] = cen[a, 0] + f * d0
            cen[v, 1] = cen[a, 1] + f * d1
            cen[v, 2] = cen[a, 2] + f * d2
            rad[v] = r * (1.0 + 1e-12)
        if src >= 0:
            for c in range(3):
                cen[v, c] = cen[src, c]
            rad[v] = rad[src]
        _merge_cone(a, b, ax, ang, v)


@njit(cache=True)
def linearise(left, right, order, cluster):
    """Depth-first layout of the tree pruned at the ``cluster`` nodes (their sub-trees dropped): for each linear slot
    the node id, the skip index (slot after its sub-tree) and the slot of its right child (-1 for a leaf; the left
    child is the next slot)."""
    nin = left.shape[0]
    m = order.shape[0]
    size = np.ones(m, np.int64)
    for q in range(m - 1, -1, -1):
        v = order[q]
        if v < nin and not cluster[v]:
            size[v] = 1 + size[left[v]] + size[right[v]]
    total = size[0]
    ids = np.empty(total, np.int64)
    skip = np.empty(total, np.int64)
    rlin = np.empty(total, np.int64)
    stack = np.empty(130, np.int64)  # depth <= 64 for unique 63-bit codes
    stack[0] = 0
    sp = 1
    k = 0
    while sp > 0:
        sp -= 1
        v = stack[sp]
        ids[k] = v
        skip[k] = k + size[v]
        if v < nin and not cluster[v]:
            rlin[k] = k + 1 + size[left[v]]
            stack[sp] = right[v]
            stack[sp + 1] = left[v]
            sp += 2
        else:
            rlin[k] = -1
        k += 1
    return ids, skip, rlin
