"""When each TSDF voxel block was last fused from a frame: per-point fusion stamps of the dense model.

Open3D's tensor SLAM model (:class:`probeless.tracking.dense.DenseSlam`) keeps its TSDF in voxel
blocks of ``block_resolution``³ voxels. Integrating a frame updates exactly the blocks near the
surfaces the frame's depth sees (``Model.frustum_block_coords`` after ``Model.integrate``), so the
stamp of the last frame integrated into a block is when every surface point in it was last fused.
Consumers that change the model's colours over time (the cubemap node's brightness change Δ, issue
17 §5) use it to tell the points a frame refreshed from those it left alone.

A point's block is ``floor(floor(p / voxel_size) / block_resolution)`` in the grid's coordinates:
Open3D puts voxel ``v`` of block ``b`` at ``(b · block_resolution + v) · voxel_size``, and an extracted
surface point lies between its voxel and the next one along an axis (the zero crossing), so it falls
in its own voxel's cell. Block stamps are coarser than voxel stamps: a point near the edge of a
frame's view shares its block with points the frame did see, and then gets that frame's stamp.
"""

from __future__ import annotations

import numpy as np

BITS = 21                  # per coordinate in a packed key: blocks within ±2^20 of the origin
OFFSET = 1 << (BITS - 1)
MASK = (1 << BITS) - 1


def pack_blocks(coords: np.ndarray) -> np.ndarray:
    """(N,) int64 keys of integer block coordinates (N, 3) (each within ±2^20, i.e. ±167 km at 1 cm voxels)."""
    c = np.asarray(coords, dtype=np.int64).reshape(-1, 3) + OFFSET
    if c.size and (c.min() < 0 or c.max() > MASK):
        raise ValueError(f"block coordinates beyond ±{OFFSET}: min {c.min() - OFFSET}, max {c.max() - OFFSET}")
    return (c[:, 0] << (2 * BITS)) | (c[:, 1] << BITS) | c[:, 2]


def blocks_of_points(points: np.ndarray, voxel_size: float, block_resolution: int) -> np.ndarray:
    """(N, 3) int64 block coordinates of points (N, 3) given in the grid's coordinates [m]."""
    voxels = np.floor(np.asarray(points, dtype=np.float64).reshape(-1, 3) / voxel_size).astype(np.int64)
    return np.floor_divide(voxels, block_resolution)


class BlockStamps:
    """Stamp of the last frame fused into each voxel block: sorted packed keys and their stamps (numpy).

    ``touch`` records a frame's blocks, ``lookup`` answers for many points at once; neither loops
    over points or blocks in Python."""

    def __init__(self, voxel_size: float, block_resolution: int):
        if voxel_size <= 0 or block_resolution < 1:
            raise ValueError(f"BlockStamps needs voxel_size > 0 and block_resolution >= 1, got {voxel_size}, "
                             f"{block_resolution}")
        self.voxel_size, self.block_resolution = float(voxel_size), int(block_resolution)
        self.keys = np.zeros(0, np.int64)     # sorted, unique
        self.stamps = np.zeros(0, np.int64)   # per key [ns, the frames' clock]

    def __len__(self) -> int:
        return len(self.keys)

    def touch(self, block_coords: np.ndarray, stamp_ns: int) -> None:
        """Record that the frame stamped ``stamp_ns`` was fused into these blocks ((M, 3) integers)."""
        new = np.unique(pack_blocks(block_coords))
        idx = np.searchsorted(self.keys, new)
        found = idx < len(self.keys)
        found[found] = self.keys[idx[found]] == new[found]
        self.stamps[idx[found]] = stamp_ns
        fresh = new[~found]
        if len(fresh):
            keys = np.concatenate([self.keys, fresh])
            order = np.argsort(keys, kind="stable")
            self.keys = keys[order]
            self.stamps = np.concatenate([self.stamps, np.full(len(fresh), stamp_ns, np.int64)])[order]

    def lookup(self, points_grid: np.ndarray, default: int = 0) -> np.ndarray:
        """(N,) int64 stamp of the block holding each point (grid coordinates [m]); ``default`` where none.

        Points of one block come in runs from Open3D's extraction (block by block): each run is looked
        up once. Any order gives the same answer."""
        keys = pack_blocks(blocks_of_points(points_grid, self.voxel_size, self.block_resolution))
        if not len(keys):
            return np.zeros(0, np.int64)
        starts = np.flatnonzero(np.concatenate([[True], keys[1:] != keys[:-1]]))
        run_keys = keys[starts]
        out = np.full(len(run_keys), default, np.int64)
        if len(self.keys):
            idx = np.minimum(np.searchsorted(self.keys, run_keys), len(self.keys) - 1)
            hit = self.keys[idx] == run_keys
            out[hit] = self.stamps[idx[hit]]
        return np.repeat(out, np.diff(np.append(starts, len(keys))))
