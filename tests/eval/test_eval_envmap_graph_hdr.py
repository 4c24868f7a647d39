"""Issue 27 / 29: ``probeless eval envmap --graph`` scores linear (HDR) maps, ``lighting:=hdr``'s, with the same
scores as LDR ones: read back from a recorded ``envmap/envmaps`` topic and scored against the linear truth."""

from __future__ import annotations

import numpy as np
import pytest

from probeless import wire
from probeless.bag.writer import BagWriter
from probeless.color import linear_to_srgb
from probeless.envmap.sh import irradiance_from_sh, project_cubemap
from probeless.errors import ProbelessError
from probeless.eval.envmap_graph import GraphRun, Truth, read_maps, score_runs
from probeless.geom.cube import cube_directions, cube_solid_angles
from probeless.messages.header import Header
from probeless.messages.lighting import Cubemap

S, STAMP, EXPOSURE = 16, 1_000, 0.5


def _truth() -> Truth:
    """A room with a lamp 40x brighter than the walls: the camera clips it (exposure 0.5)."""
    rng = np.random.default_rng(7)
    hdr = rng.uniform(0.2, 1.0, (6, S, S, 3)).astype(np.float32)
    hdr[4, 4:8, 4:8] = 40.0  # the lamp, on one face
    t = Truth()
    t.hdr["o", STAMP], t.exposure[STAMP] = hdr, np.full(3, EXPOSURE)
    t.ldr["o", STAMP] = linear_to_srgb(np.clip(hdr * EXPOSURE, 0, 1)).astype(np.float32)
    return t


def _record(path, faces: np.ndarray, linear: bool) -> None:
    cube = Cubemap(Header(STAMP, "world"), "o", np.zeros(3), faces, linear=linear,
                   observed=np.ones(faces.shape[:3], bool))
    with BagWriter(path) as w:
        w.write_frames(wire.encode("envmap/envmaps", cube, "test", STAMP), log_time_ns=STAMP)


def test_linear_maps_are_read_back_and_scored_against_the_linear_truth(tmp_path):
    truth = _truth()
    hdr_map = (truth.hdr["o", STAMP] * EXPOSURE).astype(np.float16)  # camera linear units, as lighting:=hdr sends
    ldr_map = (truth.ldr["o", STAMP] * 255 + 0.5).astype(np.uint8)   # the same room seen by the LDR camera
    _record(tmp_path / "hdr.mcap", hdr_map, linear=True)
    _record(tmp_path / "ldr.mcap", ldr_map, linear=False)
    runs = {}
    for name in ("hdr", "ldr"):
        maps, linear = read_maps(tmp_path / f"{name}.mcap")
        assert linear == (name == "hdr") and set(maps) == {("o", STAMP)}
        runs[name] = GraphRun(name, maps, None, linear)
    out = score_runs(runs, truth)
    hdr, ldr = out["hdr"]["o"], out["ldr"]["o"]
    # the HDR map is the truth (to float16): no diffuse error, no log error; its LDR view is the camera's
    assert hdr["sh_diffuse_error"] < 1e-3 and hdr["log_rmse_hdr"] < 1e-3 and hdr["psnr_common"] > 50
    # the LDR map loses the lamp: its diffuse error is that of the clipped radiance, computed here independently
    # on a fine set of normals (the SH of both maps: the irradiance of the clipped lamp vs the true one)
    normals = cube_directions(16).reshape(-1, 3)
    clipped = np.clip(truth.hdr["o", STAMP] * EXPOSURE, 0, 1) / EXPOSURE
    e, r = (irradiance_from_sh(project_cubemap(m, 3), normals) for m in (clipped, truth.hdr["o", STAMP]))
    w = cube_solid_angles(16).reshape(-1, 1)
    want = np.sqrt((w * (e - r) ** 2).sum() / (w * r * r).sum())
    assert ldr["sh_diffuse_error"] == pytest.approx(want, rel=0.02) and want > 0.3
    assert ldr["psnr_common"] > 40  # as LDR, both are right


def test_a_run_with_both_kinds_of_map_is_an_error(tmp_path):
    path = tmp_path / "mixed.mcap"
    with BagWriter(path) as w:
        for i, (faces, linear) in enumerate(((np.ones((6, S, S, 3), np.float16), True),
                                             (np.ones((6, S, S, 3), np.uint8), False))):
            cube = Cubemap(Header(STAMP + i, "world"), "o", np.zeros(3), faces, linear=linear)
            w.write_frames(wire.encode("envmap/envmaps", cube, "test", STAMP + i), log_time_ns=STAMP + i)
    with pytest.raises(ProbelessError, match="both linear"):
        read_maps(path)
