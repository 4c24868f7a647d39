"""Cloud messages and files as PBGI arrays (probeless.pbgi.cloud)."""

from __future__ import annotations

import numpy as np
import open3d as o3d
import pytest

from probeless.color import from_srgb8
from probeless.errors import PbgiError
from probeless.hdr.io import write_hdr_ply
from probeless.messages import HdrPointCloud, Header, PointCloud
from probeless.pbgi.cloud import NORMAL_NEIGHBOURS, cloud_arrays, estimate_normals, read_cloud_file


def _plane(n: int = 2000, seed: int = 0) -> np.ndarray:
    """Points on the tilted plane z = 0.3 x - 0.2 y + 1 (normal ~ (-0.3, 0.2, 1))."""
    xy = np.random.default_rng(seed).random((n, 2)) * 2 - 1
    return np.column_stack([xy, 0.3 * xy[:, 0] - 0.2 * xy[:, 1] + 1.0]).astype(np.float32)


def test_normals_of_planar_points_are_the_plane_normal_facing_the_viewpoint_as_open3d_gives_them():
    pts = _plane()
    true = np.array([-0.3, 0.2, 1.0]) / np.linalg.norm([-0.3, 0.2, 1.0])
    for viewpoint, sign in (([0.0, 0.0, 5.0], 1.0), ([0.0, 0.0, -5.0], -1.0)):
        n = estimate_normals(pts, viewpoint)
        np.testing.assert_allclose(n, np.broadcast_to(sign * true, n.shape), atol=1e-5)
        ref = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts.astype(np.float64)))
        ref.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(knn=NORMAL_NEIGHBOURS))
        ref.orient_normals_towards_camera_location(np.array(viewpoint))
        np.testing.assert_allclose(n, np.asarray(ref.normals), atol=1e-9)


def test_default_orientation_is_towards_the_centroid_so_a_room_scan_faces_inwards():
    # floor and ceiling of a box: the floor's normals point up, the ceiling's down, both into the room
    rng = np.random.default_rng(1)
    xy = rng.random((3000, 2)) * 4
    pts = np.vstack([np.column_stack([xy, np.zeros(3000)]), np.column_stack([xy, np.full(3000, 2.5)])])
    msg = PointCloud(Header(0, "map"), pts.astype(np.float32), np.full((6000, 3), 128, np.uint8))
    _, _, n = cloud_arrays(msg)
    assert (n[:3000, 2] > 0.99).all() and (n[3000:, 2] < -0.99).all()
    assert cloud_arrays(msg, estimate=False)[2].shape == (0, 3)  # no BSH to build (envmap mode): none needed


def test_colours_srgb_codes_decode_floats_and_radiance_stay_linear():
    pts = _plane(50)
    codes = np.random.default_rng(2).integers(0, 256, (50, 3), dtype=np.uint8)
    normals = np.tile(np.float32([0, 0, 1]), (50, 1))
    p, c, n = cloud_arrays(PointCloud(Header(0, "map"), pts, codes, normals))
    np.testing.assert_array_equal(c, from_srgb8(codes))
    assert p.dtype == np.float64 and c.dtype == np.float32 and n.dtype == np.float64
    np.testing.assert_array_equal(n, normals)
    floats = np.random.default_rng(3).random((50, 3), dtype=np.float32)
    np.testing.assert_array_equal(cloud_arrays(PointCloud(Header(0, "map"), pts, floats, normals))[1], floats)
    hdr = floats * 40
    np.testing.assert_array_equal(cloud_arrays(HdrPointCloud(Header(0, "map"), pts, hdr, normals))[1], hdr)


def test_bad_clouds_raise_naming_the_problem():
    empty = PointCloud(Header(0, "map"), np.zeros((0, 3), np.float32), np.zeros((0, 3), np.uint8))
    with pytest.raises(PbgiError, match="empty cloud"):
        cloud_arrays(empty)
    pts = _plane(20)
    bad = pts.copy()
    bad[3, 1] = np.nan
    with pytest.raises(PbgiError, match="'points'"):
        cloud_arrays(PointCloud(Header(0, "map"), bad, np.zeros((20, 3), np.uint8)))
    colors = np.full((20, 3), 0.5, np.float32)
    colors[0, 0] = np.nan
    with pytest.raises(PbgiError, match="'colors'"):
        cloud_arrays(PointCloud(Header(0, "map"), pts, colors))
    normals = np.tile(np.float32([0, 0, 1]), (20, 1))
    normals[5] = np.inf
    with pytest.raises(PbgiError, match="'normals'"):
        cloud_arrays(PointCloud(Header(0, "map"), pts, np.zeros((20, 3), np.uint8), normals))


def test_cloud_files_srgb_ply_and_hdr_ply(tmp_path):
    pts = _plane(100)
    ldr = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts.astype(np.float64)))
    codes = np.random.default_rng(4).integers(0, 256, (100, 3), dtype=np.uint8)
    ldr.colors = o3d.utility.Vector3dVector(codes / 255.0)
    o3d.io.write_point_cloud(str(tmp_path / "ldr.ply"), ldr)
    p, c, n = read_cloud_file(tmp_path / "ldr.ply")
    np.testing.assert_allclose(c, from_srgb8(codes), atol=1e-6)
    assert n is None and len(p) == 100
    radiance = np.random.default_rng(5).random((100, 3), dtype=np.float32) * 30
    write_hdr_ply(tmp_path / "hdr.ply", pts, radiance)
    np.testing.assert_array_equal(read_cloud_file(tmp_path / "hdr.ply")[1], radiance)  # not clipped, not decoded
    with pytest.raises(PbgiError, match="not found"):
        read_cloud_file(tmp_path / "missing.ply")
