"""Decals a few millimetres in front of their wall light a sphere as coplanar ones do (issue 27, "decals and steps").

A red wall 85 cm from a white Lambert sphere carries a pale striped poster and a bright switch plate, either cut
into the wall (coplanar) or 0.5 / 1 / 5 mm in front of it (the wall behind them not in the cloud, as in a scan).
The truth moves by far less than 1 % (checked here by summing every point's contribution to the irradiance of the
sphere's pixels, brute force, no rasterisation); PBGI must move by less than 1 % too. Before the fix the nearer
disks covered the wall beyond the decals' edges and the sphere came out up to 7 % brighter (5 mm).
"""

from __future__ import annotations

import numpy as np
import pytest

from probeless.color import luminance

pytestmark = [pytest.mark.gl, pytest.mark.slow]  # ~15 s on 2 idle cores: 4 hierarchies, renders, point sums
SPACING = 0.01          # [m], the 1 cm grid
CENTRE, RADIUS = np.zeros(3), 0.15
WALL_X = 1.0            # wall plane x [m], facing -x: far enough that a 5 mm step moves the truth by < 0.5 %
RED, POSTER, PLATE = (1.8, 0.1, 0.1), (1.3, 1.2, 0.85), (6.0, 6.0, 5.5)
SIZE = 32


def scene(offset: float):
    """(points, radiance, normals) of the wall with its two decals ``offset`` [m] in front (towards -x)."""
    g = (np.arange(-100, 100) + 0.5) * SPACING
    y, z = np.meshgrid(g, g)
    y, z = y.ravel(), z.ravel()
    poster = (np.abs(y + 0.1) < 0.4) & (np.abs(z - 0.1) < 0.4)
    plate = (np.abs(y - 0.55) < 0.05) & (np.abs(z + 0.05) < 0.07)
    rad = np.tile(np.asarray(RED, np.float64), (len(y), 1))
    rad[poster] = np.asarray(POSTER) * (1 + 0.25 * np.sin(2 * np.pi * (y[poster] + z[poster]) / 0.08))[:, None]
    rad[plate] = PLATE
    x = np.full(len(y), WALL_X) - offset * (poster | plate)
    normals = np.tile([-1.0, 0.0, 0.0], (len(y), 1))
    return np.stack([x, y, z], 1), rad.astype(np.float32), normals


@pytest.fixture(scope="module")
def renders():
    from probeless.ibl.mesh_io import place, uv_sphere
    from probeless.pbgi.bsh import build_bsh
    from probeless.pbgi.materials import Brdf
    from probeless.pbgi.render import PbgiObject, PbgiRenderer
    from probeless.scene.trajectory import look_at

    mesh = place(*uv_sphere(), CENTRE, radius=RADIUS)
    f = SIZE / 2 / np.tan(np.arcsin(RADIUS / 0.9) * 1.1)
    K = np.array([[f, 0, (SIZE - 1) / 2], [0, f, (SIZE - 1) / 2], [0, 0, 1.0]])
    pose = look_at(np.array([0.5, -0.75, 0.2]), CENTRE)  # sees the side of the sphere the wall lights
    r = PbgiRenderer([PbgiObject("ball", mesh, Brdf("lambert", (1.0, 1.0, 1.0)))], micro=24)
    out = {}
    try:
        for offset in (0.0, 0.0005, 0.001, 0.005):
            r.set_cloud(build_bsh(*scene(offset)))
            res = r.render(K, pose, SIZE, SIZE)
            out[offset] = (res.color, res.mask, res.gbuffer)
    finally:
        r.release()
    return out


def brute_force_radiance(offset: float, position: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Lambert (albedo 1) radiance (M, 3) at surface points: every cloud point a SPACING^2 emitting square."""
    pts, rad, nrm = (a.astype(np.float32) for a in scene(offset))
    v = pts[None] - position[:, None].astype(np.float32)
    d2 = (v * v).sum(-1)
    cos_r = np.clip((v * normal[:, None].astype(np.float32)).sum(-1), 0, None)
    cos_e = np.clip(-(v @ nrm[0]), 0, None)  # one wall normal
    return (cos_r * cos_e / d2 ** 2 * (SPACING ** 2 / np.pi)) @ rad


@pytest.fixture(scope="module")
def truth(renders):
    """Brute-force luminance at every 10th sphere pixel of the coplanar render, per offset."""
    _, m0, g = renders[0.0]
    pos, nrm = g.position[m0][::10].astype(np.float64), g.normal[m0][::10].astype(np.float64)
    return {o: luminance(brute_force_radiance(o, pos, nrm)).astype(np.float64) for o in renders}


@pytest.mark.parametrize("offset", [0.0005, 0.001, 0.005])
def test_decals_in_front_of_the_wall_render_like_coplanar_ones(renders, truth, offset):
    c0, m0, _ = renders[0.0]
    c1, m1, _ = renders[offset]
    both = m0 & m1
    assert both.sum() > 0.5 * SIZE * SIZE * 0.6
    y0, y1 = luminance(c0[both]).astype(np.float64), luminance(c1[both]).astype(np.float64)
    rel = np.sqrt(np.mean((y1 - y0) ** 2) / np.mean(y0 ** 2))
    # the truth, brute force over the points: the step changes the lighting by far less than the goal
    t0, t1 = truth[0.0], truth[offset]
    assert np.sqrt(np.mean((t1 - t0) ** 2) / np.mean(t0 ** 2)) < 0.005
    assert rel < 0.01, f"{offset * 1000:g} mm decals: PBGI image {rel:.2%} from the coplanar one"
    assert abs(y1.mean() / y0.mean() - t1.mean() / t0.mean()) < 0.005  # brightness moves as the truth's


def test_pbgi_agrees_with_the_brute_force_sum(renders, truth):
    """The scene is lit as the point sum says (so the comparison above is of a working render)."""
    c0, m0, _ = renders[0.0]
    ours = luminance(c0[m0][::10]).astype(np.float64)
    lit = truth[0.0] > 0.05 * truth[0.0].max()
    assert abs(ours[lit].mean() / truth[0.0][lit].mean() - 1) < 0.05
