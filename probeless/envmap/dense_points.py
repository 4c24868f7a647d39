"""A dense coloured point model near the virtual objects from RGB-D frames and their poses.

The evaluation's stand-in for the SLAM node's model (``dense_slam`` ``model/points``): depth
pixels (every ``step``-th) back-projected with the pose, kept within ``radius_m`` of any virtual
object, and fused on a voxel grid (colour = mean of the points in a voxel). Given true poses, it
measures what the dense model adds to the environment maps independently of tracking error.
"""

from __future__ import annotations

import numpy as np


class DensePoints:
    """Voxel-averaged coloured points fused from RGB-D frames."""

    def __init__(self, centres: np.ndarray, radius_m: float = 1.5, voxel_m: float = 0.02, step: int = 4):
        self.centres = np.asarray(centres, np.float64).reshape(-1, 3)
        self.radius_m, self.voxel_m, self.step = radius_m, voxel_m, step
        self._sum: dict[tuple, np.ndarray] = {}
        self.keys = np.zeros((0, 3), np.int64)
        self.color_sum = np.zeros((0, 3), np.float64)
        self.count = np.zeros(0, np.int64)

    def add(self, rgb: np.ndarray, depth_m: np.ndarray, K: np.ndarray, world_from_camera: np.ndarray) -> int:
        """Fuse one frame (rgb uint8 (H, W, 3), depth (H, W) metres, 0 = none); returns the points kept."""
        s = self.step
        z = depth_m[::s, ::s]
        v, u = np.mgrid[0:depth_m.shape[0]:s, 0:depth_m.shape[1]:s]
        ok = z > 0
        z, u, v = z[ok], u[ok], v[ok]
        x = (u - K[0, 2]) / K[0, 0] * z
        y = (v - K[1, 2]) / K[1, 1] * z
        pts = np.stack([x, y, z], axis=1) @ world_from_camera[:3, :3].T + world_from_camera[:3, 3]
        near = np.min(np.linalg.norm(pts[:, None, :] - self.centres[None], axis=2), axis=1) <= self.radius_m
        pts, cols = pts[near], rgb[::s, ::s][ok][near].astype(np.float64)
        if not len(pts):
            return 0
        keys = np.floor(pts / self.voxel_m).astype(np.int64)
        all_keys = np.concatenate([self.keys, keys])
        uniq, inv = np.unique(all_keys, axis=0, return_inverse=True)
        inv = inv.reshape(-1)
        csum = np.zeros((len(uniq), 3))
        cnt = np.zeros(len(uniq), np.int64)
        n_old = len(self.keys)
        np.add.at(csum, inv[:n_old], self.color_sum)
        np.add.at(cnt, inv[:n_old], self.count)
        np.add.at(csum, inv[n_old:], cols)
        np.add.at(cnt, inv[n_old:], 1)
        self.keys, self.color_sum, self.count = uniq, csum, cnt
        return len(pts)

    def points(self) -> tuple[np.ndarray, np.ndarray]:
        """(points (N, 3) float32 voxel centres [m, world], colours (N, 3) uint8)."""
        centres = (self.keys + 0.5) * self.voxel_m
        cols = np.clip(np.round(self.color_sum / np.maximum(self.count, 1)[:, None]), 0, 255)
        return centres.astype(np.float32), cols.astype(np.uint8)
