"""numba kernels of :mod:`probeless.hdr.patchmatch` (generalized PatchMatch, Barnes et al. 2010).

Not a public API: the callers validate every argument. Conventions shared with the caller:

* images are C-contiguous float32 (H, W, C); the *source* arrays passed here are edge-padded by the
  patch radius ``r`` (so source pixel (y, x) has its patch at ``Sp[y:y + p, x:x + p]``, which is the
  clamped patch of the unpadded image); the translation-only kernels take the target padded by ``r``
  too (raveled for :func:`iterate` / :func:`init_field`), the generalized ones the target edge-padded by one
  pixel at the right and bottom (one channel: its :func:`bilinear_table`), raveled (bilinear taps clamp their
  coordinates); the PatchMatch kernels also take the unpadded target size (ht, wt);
* a field is four (H, W) arrays: target patch centre x, y (pixels, float32), angle and scale as int32
  indices into the grids ``agrid`` (rad) and ``sgrid`` (so their sines, cosines and scales are tabled), plus
  the SSD (sum over the patch and the channels, float64) in a fifth;
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
def _gather(spf, srow, sy, sx, p, nc, sb):
    """Copy the (padded) source patch at (sy, sx) into the flat buffer ``sb`` (p * p * nc); ``spf`` is the
    raveled padded source, ``srow`` its row stride."""
    n = p * nc
    for j in range(p):
        o = (sy + j) * srow + sx * nc
        q = j * n
        for k in range(n):
            sb[q + k] = spf[o + k]


@njit(cache=True, fastmath=_FM)
def _cost_flat(sb, tf, row, base, p, nc, best):
    """SSD of the gathered source patch ``sb`` and the padded target patch starting at flat index ``base``
    of ``tf`` (row stride ``row``); stops once >= best."""
    n = p * nc
    acc = 0.0
    for j in range(p):
        o = base + j * row
        q = j * n
        part = np.float32(0.0)
        for k in range(n):
            d = sb[q + k] - tf[o + k]
            part += d * d
        acc += part
        if acc >= best:
            return acc
    return acc


@njit(cache=True, fastmath=_FM)
def _cost_bil(sb, tb, ht, wt, nc, cy, cx, ca, sa, r, best):
    """SSD of the gathered source patch ``sb`` and the target patch centred at (cx, cy), sampled bilinearly at
    ``(cx, cy) + [[ca, -sa], [sa, ca]] (dx, dy)`` (ca = s cos a, sa = s sin a), coordinates clamped to the
    image; ``tb`` is :func:`bilinear_table` of the target for nc == 1, else the target edge-padded by one pixel
    at the right and the bottom, (ht + 1, wt + 1, nc) raveled; stops once >= best. The coordinate clamps are
    no-ops when the whole patch lies inside the image; for nc == 4 (RGB plus a zero channel) a pixel is one SIMD
    vector."""
    xmax = wt - 1.0
    ymax = ht - 1.0
    ext = (abs(ca) + abs(sa)) * r
    if cx - ext >= 0.0 and cx + ext <= xmax and cy - ext >= 0.0 and cy + ext <= ymax:
        xmax = 1e30
        ymax = 1e30
    if nc == 4:
        return _bil(sb, tb, wt + 1, 4, cy, cx, ca, sa, r, best, xmax, ymax)
    if nc == 1:
        return _bil1(sb, tb, wt, cy, cx, ca, sa, r, best, xmax, ymax)
    return _bil(sb, tb, wt + 1, nc, cy, cx, ca, sa, r, best, xmax, ymax)


@njit(cache=True)
def bilinear_table(t):
    """For one channel (t (ht, wt, 1)): per pixel the coefficients (a, b, c, d) of the bilinear patch to its
    right/lower neighbours (clamped at the border), ``v(fx, fy) = a + b fx + c fy + d fx fy``; (ht * wt * 4)."""
    ht, wt = t.shape[0], t.shape[1]
    out = np.empty(ht * wt * 4, np.float32)
    k = 0
    for y in range(ht):
        y1 = min(y + 1, ht - 1)
        for x in range(wt):
            x1 = min(x + 1, wt - 1)
            t00 = t[y, x, 0]
            t01 = t[y, x1, 0]
            t10 = t[y1, x, 0]
            t11 = t[y1, x1, 0]
            out[k] = t00
            out[k + 1] = t01 - t00
            out[k + 2] = t10 - t00
            out[k + 3] = t11 - t10 - t01 + t00
            k += 4
    return out


@njit(cache=True, fastmath=_FM, inline="always")
def _bil1(sb, tb, wt, cy, cx, ca, sa, r, best, xmax, ymax):
    """:func:`_cost_bil` for one channel through the :func:`bilinear_table` ``tb`` (fewer operations per tap)."""
    p = 2 * r + 1
    acc = 0.0
    k = 0
    for j in range(p):
        dy = j - r
        x = cx - sa * dy - ca * r
        y = cy + ca * dy - sa * r
        part = np.float32(0.0)
        for i in range(p):
            xc = min(max(x, 0.0), xmax)
            yc = min(max(y, 0.0), ymax)
            x0 = int(xc)
            y0 = int(yc)
            fx = np.float32(xc - x0)
            fy = np.float32(yc - y0)
            o = (y0 * wt + x0) * 4
            v = tb[o] + fx * tb[o + 1] + fy * (tb[o + 2] + fx * tb[o + 3])
            d = sb[k] - v
            part += d * d
            k += 1
            x += ca
            y += sa
        acc += part
        if acc >= best:
            return acc
    return acc


@njit(cache=True, fastmath=_FM, inline="always")
def _bil(sb, tb, wp, nc, cy, cx, ca, sa, r, best, xmax, ymax):
    """:func:`_cost_bil` once the channel count ``nc`` is a constant (padded row width ``wp``)."""
    p = 2 * r + 1
    row = wp * nc
    acc = 0.0
    k = 0
    for j in range(p):
        dy = j - r
        x = cx - sa * dy - ca * r
        y = cy + ca * dy - sa * r
        part = np.float32(0.0)
        for i in range(p):
            xc = min(max(x, 0.0), xmax)
            yc = min(max(y, 0.0), ymax)
            x0 = int(xc)
            y0 = int(yc)
            fx = np.float32(xc - x0)
            fy = np.float32(yc - y0)
            o = y0 * row + x0 * nc
            for c in range(nc):
                t00 = tb[o + c]
                t01 = tb[o + nc + c]
                t10 = tb[o + row + c]
                t11 = tb[o + row + nc + c]
                top = t00 + fx * (t01 - t00)
                v = top + fy * (t10 + fx * (t11 - t10) - top)
                d = sb[k + c] - v
                part += d * d
            k += nc
            x += ca
            y += sa
        acc += part
        if acc >= best:
            return acc
    return acc


@njit(cache=True, parallel=True)
def box_means(t, sizes):
    """Per odd size q of ``sizes`` the mean of the q x q window around every pixel of ``t`` (H, W, C), with
    coordinates clamped to the image (an edge-padded window): (K, H, W, C) raveled, float32."""
    h, w, nc = t.shape
    out = np.empty((sizes.shape[0], h, w, nc), np.float32)
    rows = np.empty((h, w, nc), np.float64)
    for k in range(sizes.shape[0]):
        q = sizes[k]
        r = q // 2
        for y in prange(h):
            for c in range(nc):  # running sums along the row
                acc = 0.0
                for i in range(-r, r + 1):
                    acc += t[y, min(max(i, 0), w - 1), c]
                for x in range(w):
                    rows[y, x, c] = acc
                    acc += t[y, min(x + r + 1, w - 1), c] - t[y, max(x - r, 0), c]
        for x in prange(w):
            for c in range(nc):  # and down the column
                acc = 0.0
                for j in range(-r, r + 1):
                    acc += rows[min(max(j, 0), h - 1), x, c]
                for y in range(h):
                    out[k, y, x, c] = acc / (q * q)
                    acc += rows[min(y + r + 1, h - 1), x, c] - rows[max(y - r, 0), x, c]
    return out.ravel()


@njit(cache=True)
def _patch_mean(sb, nc, mu):
    """Per-channel mean of the gathered patch ``sb`` into ``mu``."""
    n = sb.shape[0] // nc
    for c in range(nc):
        acc = 0.0
        for k in range(c, sb.shape[0], nc):
            acc += sb[k]
        mu[c] = acc / n


@njit(cache=True)
def _mean_bound(mu, tm, o, nc, n):
    """``n * |mu - tm[o:o + nc]|^2``: a lower bound of the SSD of two n-sample patches with these means."""
    acc = 0.0
    for c in range(nc):
        d = mu[c] - tm[o + c]
        acc += d * d
    return n * acc


@njit(cache=True)
def _grid_index(u, n):
    """A uniform u in [0, 1) to an integer in [0, n)."""
    return min(int(u * n), n - 1)


@njit(cache=True, parallel=True)
def init_field(sp, tf, ht, wt, r, general, seed, agrid, sgrid, fx, fy, ka, ks, fd, given=False):
    """Random initial field: centres uniform over the target (integers when not ``general``), angle and scale
    indices uniform over the grids ``agrid`` (angles [rad]) and ``sgrid`` (scales, log-spaced); fills the SSD.

    ``tf`` is the flat target: as :func:`_cost_bil` takes it when ``general``, else the target padded by r,
    (ht + 2r, wt + 2r, nc), raveled.
    """
    h, w = fx.shape
    p = 2 * r + 1
    nc = sp.shape[2]
    spf = sp.reshape(sp.size)
    srow = sp.shape[1] * nc
    prow = (wt + 2 * r) * nc
    na = agrid.shape[0]
    ns = sgrid.shape[0]
    for yy in prange(h):
        y = np.int64(yy)
        sb = np.empty(p * p * nc, np.float32)
        for x in range(w):
            _gather(spf, srow, y, x, p, nc, sb)
            if given:
                if general:
                    s = sgrid[ks[y, x]]
                    a = agrid[ka[y, x]]
                    fd[y, x] = _cost_bil(sb, tf, ht, wt, nc, fy[y, x], fx[y, x], s * math.cos(a), s * math.sin(a), r,
                                         np.inf)
                else:
                    fd[y, x] = _cost_flat(sb, tf, prow, int(fy[y, x]) * prow + int(fx[y, x]) * nc, p, nc, np.inf)
                continue
            st = _seed(seed, y * w + x)
            st, u = _uniform(st)
            st, v = _uniform(st)
            if general:
                st, ua = _uniform(st)
                st, us = _uniform(st)
                cx = u * (wt - 1)
                cy = v * (ht - 1)
                ia = _grid_index(ua, na)
                js = _grid_index(us, ns)
                s = sgrid[js]
                d = _cost_bil(sb, tf, ht, wt, nc, cy, cx, s * math.cos(agrid[ia]), s * math.sin(agrid[ia]), r,
                              np.inf)
            else:
                ix = _grid_index(u, wt)
                iy = _grid_index(v, ht)
                cx = float(ix)
                cy = float(iy)
                ia = 0
                js = 0
                d = _cost_flat(sb, tf, prow, iy * prow + ix * nc, p, nc, np.inf)
            fx[y, x] = cx
            fy[y, x] = cy
            ka[y, x] = ia
            ks[y, x] = js
            fd[y, x] = d


@njit(cache=True, parallel=True)
def iterate(sp, tf, ht, wt, r, general, seed, it, starts, ends, agrid, sgrid, rmax, nglobal, tmeans, sidx, kappa,
            fx, fy, ka, ks, fd):
    """One PatchMatch iteration in place: propagation then random search, pixel by pixel in scan order.

    Rows are split into bands [starts[b], ends[b]) run in parallel; propagation reads only neighbours in
    the pixel's own band (so no thread reads what another writes). Even iterations scan forwards and
    propagate from the left and upper neighbours, odd ones backwards from the right and lower ones.
    The random search tries ``nglobal`` centres uniform over the whole target, then centres around the
    current best in a window halving from ``rmax`` down to one pixel, angle and scale indices in a window
    halving from the whole grids along with it. ``tf`` as in :func:`init_field`.

    A random candidate is skipped without computing its SSD when ``p^2 |mean(source patch) - mean(target
    patch)|^2``, a lower bound of the SSD, is at least ``kappa`` times the current best; the target means are
    ``tmeans`` (K, ht, wt, nc) raveled, box means of the size ``sidx[scale index]`` picks (exact for a
    translation, an estimate for a rotated or scaled patch).
    """
    h, w = fx.shape
    p = 2 * r + 1
    nc = sp.shape[2]
    spf = sp.reshape(sp.size)
    srow = sp.shape[1] * nc
    prow = (wt + 2 * r) * nc
    forward = it % 2 == 0
    step = 1 if forward else -1
    na = agrid.shape[0]
    ns = sgrid.shape[0]
    cosg = np.cos(agrid)
    sing = np.sin(agrid)
    xmax = wt - 1.0
    ymax = ht - 1.0
    nb = starts.shape[0]
    for b in prange(nb):
        y_lo = starts[b]
        y_hi = ends[b]
        sb = np.empty(p * p * nc, np.float32)
        mu = np.empty(nc, np.float64)
        npix = float(p * p)
        for k in range(y_hi - y_lo):
            y = y_lo + k if forward else y_hi - 1 - k
            for m in range(w):
                x = m if forward else w - 1 - m
                _gather(spf, srow, y, x, p, nc, sb)
                _patch_mean(sb, nc, mu)
                bx = fx[y, x]
                by = fy[y, x]
                ba = ka[y, x]
                bs = ks[y, x]
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
                    if general:
                        na_ = ka[ny, nx]
                        ns_ = ks[ny, nx]
                        ca = sgrid[ns_] * cosg[na_]
                        sa = sgrid[ns_] * sing[na_]
                        cx = min(max(fx[ny, nx] + ca * ddx - sa * ddy, 0.0), xmax)
                        cy = min(max(fy[ny, nx] + sa * ddx + ca * ddy, 0.0), ymax)
                        if cx == bx and cy == by and na_ == ba and ns_ == bs:
                            continue
                        d = _cost_bil(sb, tf, ht, wt, nc, cy, cx, ca, sa, r, best)
                        if d < best:
                            best = d
                            bx = cx
                            by = cy
                            ba = na_
                            bs = ns_
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
                st = _seed(seed, (it + 1) * h * w + y * w + x)
                # global samples: uniform over the whole target and the whole grids
                for g in range(nglobal):
                    st, u = _uniform(st)
                    st, v = _uniform(st)
                    if general:
                        st, ua = _uniform(st)
                        st, us = _uniform(st)
                        cx = u * xmax
                        cy = v * ymax
                        ia = _grid_index(ua, na)
                        js = _grid_index(us, ns)
                        o = ((sidx[js] * ht + int(cy + 0.5)) * wt + int(cx + 0.5)) * nc
                        if _mean_bound(mu, tmeans, o, nc, npix) >= kappa * best:
                            continue
                        s = sgrid[js]
                        d = _cost_bil(sb, tf, ht, wt, nc, cy, cx, s * cosg[ia], s * sing[ia], r, best)
                        if d < best:
                            best = d
                            bx = cx
                            by = cy
                            ba = ia
                            bs = js
                    else:
                        ix = _grid_index(u, wt)
                        iy = _grid_index(v, ht)
                        if _mean_bound(mu, tmeans, (iy * wt + ix) * nc, nc, npix) >= kappa * best:
                            continue
                        d = _cost_flat(sb, tf, prow, iy * prow + ix * nc, p, nc, best)
                        if d < best:
                            best = d
                            bx = float(ix)
                            by = float(iy)
                # random search around the current best, window halving from rmax (position) and the
                # whole grids (angle, scale) down to one pixel
                radius = rmax
                aw = float(na - 1)
                sw = float(ns - 1)
                while radius >= 1.0:
                    st, u = _uniform(st)
                    st, v = _uniform(st)
                    if general:
                        st, ua = _uniform(st)
                        st, us = _uniform(st)
                        cx = min(max(bx + radius * (2.0 * u - 1.0), 0.0), xmax)
                        cy = min(max(by + radius * (2.0 * v - 1.0), 0.0), ymax)
                        ia = min(max(int(math.floor(ba + aw * (2.0 * ua - 1.0) + 0.5)), 0), na - 1)
                        js = min(max(int(math.floor(bs + sw * (2.0 * us - 1.0) + 0.5)), 0), ns - 1)
                        o = ((sidx[js] * ht + int(cy + 0.5)) * wt + int(cx + 0.5)) * nc
                        if _mean_bound(mu, tmeans, o, nc, npix) < kappa * best:
                            s = sgrid[js]
                            d = _cost_bil(sb, tf, ht, wt, nc, cy, cx, s * cosg[ia], s * sing[ia], r, best)
                            if d < best:
                                best = d
                                bx = cx
                                by = cy
                                ba = ia
                                bs = js
                    else:
                        cx = min(max(math.floor(bx + radius * (2.0 * u - 1.0) + 0.5), 0.0), xmax)
                        cy = min(max(math.floor(by + radius * (2.0 * v - 1.0) + 0.5), 0.0), ymax)
                        o = (int(cy) * wt + int(cx)) * nc
                        if (cx != bx or cy != by) and _mean_bound(mu, tmeans, o, nc, npix) < kappa * best:
                            d = _cost_flat(sb, tf, prow, int(cy) * prow + int(cx) * nc, p, nc, best)
                            if d < best:
                                best = d
                                bx = cx
                                by = cy
                    radius *= 0.5
                    aw *= 0.5
                    sw *= 0.5
                fx[y, x] = bx
                fy[y, x] = by
                ka[y, x] = ba
                ks[y, x] = bs
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
