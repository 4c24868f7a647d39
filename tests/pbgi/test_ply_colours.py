"""PLY colours by declared type (``probeless pbgi render``'s reader): float/double = linear radiance, uchar = sRGB,
anything else refused naming the property. PLYs are written here by hand with numpy, in the PLY layout."""

from __future__ import annotations

import numpy as np
import pytest

from probeless.cli import main
from probeless.errors import PbgiError
from probeless.pbgi.cloud import read_cloud_file

TYPES = {"float": "<f4", "double": "<f8", "uchar": "u1", "ushort": "<u2", "short": "<i2", "int": "<i4"}
RADIANCE = np.array([[20.0, 18.0, 15.0], [0.5, 0.25, 0.125], [1e-3, 2.0, 0.0]])  # a lamp of 20 among walls


def write_ply(path, colours, types=("float", "float", "float"), ascii_=False, xyz="float"):
    n = len(colours)
    pts = np.arange(3 * n, dtype=np.float64).reshape(n, 3) * 0.01
    names = ["x", "y", "z", "red", "green", "blue"]
    kinds = [xyz] * 3 + list(types)
    dt = np.dtype([(nm, TYPES[k]) for nm, k in zip(names, kinds)])
    v = np.zeros(n, dt)
    for i, nm in enumerate("xyz"):
        v[nm] = pts[:, i]
    for i, nm in enumerate(("red", "green", "blue")):
        v[nm] = colours[:, i]
    fmt = "ascii" if ascii_ else "binary_little_endian"
    header = ["ply", f"format {fmt} 1.0", f"element vertex {n}"]
    header += [f"property {k} {nm}" for nm, k in zip(names, kinds)] + ["end_header"]
    body = ("\n".join(" ".join(str(x) for x in row) for row in v.tolist()) + "\n").encode() if ascii_ else v.tobytes()
    path.write_bytes(("\n".join(header) + "\n").encode() + body)
    return path


def iec_srgb_decode(code):  # IEC 61966-2-1, written out independently of probeless.color
    c = np.asarray(code, np.float64) / 255.0
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


@pytest.mark.parametrize("kind", ["float", "double"])
@pytest.mark.parametrize("ascii_", [False, True])
def test_float_and_double_colours_are_linear_radiance(tmp_path, kind, ascii_):
    path = write_ply(tmp_path / "hdr.ply", RADIANCE, (kind,) * 3, ascii_=ascii_, xyz="double")
    points, radiance, normals = read_cloud_file(path)
    np.testing.assert_allclose(radiance, RADIANCE, rtol=1e-6)  # the lamp stays 20, not 20/255 or clipped
    assert points.shape == (3, 3) and normals is None


def test_uchar_colours_are_srgb_codes(tmp_path):
    codes = np.array([[255, 128, 0], [10, 200, 64], [1, 2, 3]])
    _, radiance, _ = read_cloud_file(write_ply(tmp_path / "ldr.ply", codes, ("uchar",) * 3))
    np.testing.assert_allclose(radiance, iec_srgb_decode(codes), rtol=1e-5, atol=1e-7)
    assert radiance[0, 1] == pytest.approx(0.2158605, rel=1e-5)  # code 128, the published value


@pytest.mark.parametrize("types, prop, what", [
    (("ushort", "ushort", "ushort"), "red", "ushort"),
    (("float", "short", "float"), "green", "short"),
    (("float", "float", "uchar"), "blue", "uchar"),   # a mixture: linear or sRGB?
    (("uchar", "int", "uchar"), "green", "int"),
])
def test_ambiguous_colour_types_are_refused_naming_the_property(tmp_path, types, prop, what):
    path = write_ply(tmp_path / "odd.ply", np.ones((3, 3)), types)
    with pytest.raises(PbgiError) as err:
        read_cloud_file(path)
    assert f"'{prop}'" in str(err.value) and what in str(err.value) and "odd.ply" in str(err.value)


def test_render_refuses_an_ambiguous_cloud_with_a_clear_error(tmp_path, capsys):
    path = write_ply(tmp_path / "scan.ply", np.ones((3, 3)) * 1000, ("ushort",) * 3)
    assert main(["pbgi", "render", str(path), "-o", str(tmp_path / "x.png"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and "'red'" in err and "ushort" in err
