"""A dense coloured point model near the virtual objects from RGB-D frames and their poses.

The evaluation's stand-in for the SLAM node's model (``dense_slam`` ``model/points``): depth
pixels (every ``step``-th) back-projected with the pose, kept within ``radius_m`` of any virtual
object, and fused on a voxel grid (colour = mean of the points in a voxel). Given true poses, it
measures what the dense model adds to the environment maps independently of tracking error.

Each point also gets a normal (:meth:`DensePoints.normals`): the cross product of the depth grid's central
differences, turned towards the camera, summed per voxel. The renderer uses it to drop points seen from
behind or edge-on (:class:`probeless.envmap.cubemap.EnvmapRenderer`). Pixels at a depth edge (a neighbour
``EDGE_REL`` farther or nearer, or missing) get no normal.
"""

from __future__ import annotations

import numpy as np

EDGE_REL = 0.05  # relative depth jump between grid neighbours that marks a depth edge (no normal there)


def grid_normals(xyz: np.ndarray) -> np.ndarray:
    """(h, w, 3) unit normals of an organised camera-frame point grid (h, w, 3) (z = 0: no point), facing the
    camera (n . p < 0); rows of 0 where a neighbour is missing or across a depth edge."""
    n = np.zeros_like(xyz)
    if min(xyz.shape[:2]) < 3:
        return n
    z = xyz[..., 2]
    dx, dy = xyz[1:-1, 2:] - xyz[1:-1, :-2], xyz[2:, 1:-1] - xyz[:-2, 1:-1]
    c = np.cross(dx, dy)
    zc = z[1:-1, 1:-1]
    near = np.stack([z[1:-1, 2:], z[1:-1, :-2], z[2:, 1:-1], z[:-2, 1:-1]])
    ok = (zc > 0) & np.all(near > 0, axis=0) & np.all(np.abs(near - zc) <= EDGE_REL * zc, axis=0)
    norm = np.linalg.norm(c, axis=-1)
    ok &= norm > 0
    c = c / np.maximum(norm, 1e-30)[..., None]
    c *= np.where((c * xyz[1:-1, 1:-1]).sum(-1) > 0, -1.0, 1.0)[..., None]
    n[1:-1, 1:-1] = np.where(ok[..., None], c, 0.0)
    return n


class DensePoints:
    """Voxel-averaged coloured points fused from RGB-D frames."""

    def __init__(self, centres: np.ndarray, radius_m: float = 1.5, voxel_m: float = 0.02, step: int = 4):
        self.centres = np.asarray(centres, np.float64).reshape(-1, 3)
        self.radius_m, self.voxel_m, self.step = radius_m, voxel_m, step
        self._sum: dict[tuple, np.ndarray] = {}
        self.keys = np.zeros((0, 3), np.int64)
        self.color_sum = np.zeros((0, 3), np.float64)
        self.count = np.zeros(0, np.int64)
        self.normal_sum = np.zeros((0, 3), np.float64)

    def add(self, rgb: np.ndarray, depth_m: np.ndarray, K: np.ndarray, world_from_camera: np.ndarray) -> int:
        """Fuse one frame (rgb uint8 (H, W, 3), depth (H, W) metres, 0 = none); returns the points kept."""
        s = self.step
        z = np.asarray(depth_m[::s, ::s], np.float64)
        v, u = np.mgrid[0:depth_m.shape[0]:s, 0:depth_m.shape[1]:s]
        grid = np.stack([(u - K[0, 2]) / K[0, 0] * z, (v - K[1, 2]) / K[1, 1] * z, z], axis=-1)
        ok = z > 0
        R = world_from_camera[:3, :3]
        pts = grid[ok] @ R.T + world_from_camera[:3, 3]
        nrm = grid_normals(grid)[ok] @ R.T
        near = np.min(np.linalg.norm(pts[:, None, :] - self.centres[None], axis=2), axis=1) <= self.radius_m
        pts, cols, nrm = pts[near], rgb[::s, ::s][ok][near].astype(np.float64), nrm[near]
        if not len(pts):
            return 0
        keys = np.floor(pts / self.voxel_m).astype(np.int64)
        all_keys = np.concatenate([self.keys, keys])
        uniq, inv = np.unique(all_keys, axis=0, return_inverse=True)
        inv = inv.reshape(-1)
        csum, nsum = np.zeros((len(uniq), 3)), np.zeros((len(uniq), 3))
        cnt = np.zeros(len(uniq), np.int64)
        n_old = len(self.keys)
        np.add.at(csum, inv[:n_old], self.color_sum)
        np.add.at(nsum, inv[:n_old], self.normal_sum)
        np.add.at(cnt, inv[:n_old], self.count)
        np.add.at(csum, inv[n_old:], cols)
        np.add.at(nsum, inv[n_old:], nrm)
        np.add.at(cnt, inv[n_old:], 1)
        self.keys, self.color_sum, self.count, self.normal_sum = uniq, csum, cnt, nsum
        return len(pts)

    def points(self) -> tuple[np.ndarray, np.ndarray]:
        """(points (N, 3) float32 voxel centres [m, world], colours (N, 3) uint8)."""
        centres = (self.keys + 0.5) * self.voxel_m
        cols = np.clip(np.round(self.color_sum / np.maximum(self.count, 1)[:, None]), 0, 255)
        return centres.astype(np.float32), cols.astype(np.uint8)

    def normals(self) -> np.ndarray:
        """(N, 3) float32 unit normals [world] in :meth:`points`' order; 0 where unknown (no normal fused, or the
        fused ones disagree: their mean is shorter than 0.5)."""
        norm = np.linalg.norm(self.normal_sum, axis=1)
        known = norm >= 0.5 * np.maximum(self.count, 1)
        return np.where(known[:, None], self.normal_sum / np.maximum(norm, 1e-30)[:, None], 0.0).astype(np.float32)
