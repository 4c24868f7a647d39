"""numba kernels of :mod:`probeless.hdr.patchmatch` (generalized PatchMatch, Barnes et al. 2010).

Not a public API: the callers validate every argument. Conventions shared with the caller:

* images are C-contiguous float32 (H, W, C); the *source* arrays passed here are edge-padded by the
  patch radius ``r`` (so source pixel (y, x) has its patch at ``Sp[y:y + p, x:x + p]``, which is the
  clamped patch of the unpadded image); the translation-only kernels take the target padded by ``r``
  too (raveled for :func:`iterate` / :func:`init_field`), the generalized ones the
  :func:`bilinear_table` of the unpadded target (bilinear taps clamp their coordinates); the
  PatchMatch kernels also take the unpadded target size (ht, wt);
* a field is four (H, W) arrays: target patch centre x, y (pixels, float32), angle (rad) and scale,
  plus the SSD (sum over the patch and the channels) in a fifth;
* a target offset ``(dx, dy)`` of the source patch maps to ``s * R(a) (dx, dy)`` around the centre,
  ``R(a) = [[cos a, -sin a], [sin a, cos a]]`` in pixel coordinates (x right, y down);
* randomness is a counter-based hash (splitmix64) of (seed, iteration, pixel), so a run gives the same
  field whatever the number of threads.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import njit, prange

# numba tries TBB first; the TBB a machine has may be too old (numba then warns and falls back):
# prefer OpenMP, then numba's own work queue, which are always usable for these row bands.
numba.config.THREADING_LAYER_PRIORITY = ["omp", "workqueue", "tbb"]

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MUL1 = np.uint64(0xBF58476D1CE4E5B9)
_MUL2 = np.uint64(0x94D049BB133111EB)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)
_S11 = np.uint64(11)
_INV53 = 1.0 / 9007199254740992.0


@njit(cache=True)
def _mix(z):
    z = (z ^ (z >> _S30)) * _MUL1
    z = (z ^ (z >> _S27)) * _MUL2
    return z ^ (z >> _S31)


@njit(cache=True)
def _seed(seed, counter):
    return _mix(np.uint64(seed) * _GOLDEN + _mix(np.uint64(counter) + _GOLDEN))


@njit(cache=True)
def _uniform(state):
    """(new state, uniform float in [0, 1))."""
    state = state + _GOLDEN
    return state, float(_mix(state) >> _S11) * _INV53


_FM = {"reassoc", "contract", "arcp", "nsz"}  # fastmath without nnan/ninf: costs are compared against inf


@njit(cache=True)
def _cost_int(sp, tp, sy, sx, ty, tx, p, best):
    """SSD of the source patch at (sy, sx) and the target patch at (ty, tx), both padded; stops once >= best."""
    nc = sp.shape[2]
    acc = 0.0
    for j in range(p):
        for i in range(p):
            for c in range(nc):
                d = sp[sy + j, sx + i, c] - tp[ty + j, tx + i, c]
                acc += d * d
        if acc >= best:
            return acc
    return acc


@njit(cache=True)
def _gather(sp, sy, sx, p, sb):
    """Copy the (padded) source patch at (sy, sx) into the flat buffer ``sb`` (p * p * nc)."""
    nc = sp.shape[2]
    k = 0
    for j in range(p):
        for i in range(p):
            for c in range(nc):
                sb[k] = sp[sy + j, sx + i, c]
                k += 1


@njit(cache=True, fastmath=_FM)
def _cost_flat(sb, tf, row, base, p, nc, best):
    """SSD of the gathered source patch ``sb`` and the padded target patch starting at flat index ``base``
    of ``tf`` (row stride ``row``); stops once >= best."""
    n = p * nc
    acc = 0.0
    for j in range(p):
        o = base + j * row
        q = j * n
        part = 0.0
        for k in range(n):
            d = sb[q + k] - tf[o + k]
            part += d * d
        acc += part
        if acc >= best:
            return acc
    return acc


@njit(cache=True)
def bilinear_table(t):
    """Per target pixel and channel the coefficients (a, b, c, d) of the bilinear patch to its right/lower
    neighbours (clamped at the border): ``v(fx, fy) = a + b fx + c fy + d fx fy``; flat, (ht * wt * nc * 4)."""
    ht, wt, nc = t.shape
    out = np.empty(ht * wt * nc * 4, np.float32)
    k = 0
    for y in range(ht):
        y1 = min(y + 1, ht - 1)
        for x in range(wt):
            x1 = min(x + 1, wt - 1)
            for c in range(nc):
                t00 = t[y, x, c]
                t01 = t[y, x1, c]
                t10 = t[y1, x, c]
                t11 = t[y1, x1, c]
                out[k] = t00
                out[k + 1] = t01 - t00
                out[k + 2] = t10 - t00
                out[k + 3] = t11 - t10 - t01 + t00
                k += 4
    return out


@njit(cache=True, fastmath=_FM)
def _cost_bil(sb, tb, ht, wt, nc, cy, cx, ca, sa, r, best):
    """SSD of the gathered source patch ``sb`` and the target patch centred at (cx, cy), sampled bilinearly at
    ``(cx, cy) + [[ca, -sa], [sa, ca]] (dx, dy)`` (ca = s cos a, sa = s sin a), coordinates clamped to the
    image, through the table ``tb`` of :func:`bilinear_table`; stops once >= best."""
    p = 2 * r + 1
    n4 = nc * 4
    xmax = wt - 1.0
    ymax = ht - 1.0
    acc = 0.0
    k = 0
    for j in range(p):
        dy = j - r
        x = cx - sa * dy - ca * r
        y = cy + ca * dy - sa * r
        for i in range(p):
            xc = min(max(x, 0.0), xmax)
            yc = min(max(y, 0.0), ymax)
            x0 = int(xc)
            y0 = int(yc)
            fx = np.float32(xc - x0)
            fy = np.float32(yc - y0)
            o = (y0 * wt + x0) * n4
            part = np.float32(0.0)
            for c in range(nc):
                q = o + 4 * c
                v = tb[q] + fx * tb[q + 1] + fy * (tb[q + 2] + fx * tb[q + 3])
                d = sb[k] - v
                part += d * d
                k += 1
            acc += part
            x += ca
            y += sa
        if acc >= best:
            return acc
    return acc


@njit(cache=True, parallel=True)
def init_field(sp, tf, ht, wt, r, general, seed, amin, amax, lsmin, lsmax, fx, fy, fa, fs, fd):
    """Random initial field: centres uniform over the target (integers when not ``general``), angles
    uniform in [amin, amax], scales log-uniform in [exp(lsmin), exp(lsmax)]; fills the SSD.

    ``tf`` is the flat target: :func:`bilinear_table` of it when ``general``, else the target padded by r,
    (ht + 2r, wt + 2r, nc), raveled.
    """
    h, w = fx.shape
    p = 2 * r + 1
    nc = sp.shape[2]
    prow = (wt + 2 * r) * nc
    for yy in prange(h):
        y = np.int64(yy)
        sb = np.empty(p * p * nc, np.float32)
        for x in range(w):
            _gather(sp, y, x, p, sb)
            st = _seed(seed, y * w + x)
            st, u = _uniform(st)
            st, v = _uniform(st)
            if general:
                st, ua = _uniform(st)
                st, us = _uniform(st)
                cx = u * (wt - 1)
                cy = v * (ht - 1)
                a = amin + ua * (amax - amin)
                s = math.exp(lsmin + us * (lsmax - lsmin))
                d = _cost_bil(sb, tf, ht, wt, nc, cy, cx, s * math.cos(a), s * math.sin(a), r, np.inf)
            else:
                ix = min(int(u * wt), wt - 1)
                iy = min(int(v * ht), ht - 1)
                cx = float(ix)
                cy = float(iy)
                a = 0.0
                s = 1.0
                d = _cost_flat(sb, tf, prow, iy * prow + ix * nc, p, nc, np.inf)
            fx[y, x] = cx
            fy[y, x] = cy
            fa[y, x] = a
            fs[y, x] = s
            fd[y, x] = d


@njit(cache=True, parallel=True)
def iterate(sp, tf, ht, wt, r, general, seed, it, starts, ends, amin, amax, lsmin, lsmax, fx, fy, fa, fs, fd):
    """One PatchMatch iteration in place: propagation then random search, pixel by pixel in scan order.

    Rows are split into bands [starts[b], ends[b]) run in parallel; propagation reads only neighbours in
    the pixel's own band (so no thread reads what another writes). Even iterations scan forwards and
    propagate from the left and upper neighbours, odd ones backwards from the right and lower ones.
    ``tf`` as in :func:`init_field`.
    """
    h, w = fx.shape
    p = 2 * r + 1
    nc = sp.shape[2]
    prow = (wt + 2 * r) * nc
    forward = it % 2 == 0
    step = 1 if forward else -1
    wmax = float(max(ht, wt))
    arange = amax - amin
    lsrange = lsmax - lsmin
    xmax = wt - 1.0
    ymax = ht - 1.0
    nb = starts.shape[0]
    for b in prange(nb):
        y_lo = starts[b]
        y_hi = ends[b]
        sb = np.empty(p * p * nc, np.float32)
        for k in range(y_hi - y_lo):
            y = y_lo + k if forward else y_hi - 1 - k
            for m in range(w):
                x = m if forward else w - 1 - m
                _gather(sp, y, x, p, sb)
                bx = fx[y, x]
                by = fy[y, x]
                ba = fa[y, x]
                bs = fs[y, x]
                best = fd[y, x]
                # propagation: the neighbour n = (x - step, y) or (x, y - step) predicts the centre
                # c_n + s_n R(a_n) (x - n) for this pixel, with its own angle and scale
                for q in range(2):
                    if q == 0:
                        nx = x - step
                        ny = y
                        if nx < 0 or nx >= w:
                            continue
                    else:
                        nx = x
                        ny = y - step
                        if ny < y_lo or ny >= y_hi:
                            continue
                    ddx = float(x - nx)
                    ddy = float(y - ny)
                    na = fa[ny, nx]
                    ns = fs[ny, nx]
                    if general:
                        ca = ns * math.cos(na)
                        sa = ns * math.sin(na)
                        cx = min(max(fx[ny, nx] + ca * ddx - sa * ddy, 0.0), xmax)
                        cy = min(max(fy[ny, nx] + sa * ddx + ca * ddy, 0.0), ymax)
                        if cx == bx and cy == by and na == ba and ns == bs:
                            continue
                        d = _cost_bil(sb, tf, ht, wt, nc, cy, cx, ca, sa, r, best)
                    else:
                        cx = min(max(fx[ny, nx] + ddx, 0.0), xmax)
                        cy = min(max(fy[ny, nx] + ddy, 0.0), ymax)
                        if cx == bx and cy == by:
                            continue
                        d = _cost_flat(sb, tf, prow, int(cy) * prow + int(cx) * nc, p, nc, best)
                    if d < best:
                        best = d
                        bx = cx
                        by = cy
                        ba = na
                        bs = ns
                # random search around the current best, window halving from the whole target
                st = _seed(seed, (it + 1) * h * w + y * w + x)
                radius = wmax
                ratio = 1.0
                while radius >= 1.0:
                    st, u = _uniform(st)
                    st, v = _uniform(st)
                    if general:
                        st, ua = _uniform(st)
                        st, us = _uniform(st)
                        cx = min(max(bx + radius * (2.0 * u - 1.0), 0.0), xmax)
                        cy = min(max(by + radius * (2.0 * v - 1.0), 0.0), ymax)
                        a = min(max(ba + arange * ratio * (2.0 * ua - 1.0), amin), amax)
                        s = bs
                        if lsrange > 0.0:
                            s = math.exp(min(max(math.log(bs) + lsrange * ratio * (2.0 * us - 1.0), lsmin), lsmax))
                        d = _cost_bil(sb, tf, ht, wt, nc, cy, cx, s * math.cos(a), s * math.sin(a), r, best)
                        if d < best:
                            best = d
                            bx = cx
                            by = cy
                            ba = a
                            bs = s
                    else:
                        cx = min(max(math.floor(bx + radius * (2.0 * u - 1.0) + 0.5), 0.0), xmax)
                        cy = min(max(math.floor(by + radius * (2.0 * v - 1.0) + 0.5), 0.0), ymax)
                        if cx != bx or cy != by:
                            d = _cost_flat(sb, tf, prow, int(cy) * prow + int(cx) * nc, p, nc, best)
                            if d < best:
                                best = d
                                bx = cx
                                by = cy
                    radius *= 0.5
                    ratio *= 0.5
                fx[y, x] = bx
                fy[y, x] = by
                fa[y, x] = ba
                fs[y, x] = bs
                fd[y, x] = best


@njit(cache=True, parallel=True)
def exhaustive(sp, tp, r, nchunks, fx, fy, fd):
    """Exact translation-only nearest neighbours by brute force over every offset (oy, ox).

    For one offset the squared differences D of the padded images are summed over the patch with running
    column and row sums (O(1) per pixel instead of O(patch^2)); chunks of offset rows run in parallel, each
    with its own best field, merged in chunk order (ties keep the first offset in scan order). The SSD of
    the winner is then recomputed directly, so it is the same number :func:`iterate` would give.
    """
    h, w = fx.shape
    ht = tp.shape[0] - 2 * r
    wt = tp.shape[1] - 2 * r
    p = 2 * r + 1
    nc = sp.shape[2]
    oy_min = -(h - 1)
    n_oy = h + ht - 1
    bd = np.full((nchunks, h, w), np.inf)
    bx = np.zeros((nchunks, h, w), np.int64)
    by = np.zeros((nchunks, h, w), np.int64)
    for ch in prange(nchunks):
        d = np.empty((h + 2 * r, w + 2 * r))
        col = np.empty(w + 2 * r)
        for k in range(ch, n_oy, nchunks):
            oy = oy_min + k
            y_lo = max(0, -oy)
            y_hi = min(h, ht - oy)
            for ox in range(-(w - 1), wt):
                x_lo = max(0, -ox)
                x_hi = min(w, wt - ox)
                # squared differences on the padded rows/cols the valid patches cover
                for u in range(y_lo, y_hi + 2 * r):
                    for v in range(x_lo, x_hi + 2 * r):
                        acc = 0.0
                        for c in range(nc):
                            e = sp[u, v, c] - tp[u + oy, v + ox, c]
                            acc += e * e
                        d[u, v] = acc
                for v in range(x_lo, x_hi + 2 * r):
                    acc = 0.0
                    for j in range(p - 1):
                        acc += d[y_lo + j, v]
                    col[v] = acc
                for y in range(y_lo, y_hi):
                    for v in range(x_lo, x_hi + 2 * r):
                        col[v] += d[y + p - 1, v]
                    acc = 0.0
                    for i in range(p - 1):
                        acc += col[x_lo + i]
                    for x in range(x_lo, x_hi):
                        acc += col[x + p - 1]
                        if acc < bd[ch, y, x]:
                            bd[ch, y, x] = acc
                            bx[ch, y, x] = x + ox
                            by[ch, y, x] = y + oy
                        acc -= col[x]
                    for v in range(x_lo, x_hi + 2 * r):
                        col[v] -= d[y, v]
    for yy in prange(h):
        y = np.int64(yy)
        for x in range(w):
            best = np.inf
            cx = 0
            cy = 0
            for ch in range(nchunks):
                e = bd[ch, y, x]
                if e < best or (e == best and (by[ch, y, x] < cy or (by[ch, y, x] == cy and bx[ch, y, x] < cx))):
                    best = e
                    cx = bx[ch, y, x]
                    cy = by[ch, y, x]
            fx[y, x] = cx
            fy[y, x] = cy
            fd[y, x] = _cost_int(sp, tp, y, x, cy, cx, p, np.inf)
