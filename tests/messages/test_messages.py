"""Schema checks of every message family, and the quaternion helpers against scipy."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from message_examples import EXAMPLES, examples, header

from probeless.errors import SchemaError
from probeless.geom.cube import texel_direction
from probeless.geom.rotation import (
    invert_transform,
    matrix_from_quat,
    quat_conjugate,
    quat_from_matrix,
    quat_multiply,
    quat_normalize,
    transform_from,
)
from probeless.messages import (
    CameraInfo,
    CubemapLevel,
    DepthImage,
    Image,
    PointCloud,
    TriangleMesh,
    registry,
    schema_of,
)

TYPE_NAMES = sorted(registry())
BAD_DTYPES = ("int64", "complex128", "int8", "float64", "bool")


def _array_fields(msg):
    return [s.name for s in schema_of(type(msg)) if s.kind == "array"]


def _strided(a: np.ndarray) -> np.ndarray:
    """A non-contiguous view with the same shape, dtype and values as ``a``."""
    big = np.zeros(a.shape + (2,), dtype=a.dtype)
    view = big[..., 0]
    view[...] = a
    return view


def _replace(msg, **changes):
    return dataclasses.replace(msg, **changes)


# ---------------------------------------------------------------- every registered type

def test_every_registered_type_has_an_example():
    assert set(EXAMPLES) == set(registry()), "add a factory to tests/message_examples.py"


@pytest.mark.parametrize("name", TYPE_NAMES)
def test_example_is_valid_and_registered(name):
    msg = examples()[name]
    assert type(msg) is registry()[name] and type(msg).TYPE_NAME == name and type(msg).VERSION >= 1
    for field in _array_fields(msg):
        assert getattr(msg, field).flags.c_contiguous
    with pytest.raises(dataclasses.FrozenInstanceError):
        msg.header = header()


@pytest.mark.parametrize("name", TYPE_NAMES)
def test_non_contiguous_and_big_endian_arrays_are_normalised(name):
    msg = EXAMPLES[name]()
    for field in _array_fields(msg):
        a = getattr(msg, field)
        if a.size > 1:
            view = _strided(a)
            assert not view.flags.c_contiguous
            got = getattr(_replace(msg, **{field: view}), field)
            assert got.flags.c_contiguous and got.dtype == a.dtype and np.array_equal(got, a, equal_nan=True)
        if a.dtype.itemsize > 1:
            got = getattr(_replace(msg, **{field: a.astype(a.dtype.newbyteorder(">"))}), field)
            assert got.dtype.isnative and np.array_equal(got, a, equal_nan=True)


@pytest.mark.parametrize("name", TYPE_NAMES)
def test_wrong_dtype_and_rank_raise(name):
    msg = EXAMPLES[name]()
    cls = type(msg).__name__
    for spec in schema_of(type(msg)):
        if spec.kind != "array":
            continue
        a = getattr(msg, spec.name)
        bad = next(d for d in BAD_DTYPES if d not in spec.array.dtypes)
        with pytest.raises(SchemaError, match=rf"{cls}\.{spec.name}"):
            _replace(msg, **{spec.name: a.astype(bad)})
        with pytest.raises(SchemaError, match=rf"{cls}\.{spec.name}"):
            _replace(msg, **{spec.name: a[None]})
        if a.ndim > 1:
            with pytest.raises(SchemaError, match=rf"{cls}\.{spec.name}"):
                _replace(msg, **{spec.name: a.reshape(-1)})
        with pytest.raises(SchemaError, match=rf"{cls}\.{spec.name}"):
            _replace(msg, **{spec.name: a.tolist()})


@pytest.mark.parametrize("name", TYPE_NAMES)
def test_wrong_scalar_types_raise(name):
    msg = EXAMPLES[name]()
    for spec in schema_of(type(msg)):
        if spec.kind != "array":
            with pytest.raises(SchemaError, match=rf"{type(msg).__name__}\.{spec.name}"):
                _replace(msg, **{spec.name: object()})


# ---------------------------------------------------------------- sensor

def test_image_encoding_must_match_dtype_and_channels():
    img = EXAMPLES["sensor/Image"]()
    assert (img.height, img.width, img.channels) == (4, 6, 3)
    with pytest.raises(SchemaError, match=r"Image\.encoding"):
        _replace(img, data=img.data.astype(np.uint16))          # rgb8 needs uint8
    with pytest.raises(SchemaError, match=r"Image\.encoding"):
        _replace(img, encoding="mono8")                          # 3 channels
    with pytest.raises(SchemaError, match=r"Image\.encoding"):
        _replace(img, encoding="yuv422")
    mono = Image(header("rgbd"), np.zeros((4, 6, 1), np.uint16), "mono16")
    assert mono.channels == 1
    with pytest.raises(SchemaError, match=r"Image\.data"):
        Image(header("rgbd"), np.zeros((4, 6), np.uint8), "mono8")  # mono is rank 3 too
    Image(header("rgbd"), np.zeros((2, 2, 3), np.float32), "rgbf32")
    Image(header("rgbd"), np.zeros((2, 2, 4), np.uint8), "bgra8")


def test_depth_image():
    d = EXAMPLES["sensor/DepthImage"]()
    assert np.allclose(d.metres(), d.data / 1000.0)
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(SchemaError, match=r"DepthImage\.depth_scale"):
            _replace(d, depth_scale=bad)
    f = DepthImage(header("rgbd"), np.array([[1.5, np.nan]], np.float32), 1.0)
    assert f.metres().tolist() == [[1.5, 0.0]]
    with pytest.raises(SchemaError, match=r"DepthImage\.data"):
        DepthImage(header("rgbd"), np.zeros((2, 2), np.float64), 1.0)


def test_camera_info_validation():
    c = EXAMPLES["sensor/CameraInfo"]()
    assert c.ocam_poly.shape == (0,) and c.ocam_affine.tolist() == [1.0, 0.0, 0.0]
    with pytest.raises(SchemaError, match=r"CameraInfo\.model"):
        _replace(c, model="fisheye")
    with pytest.raises(SchemaError, match=r"CameraInfo\.width"):
        _replace(c, width=0)
    with pytest.raises(SchemaError, match=r"CameraInfo\.D"):
        _replace(c, model="kannala_brandt", xi=0.0, D=np.zeros(5))
    with pytest.raises(SchemaError, match=r"CameraInfo\.xi"):
        _replace(c, model="pinhole")                             # xi only for omnidir
    with pytest.raises(SchemaError, match=r"CameraInfo\.K"):
        _replace(c, K=np.zeros((3, 3)))
    with pytest.raises(SchemaError, match=r"CameraInfo\.K"):
        _replace(c, K=np.full((3, 3), np.nan))
    with pytest.raises(SchemaError, match=r"CameraInfo\.ocam_poly"):
        _replace(c, model="ocam", xi=0.0, D=np.zeros(0))
    ocam = _replace(c, model="ocam", xi=0.0, D=np.zeros(0), ocam_poly=np.array([-300.0, 0.0, 1e-3]),
                    ocam_invpoly=np.array([400.0, 200.0, 10.0]), ocam_center=np.array([240.0, 320.0]))
    assert ocam.ocam_poly[0] == -300.0
    # defaults are fresh arrays, not shared between instances
    assert CameraInfo(header(), 1, 1, "pinhole", np.eye(3)).D is not CameraInfo(header(), 1, 1, "pinhole", np.eye(3)).D


# ---------------------------------------------------------------- geometry

def test_pose_stamped_properties():
    p = EXAMPLES["geometry/PoseStamped"]()
    assert np.allclose(p.rotation, matrix_from_quat(np.array([0.1, -0.2, 0.3, 0.9])))
    assert p.translation.tolist() == [1.0, 2.0, 1.5]
    assert np.allclose(p.quaternion, quat_normalize(np.array([0.1, -0.2, 0.3, 0.9])))
    T = p.target_from_source
    assert np.allclose(invert_transform(T) @ T, np.eye(4)) and np.allclose(invert_transform(T), np.linalg.inv(T))


@pytest.mark.parametrize("mutate, match", [
    (lambda T: T.__setitem__((0, 3), np.nan), "NaN"),
    (lambda T: T.__setitem__((1, 1), np.inf), "NaN"),
    (lambda T: T.__setitem__((3, 0), 0.5), "last row"),
    (lambda T: T.__setitem__((slice(0, 3), 0), T[:3, 0] * 1.01), "orthonormal"),
    (lambda T: T.__setitem__((slice(0, 3), 0), -T[:3, 0]), "orthonormal"),       # reflection, det -1
])
def test_pose_stamped_rejects_invalid_transforms(mutate, match):
    p = EXAMPLES["geometry/PoseStamped"]()
    T = p.target_from_source.copy()
    mutate(T)
    with pytest.raises(SchemaError, match=rf"PoseStamped\.target_from_source: invalid pose.*{match}"):
        _replace(p, target_from_source=T)


def test_floorplan():
    f = EXAMPLES["geometry/Floorplan"]()
    assert f.area == pytest.approx(12.0)
    with pytest.raises(SchemaError, match=r"Floorplan\.vertices: .*clockwise"):
        _replace(f, vertices=f.vertices[::-1])
    with pytest.raises(SchemaError, match=r"Floorplan\.vertices: .*clockwise"):
        _replace(f, vertices=np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]]))      # degenerate
    with pytest.raises(SchemaError, match=r"Floorplan\.vertices: need at least 3"):
        _replace(f, vertices=f.vertices[:2])
    with pytest.raises(SchemaError, match=r"Floorplan\.vertices: contains NaN"):
        _replace(f, vertices=np.where(np.eye(4, 2, dtype=bool), np.nan, f.vertices))
    for bad in (0.0, -2.0, float("nan")):
        with pytest.raises(SchemaError, match=r"Floorplan\.ceiling_height"):
            _replace(f, ceiling_height=bad)


# ---------------------------------------------------------------- mesh

def test_point_cloud_rows_must_agree():
    pc = EXAMPLES["mesh/PointCloud"]()
    assert len(pc) == 5
    with pytest.raises(SchemaError, match=r"PointCloud\.colors: dimension 'n'"):
        _replace(pc, colors=pc.colors[:4])
    with pytest.raises(SchemaError, match=r"PointCloud\.normals"):
        _replace(pc, normals=pc.normals[:3])
    bare = PointCloud(header("rgbd"), pc.points, np.ones((5, 3), np.float32))
    assert bare.normals.shape == (0, 3)
    with pytest.raises(SchemaError, match=r"PointCloud\.colors"):
        _replace(pc, colors=pc.colors[:, :2])


def test_triangle_mesh_validation():
    m = EXAMPLES["mesh/TriangleMesh"]()
    with pytest.raises(SchemaError, match=r"TriangleMesh\.triangles: index out of range"):
        _replace(m, triangles=np.array([[0, 1, 4]], np.int32))
    with pytest.raises(SchemaError, match=r"TriangleMesh\.triangles: index out of range"):
        _replace(m, triangles=np.array([[0, -1, 2]], np.int32))
    _replace(m, triangles=m.triangles.astype(np.uint32))
    for field in ("vertex_colors", "vertex_normals", "uvs"):
        with pytest.raises(SchemaError, match=rf"TriangleMesh\.{field}"):
            _replace(m, **{field: getattr(m, field)[:3]})
    bare = TriangleMesh(header(), m.vertices, np.zeros((0, 3), np.int32))
    assert bare.uvs.shape == (0, 2) and bare.vertex_colors.shape == (0, 3)


# ---------------------------------------------------------------- lighting

def test_cubemap_validation():
    c = EXAMPLES["lighting/Cubemap"]()
    assert c.size == 4
    with pytest.raises(SchemaError, match=r"Cubemap\.faces: dimension 's'"):
        _replace(c, faces=c.faces[:, :, :3])                     # not square
    with pytest.raises(SchemaError, match=r"Cubemap\.faces"):
        _replace(c, faces=c.faces[:5])
    with pytest.raises(SchemaError, match=r"Cubemap\.faces: expected 3"):
        _replace(c, faces=c.faces[..., :2])
    with pytest.raises(SchemaError, match=r"Cubemap\.position"):
        _replace(c, position=np.array([0.0, np.nan, 0.0]))
    with pytest.raises(SchemaError, match=r"Cubemap\.mips\[0\]\.faces"):
        _replace(c, mips=(CubemapLevel(0.5, c.mips[0].faces.astype(np.float32)),))
    with pytest.raises(SchemaError, match=r"Cubemap\.mips\[1\]\.roughness"):
        _replace(c, mips=c.mips[::-1])
    with pytest.raises(SchemaError, match=r"CubemapLevel\.faces"):
        CubemapLevel(0.5, np.zeros((6, 2, 3, 3), np.float16))
    level = CubemapLevel(0.5, _strided(c.mips[0].faces))
    assert level.faces.flags.c_contiguous


def test_cubemap_texel_direction_matches_opengl_lookup():
    """Invert the OpenGL face-selection table and check every texel maps back to itself."""
    size = 5
    rows, cols = np.meshgrid(np.arange(size), np.arange(size), indexing="ij")
    for face in range(6):
        d = texel_direction(face, rows, cols, size)
        x, y, z = np.moveaxis(d, -1, 0)
        axis = np.argmax(np.abs(d), axis=-1)
        sign = np.take_along_axis(d, axis[..., None], -1)[..., 0] > 0
        assert np.all(axis * 2 + (~sign) == face)
        sc, tc, ma = {0: (-z, -y, x), 1: (z, -y, -x), 2: (x, z, y),
                      3: (x, -z, -y), 4: (x, -y, z), 5: (-x, -y, -z)}[face]
        s, t = (sc / ma + 1) / 2, (tc / ma + 1) / 2
        assert np.allclose(s * size - 0.5, cols) and np.allclose(t * size - 0.5, rows)
    assert np.allclose(texel_direction(4, 2, 2, 5), [0, 0, 1])  # +Z face centre looks up (z-up world)


def test_sh_rows_must_equal_bands_squared():
    sh = EXAMPLES["lighting/SHCoefficients"]()
    with pytest.raises(SchemaError, match=r"SHCoefficients\.coeffs: 8 rows"):
        _replace(sh, coeffs=sh.coeffs[:8])
    with pytest.raises(SchemaError, match=r"SHCoefficients\.coeffs"):
        _replace(sh, bands=5)
    _replace(sh, bands=5, coeffs=np.zeros((25, 3)))
    with pytest.raises(SchemaError, match=r"SHCoefficients\.bands"):
        _replace(sh, bands=0, coeffs=np.zeros((0, 3)))


def test_brightness_delta():
    b = EXAMPLES["lighting/BrightnessDelta"]()
    with pytest.raises(SchemaError, match=r"BrightnessDelta\.delta"):
        _replace(b, delta=np.array([np.nan, 0, 0], np.float32))
    with pytest.raises(SchemaError, match=r"BrightnessDelta\.texels_used"):
        _replace(b, texels_used=-1)


# ---------------------------------------------------------------- quaternion helpers

def _special_rotations(Rotation):
    """Random rotations plus the awkward ones: identity, 180 degrees about axes and diagonals."""
    rng = np.random.default_rng(7)
    rots = list(Rotation.random(200, random_state=rng))
    axes = np.vstack([np.eye(3), [[1, 1, 0], [1, -1, 0], [0, 1, 1], [1, 1, 1], [-1, 2, 3]],
                      rng.standard_normal((20, 3))])
    for ax in axes:
        ax = ax / np.linalg.norm(ax)
        rots += [Rotation.from_rotvec(np.pi * ax), Rotation.from_rotvec((np.pi - 1e-9) * ax),
                 Rotation.from_rotvec(1e-9 * ax)]
    return rots + [Rotation.identity()]


def test_quaternions_match_scipy():
    from scipy.spatial.transform import Rotation
    rots = _special_rotations(Rotation)
    for r in rots:
        R = r.as_matrix()
        q = quat_from_matrix(R)
        ref = r.as_quat()
        assert q[3] >= 0
        assert np.allclose(q, ref, atol=1e-12) or np.allclose(q, -ref, atol=1e-12)
        assert np.allclose(matrix_from_quat(q), R, atol=1e-12)
        assert np.allclose(matrix_from_quat(ref), R, atol=1e-12)
    # batched versions agree with the loop
    Rs = np.stack([r.as_matrix() for r in rots])
    assert np.allclose(matrix_from_quat(quat_from_matrix(Rs)), Rs, atol=1e-12)
    # composition: q_a * q_b rotates by b first, then a
    rng = np.random.default_rng(3)
    a, b = Rotation.random(50, random_state=rng), Rotation.random(50, random_state=rng)
    qab = quat_multiply(a.as_quat(), b.as_quat())
    assert np.allclose(matrix_from_quat(qab), (a * b).as_matrix(), atol=1e-12)
    assert np.allclose(matrix_from_quat(quat_conjugate(a.as_quat())), a.inv().as_matrix(), atol=1e-12)


def test_quaternion_helpers_without_scipy():
    q = quat_normalize(np.array([1.0, 2.0, 3.0, 4.0]))
    assert np.allclose(quat_multiply(q, quat_conjugate(q)), [0, 0, 0, 1])
    assert quat_from_matrix(np.diag([1.0, -1.0, -1.0])).tolist() == [1.0, 0.0, 0.0, 0.0]  # 180 deg about x
    with pytest.raises(Exception, match="zero-norm"):
        quat_normalize(np.zeros(4))
    T = transform_from(matrix_from_quat(q), np.array([1.0, -2.0, 3.0]))
    assert T.shape == (4, 4) and T.dtype == np.float64 and T[3].tolist() == [0, 0, 0, 1]
    assert np.allclose(invert_transform(T), np.linalg.inv(T))
    Ts = np.stack([T, invert_transform(T)])
    assert np.allclose(invert_transform(Ts)[0], Ts[1])
