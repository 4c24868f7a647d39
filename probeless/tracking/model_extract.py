"""Surface extraction from an Open3D tensor SLAM model: coloured point cloud and triangle mesh."""

from __future__ import annotations

import numpy as np


def extraction_threshold(integrated: int) -> float:
    """Weight threshold of the extraction: 3, less while the model is young. Open3D keeps the voxels whose
    weight exceeds it (strictly: 3 integrations of a surface give no points at threshold 3, asserted in
    tests/tracking/test_block_stamps.py), so a surface needs 4 observations, 2 after one frame."""
    return float(max(1, min(3, integrated)))


def extract_pointcloud(model, weight_threshold: float,
                       max_points: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(points (N, 3) float32 [m, grid], colours (N, 3) float32 0..1, unit normals (N, 3) float32 [grid]: the
    TSDF gradient, rows of 0 where Open3D gives none) of ``model``'s surface (an ``o3d.t.pipelines.slam.Model``);
    at most ``max_points``, evenly subsampled."""
    pcd = model.extract_pointcloud(weight_threshold)
    if pcd.is_empty():
        return np.zeros((0, 3), np.float32), np.zeros((0, 3), np.float32), np.zeros((0, 3), np.float32)
    pts = pcd.point.positions.numpy().astype(np.float32)
    cols = pcd.point.colors.numpy().astype(np.float32, copy=False) if "colors" in pcd.point else np.zeros_like(pts)
    nrm = pcd.point.normals.numpy().astype(np.float32) if "normals" in pcd.point else np.zeros_like(pts)
    if max_points is not None and len(pts) > max_points:
        keep = np.linspace(0, len(pts) - 1, max_points).astype(np.int64)
        pts, cols, nrm = pts[keep], cols[keep], nrm[keep]
    length = np.linalg.norm(nrm, axis=1, keepdims=True)
    nrm = np.where((length > 1e-6) & np.isfinite(length), nrm / np.maximum(length, 1e-6), 0.0).astype(np.float32)
    return np.ascontiguousarray(pts), np.ascontiguousarray(np.clip(cols, 0.0, 1.0)), np.ascontiguousarray(nrm)


def extract_mesh(model, weight_threshold: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(vertices (V, 3) float32 [m, world], triangles (T, 3) int32, colours (V, 3) float32 0..1)."""
    mesh = model.extract_trianglemesh(weight_threshold)
    if mesh.is_empty() or "indices" not in mesh.triangle:
        return np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32), np.zeros((0, 3), np.float32)
    v = mesh.vertex.positions.numpy().astype(np.float32)
    tri = mesh.triangle.indices.numpy().astype(np.int32)
    c = mesh.vertex.colors.numpy().astype(np.float32) if "colors" in mesh.vertex else np.zeros_like(v)
    return v, tri, np.clip(c, 0.0, 1.0)
