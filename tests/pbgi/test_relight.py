"""Per-frame relighting (probeless.pbgi.relight): reduced-size rendering and per-object far fields."""

from __future__ import annotations

import numpy as np
import pytest

from probeless.coarse.view import look_at
from probeless.errors import PbgiError
from probeless.pbgi.relight import Relighter, pbgi_objects, pbgi_objects_problem, scaled_camera

K = np.array([[200.0, 0, 99.5], [0, 200.0, 74.5], [0, 0, 1]])
BALL = {"id": "ball", "mesh": "sphere", "position": [0.0, 0.0, 0.0], "radius": 0.3,
        "material": {"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}}


def test_scaled_camera_keeps_pixel_centres_where_they_were():
    K2, w, h = scaled_camera(K, 200, 150, 50)
    assert (w, h) == (50, 38) or (w, h) == (50, 37)
    p = np.array([0.3, -0.2, 2.0])
    u, u2 = K @ p / p[2], K2 @ p / p[2]
    np.testing.assert_allclose(u2[:2], (u[:2] + 0.5) * np.array([w / 200, h / 150]) - 0.5, atol=1e-9)
    assert scaled_camera(K, 200, 150, 0)[1:] == (200, 150) and scaled_camera(K, 200, 150, 400)[1:] == (200, 150)


@pytest.mark.gl
def test_a_reduced_render_upscaled_matches_the_full_size_one():
    r = Relighter(pbgi_objects([BALL, dict(BALL, id="small", position=[0.8, 0.0, 0.0], radius=0.2)]), mode="envmap",
                  micro=16)
    try:
        faces = np.ones((6, 8, 8, 3), np.float32)
        faces[4] = 3.0  # a brighter ceiling
        r.set_envmap("ball", faces)
        with pytest.raises(PbgiError, match="no cloud yet"):  # the second object has no far field yet
            r.render(K, look_at(np.array([0.0, -2.0, 0.5]), np.zeros(3)), 200, 150)
        r.set_envmap("small", np.full((6, 8, 8, 3), 0.2, np.float32))
        pose = look_at(np.array([0.4, -2.0, 0.5]), np.array([0.4, 0.0, 0.0]))
        full, small = r.render(K, pose, 200, 150), r.render(K, pose, 200, 150, max_width=100)
    finally:
        r.release()
    assert small.mask.shape == full.mask.shape and len(full.stats) == 2
    iou = (small.mask & full.mask).sum() / (small.mask | full.mask).sum()
    assert iou > 0.95
    both = small.mask & full.mask
    assert np.median(np.abs(small.color[both] - full.color[both])) < 0.02
    assert np.isinf(small.depth[~small.mask]).all() and np.isfinite(small.depth[small.mask]).all()
    # each object got its own far field: the ball (lit 1..3) is brighter than the small one (0.2)
    ball, small_ = full.color[:, :100][full.mask[:, :100]], full.color[:, 120:][full.mask[:, 120:]]
    assert ball.mean() > 3 * small_.mean()


def test_objects_rule_adds_the_brdf_check_to_the_compositors():
    assert pbgi_objects_problem([BALL]) is None
    assert "glass" in pbgi_objects_problem([dict(BALL, material={"type": "glass"})])
    assert "unique" in pbgi_objects_problem([BALL, BALL])
