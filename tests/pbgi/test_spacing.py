"""The BSH voxel default, :func:`probeless.pbgi.bsh.point_spacing`, against the spacing clouds were built with."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from probeless.pbgi.bsh import build_bsh, point_spacing
from probeless.pbgi.room import reference_room, sample_cloud


def tilted_grid(spacing: float, n_side: int, jitter: bool = False, seed: int = 0) -> np.ndarray:
    """An n_side^2 grid of ``spacing`` [m] in a randomly turned plane (more points than point_spacing samples)."""
    rng = np.random.default_rng(seed)
    g = np.arange(n_side) * spacing
    x, y = np.meshgrid(g, g)
    uv = np.stack([x.ravel(), y.ravel()], 1)
    if jitter:
        uv += rng.uniform(-0.5, 0.5, uv.shape) * spacing
    pts = np.c_[uv, np.zeros(len(uv))]
    return Rotation.random(random_state=seed).apply(pts) + rng.normal(size=3)


@pytest.mark.parametrize("spacing", [0.004, 0.01, 0.03])
def test_regular_grids_within_20_percent(spacing):
    assert point_spacing(tilted_grid(spacing, 300)) == pytest.approx(spacing, rel=0.2)


def test_jittered_grid_and_random_points_within_20_percent():
    assert point_spacing(tilted_grid(0.01, 300, jitter=True)) == pytest.approx(0.01, rel=0.2)
    rng = np.random.default_rng(3)
    n = 120_000
    pts = np.c_[rng.random((n, 2)) * 2.0, np.zeros(n)]  # 4 m^2: sqrt(area per point)
    assert point_spacing(pts) == pytest.approx(np.sqrt(4.0 / n), rel=0.2)


def test_room_cloud_at_2_cm_and_the_bsh_voxel():
    """The issue's case (a room sampled on a grid; 0.0041 was reported for 1 cm), and what build_bsh reports."""
    room = reference_room("red_wall")
    for jitter in (False, True):
        pts, col, nrm = sample_cloud(room, 0.02, jitter=jitter)
        assert point_spacing(pts) == pytest.approx(0.02, rel=0.2)
    report = build_bsh(pts, col, nrm).report
    assert report.spacing == pytest.approx(0.02, rel=0.2)
    assert 0.3 * report.spacing < report.voxel < 0.5 * report.spacing  # one point per leaf (bsh.VOXEL_PER_SPACING)
