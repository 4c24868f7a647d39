"""The whole HDR expansion (probeless.hdr.expand), its I/O, the HdrPointCloud message and ``probeless hdr expand``.

Scene: a 4 x 4 x 3 m box room of textured walls (true radiance 0.05..0.6) with a window on the +x wall of
true radiance WINDOW (20, 15, 10). The LDR cloud is the true radiance exposed at 1 and clamped to 0..1
(so the window is white, 1); the photo is the true radiance splatted as a cubemap from an off-centre
point the views never use, the six faces side by side, times an unknown 0.37.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from locations import SHARED_DATA

from probeless.errors import HdrError, SchemaError
from probeless.hdr.expand import METHODS, expand_cloud
from probeless.hdr.exposure import luminance
from probeless.hdr.io import read_cloud, read_hdr_ply, write_hdr_ply
from probeless.hdr.transfer import overexposed
from probeless.messages import HdrPointCloud, Header

WINDOW = np.array([20.0, 15.0, 10.0], np.float32)
PHOTO_SCALE = 0.37
SIZE = 128
FRAGMENT = SHARED_DATA / "pointclouds" / "open3d_fragment.pcd"
HDRI = SHARED_DATA / "hdri" / "st_fagans_interior_1k.hdr"


def _room(step: float = 0.04, seed: int = 0):
    """(points (N, 3), true radiance (N, 3), window mask (N,)): a box [-2, 2]^2 x [0, 3] sampled every ``step``."""
    rng = np.random.default_rng(seed)
    a = np.arange(-2.0, 2.0 + 1e-9, step)
    h = np.arange(0.0, 3.0 + 1e-9, step)
    faces = []
    for x in (-2.0, 2.0):
        y, z = np.meshgrid(a, h, indexing="ij")
        faces.append(np.stack([np.full(y.size, x), y.ravel(), z.ravel()], 1))
        faces.append(np.stack([y.ravel(), np.full(y.size, x), z.ravel()], 1))
    for z in (0.0, 3.0):
        x, y = np.meshgrid(a, a, indexing="ij")
        faces.append(np.stack([x.ravel(), y.ravel(), np.full(x.size, z)], 1))
    p = np.unique(np.round(np.concatenate(faces), 6), axis=0).astype(np.float32)
    # smooth texture: a few sinusoids per channel, 0.05..0.6
    tex = np.stack([np.sin(p @ rng.normal(0, 3, 3) + c) + np.sin(p @ rng.normal(0, 7, 3)) for c in range(3)], 1)
    true = (0.05 + 0.55 * (tex - tex.min()) / (tex.max() - tex.min())).astype(np.float32)
    window = (p[:, 0] > 1.99) & (np.abs(p[:, 1]) < 0.6) & (p[:, 2] > 1.0) & (p[:, 2] < 2.2)
    true[window] = WINDOW
    return p, true, window


@pytest.fixture(scope="module")
def room():
    p, true, window = _room()
    ldr = np.clip(true, 0.0, 1.0)
    return p, true, ldr, window


def _photo(points, true, face: int = SIZE) -> np.ndarray:
    from probeless.hdr.splat import SplatRenderer, point_spacing

    r = SplatRenderer()
    try:
        faces = r.render_cubemap(points, true, point_spacing(points), (-0.7, 0.5, 1.2), face_size=face)
    finally:
        r.release()
    return np.concatenate([f.color for f in faces], axis=1) * np.float32(PHOTO_SCALE)


@pytest.fixture(scope="module")
def photo(room):
    return _photo(room[0], room[1])


def _check_common(res, ldr, window):
    over = overexposed(ldr)
    assert over[window].all()
    np.testing.assert_array_equal(res.radiance[~over], ldr[~over])  # well-exposed points keep their colour
    assert np.isfinite(res.radiance).all() and (res.radiance >= 0).all()
    r = res.report
    assert r["points_overexposed"] == int(over.sum())
    assert r["points_expanded"] + r["points_filled"] + r["points_left_ldr"] == r["points_overexposed"]


@pytest.mark.parametrize("method", ["landis-pc", "banterle-pc"])
def test_operator_per_point_needs_no_gl_or_photo(room, method):
    p, _, ldr, window = room
    res = expand_cloud(p, ldr, None, method=method, max_lum=10.0)
    _check_common(res, ldr, window)
    assert (luminance(res.radiance[window]) > 1.0).all()
    assert res.report["views"] == [] and res.report["alpha"] is None and res.views == []


@pytest.mark.slow
@pytest.mark.gl
@pytest.mark.parametrize("method", [m for m in METHODS if not m.endswith("-pc")])
def test_view_methods(room, photo, method):
    p, true, ldr, window = room
    res = expand_cloud(p, ldr, photo, method=method, views=1, size=SIZE,
                       transfer="lum" if method == "pmatch-lum" else "rgb")
    _check_common(res, ldr, window)
    assert len(res.report["views"]) == 1 and len(res.views) == 1
    assert res.report["alpha"] == pytest.approx(1 / PHOTO_SCALE, rel=0.5)
    y = luminance(res.radiance[window])
    assert np.median(y) > 1.0
    if method == "pmatch-rgb":
        # the median window radiance per channel within a factor of 2 of the truth; LDR is off by >= 10
        ratio = np.median(res.radiance[window], axis=0) / WINDOW
        assert ((ratio > 0.5) & (ratio < 2.0)).all(), ratio
        assert (np.median(ldr[window], axis=0) / WINDOW <= 0.1).all()


@pytest.mark.gl
def test_explicit_positions(room, photo):
    p, _, ldr, window = room
    views = np.array([[[0.5, 0.0, 1.6], [2.0, 0.0, 1.6]]])
    res = expand_cloud(p, ldr, None, method="landis", views=views, size=64, max_lum=10.0)
    assert res.report["views"][0]["position"] == [0.5, 0.0, 1.6]
    _check_common(res, ldr, window)


def test_bad_arguments(room):
    p, _, ldr, _ = room
    with pytest.raises(HdrError, match="unknown method"):
        expand_cloud(p, ldr, None, method="nope")
    with pytest.raises(HdrError, match="needs the HDR photo"):
        expand_cloud(p, ldr, None, method="pmatch-rgb")
    with pytest.raises(HdrError, match="ldr_colors"):
        expand_cloud(p, ldr * 3, None, method="landis-pc", max_lum=10.0)
    with pytest.raises(HdrError, match="max_lum"):
        expand_cloud(p, ldr, None, method="landis-pc")


@pytest.mark.slow
def test_hdr_ply_round_trip(tmp_path, room):
    import open3d as o3d

    p, true, _, _ = room
    n = np.tile(np.array([0, 0, 1], np.float32), (len(p), 1))
    for normals in (None, n):
        path = write_hdr_ply(tmp_path / "c.ply", p, true, normals)
        q, r, m = read_hdr_ply(path)
        assert q.tobytes() == p.tobytes() and r.tobytes() == true.tobytes()
        assert (m is None) if normals is None else (m.tobytes() == n.tobytes())
        pcd = o3d.io.read_point_cloud(str(path))
        assert len(pcd.points) == len(p) and pcd.has_colors()
    with pytest.raises(HdrError, match="radiance"):
        write_hdr_ply(tmp_path / "bad.ply", p, -true)


def test_read_cloud_errors(tmp_path):
    import open3d as o3d

    with pytest.raises(HdrError, match="not found"):
        read_cloud(tmp_path / "missing.ply")
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.random.default_rng(0).random((10, 3))))
    o3d.io.write_point_cloud(str(tmp_path / "plain.ply"), pcd)
    with pytest.raises(HdrError, match="no colours"):
        read_cloud(tmp_path / "plain.ply")
    pcd.colors = o3d.utility.Vector3dVector(np.full((10, 3), 0.5))
    o3d.io.write_point_cloud(str(tmp_path / "col.ply"), pcd)
    _, c, _ = read_cloud(tmp_path / "col.ply")
    assert c.dtype == np.float32 and np.allclose(c, 0.2140, atol=2e-3)  # sRGB 0.5 (code 128) -> linear


def test_message_rejects_nan_and_negative():
    p = np.zeros((2, 3), np.float32)
    HdrPointCloud(Header(stamp_ns=0, frame_id="world", seq=0), p, np.array([[0, 1, 50], [2, 3, 4]], np.float32))
    for bad in (np.array([[np.nan, 0, 0], [0, 0, 0]], np.float32), np.array([[-1, 0, 0], [0, 0, 0]], np.float32)):
        with pytest.raises(SchemaError, match="radiance"):
            HdrPointCloud(Header(stamp_ns=0, frame_id="world", seq=0), p, bad)


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "probeless.cli", "hdr", "expand", *map(str, args)],
                          capture_output=True, text=True, timeout=120)


@pytest.mark.gl
@pytest.mark.graph
@pytest.mark.slow
def test_cli_on_fragment(tmp_path):
    out = tmp_path / "out.ply"
    fig = tmp_path / "fig"
    r = _cli(FRAGMENT, "--photo", HDRI, "-o", out, "--method", "landis", "--views", "1", "--size", "64",
             "--figures", fig, "--json")
    assert r.returncode == 0, r.stderr
    report = json.loads(r.stdout)
    assert report == json.loads(out.with_suffix(".json").read_text())
    pts, rad, _ = read_hdr_ply(out)
    assert len(pts) == report["points"] and np.isfinite(rad).all()
    assert report["alpha"] > 0
    assert (fig / "pano_before.png").is_file() and (fig / "pano_after.png").is_file()
    # explicit views (the fragment has no over-exposed point, so --views places none)
    (tmp_path / "views.txt").write_text("# position, look-at\n2.3 1.7 2.6  2.3 1.7 1.0\n2.3, 1.7, 2.0\n")
    r = _cli(FRAGMENT, "--photo", HDRI, "-o", out, "--method", "banterle", "--view-positions",
             tmp_path / "views.txt", "--size", "64", "--figures", fig, "--json")
    assert r.returncode == 0, r.stderr
    report = json.loads(r.stdout)
    assert len(report["views"]) == 2 and report["views"][0]["look_at"] == [2.3, 1.7, 1.0]
    assert (fig / "view_01_ldr.png").is_file() and (fig / "view_01_hdr.png").is_file()


@pytest.mark.graph
@pytest.mark.slow
def test_cli_bad_inputs(tmp_path):
    import open3d as o3d

    r = _cli(tmp_path / "missing.ply", "--photo", HDRI, "-o", tmp_path / "o.ply", "--method", "landis-pc")
    assert r.returncode == 2 and "missing.ply" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.random.default_rng(0).random((10, 3))))
    o3d.io.write_point_cloud(str(tmp_path / "plain.ply"), pcd)
    r = _cli(tmp_path / "plain.ply", "--photo", HDRI, "-o", tmp_path / "o.ply", "--method", "landis-pc")
    assert r.returncode == 2 and "plain.ply" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    r = _cli(FRAGMENT, "--photo", tmp_path / "nophoto.hdr", "-o", tmp_path / "o.ply", "--method", "landis-pc")
    assert r.returncode == 2 and "nophoto.hdr" in r.stderr


def test_foxglove_export_tone_maps_radiance():
    import base64

    from probeless.bag.export import FOXGLOVE

    msg = HdrPointCloud(Header(stamp_ns=0, frame_id="world", seq=0), np.zeros((3, 3), np.float32),
                        np.array([[0, 0, 0], [1, 1, 1], [1000, 1000, 1000]], np.float32))
    schema, body = FOXGLOVE["mesh/HdrPointCloud"](msg, "cloud", None)
    assert schema == "foxglove.PointCloud"
    data = np.frombuffer(base64.b64decode(body["data"]), np.uint8).reshape(3, body["point_stride"])
    assert data[:, 12].tolist() == [0, 188, 255]  # Reinhard: 0, 0.5 (sRGB code 188), ~1


def test_read_cloud_takes_float_ply_colours_as_linear_radiance(tmp_path, capsys):
    """A PLY with `property double red` holds linear radiance: a lamp of 20 stays 20 (the legacy Open3D path read
    it as sRGB/255: 0.007), and `hdr expand`, which takes LDR clouds, refuses it naming the file and the count."""
    from probeless.cli import main

    rng = np.random.default_rng(1)
    pts = rng.random((50, 3))
    rad = rng.random((50, 3)) * 0.8
    rad[:3] = 20.0
    head = ("ply\nformat ascii 1.0\nelement vertex 50\nproperty float x\nproperty float y\nproperty float z\n"
            "property double red\nproperty double green\nproperty double blue\nend_header\n")
    body = "".join(" ".join(f"{v:.9g}" for v in (*p, *c)) + "\n" for p, c in zip(pts, rad))
    path = tmp_path / "lamp.ply"
    path.write_text(head + body)
    p, c, n = read_cloud(path)
    assert n is None and np.allclose(p, pts, atol=1e-6) and np.allclose(c, rad, rtol=1e-6)
    assert c.max() == pytest.approx(20.0)
    assert main(["hdr", "expand", str(path), "--photo", str(tmp_path / "photo.hdr"), "-o", str(tmp_path / "o.ply")])
    err = capsys.readouterr().err
    assert "lamp.ply: 3 point(s) have linear colours above 1 (up to 20)" in err and err.count("\n") == 1
