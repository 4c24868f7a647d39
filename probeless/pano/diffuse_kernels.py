"""numba kernel of :mod:`probeless.pano.diffuse_fast`: the exact cosine sums of a few full-resolution pixels.

Not a public API: the caller passes C-contiguous float32 arrays of matching lengths.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, fastmath=True)
def _sums3(nx, ny, nz, dirs, lw, r, g, b):  # pragma: no cover - compiled
    for p in range(dirs.shape[0]):
        dx, dy, dz, lr, lg, lb = dirs[p, 0], dirs[p, 1], dirs[p, 2], lw[p, 0], lw[p, 1], lw[p, 2]
        for k in range(nx.shape[0]):
            w = max(nx[k] * dx + ny[k] * dy + nz[k] * dz, np.float32(0.0))
            r[k] += w * lr
            g[k] += w * lg
            b[k] += w * lb


def cosine_sums(normals_t: np.ndarray, dirs: np.ndarray, omega: np.ndarray, radiance: np.ndarray) -> np.ndarray:
    """(N, C) float64 ``sum_p radiance[p] * omega[p] * max(0, n . dirs[p])`` for the (3, N) ``normals_t``
    over the (P, 3) ``dirs``, (P,) ``omega`` and (P, C) ``radiance``, float32 sums, three channels at a time
    (the inner loop runs over the normals: contiguous, vectorised)."""
    lw = (radiance * omega[:, None]).astype(np.float32)
    c = lw.shape[1]
    lw = np.concatenate([lw, np.zeros((len(lw), (-c) % 3), np.float32)], axis=1)
    out = np.zeros((lw.shape[1], normals_t.shape[1]), np.float32)
    for k in range(0, lw.shape[1], 3):
        _sums3(normals_t[0], normals_t[1], normals_t[2], dirs, np.ascontiguousarray(lw[:, k:k + 3]),
               out[k], out[k + 1], out[k + 2])
    return out[:c].T.astype(np.float64)
