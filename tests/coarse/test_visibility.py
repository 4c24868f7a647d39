"""Visibility polygon of a floorplan (paper §4.4) against hand-worked rooms and a brute-force reference."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from locations import REPO

from probeless.coarse.visibility import (
    is_convex,
    visibility_polygon,
    visible_from,
)
from probeless.errors import GeometryError, ProbelessError
from probeless.geom.floorplan import check_floorplan
from probeless.geom.polygon import (
    contains,
    distance_to_boundary,
    self_intersection,
    signed_area,
)
from probeless.scene.parse import load_scene

SCENES = REPO / "launch" / "scenes"
L_ROOM = np.array([[0, 0], [6, 0], [6, 3], [3, 3], [3, 5], [0, 5]], float)
SETTINGS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def same_cycle(got: np.ndarray, want, atol: float = 1e-9) -> bool:
    """Same vertices in the same cyclic order, whichever vertex comes first."""
    want = np.asarray(want, float)
    return got.shape == want.shape and any(np.allclose(np.roll(got, -k, axis=0), want, atol=atol, rtol=0)
                                           for k in range(len(got)))


def check_against_reference(poly: np.ndarray, p, seed: int, samples: int = 400) -> np.ndarray:
    """Assert the visibility polygon's shape properties and that it agrees with :func:`visible_from`."""
    vis = visibility_polygon(poly, p)
    assert vis.dtype == np.float64 and vis.ndim == 2 and vis.shape[1] == 2 and len(vis) >= 3
    assert np.all(np.linalg.norm(vis - np.roll(vis, -1, axis=0), axis=1) > 1e-9), "repeated vertices"
    assert signed_area(vis) > 0, "not counter-clockwise"
    assert self_intersection(vis) is None, "not simple"
    mids = 0.5 * (vis + np.roll(vis, -1, axis=0))
    for q in (vis, mids):   # vertices and edge midpoints inside the room or on its walls
        assert np.all(contains(poly, q) | (distance_to_boundary(poly, q) < 1e-7))
    rng = np.random.default_rng(seed)
    lo, hi = poly.min(axis=0), poly.max(axis=0)
    q = rng.uniform(lo, hi, (samples, 2))
    assert np.all(contains(poly, q[contains(vis, q)]) | (distance_to_boundary(poly, q[contains(vis, q)]) < 1e-7))
    q = q[contains(poly, q) & (distance_to_boundary(vis, q) > 1e-6)]
    np.testing.assert_array_equal(contains(vis, q), visible_from(poly, p, q))
    return vis


# ---------------------------------------------------------------- rooms worked out by hand

def test_square_sees_itself_from_inside_edge_and_corner():
    square = np.array([[0, 0], [2, 0], [2, 2], [0, 2]], float)
    for p in ([0.5, 1.3], [1, 0], [2, 2], [0, 1.5]):
        assert same_cycle(visibility_polygon(square, p), square)
    assert is_convex(square)


@pytest.mark.parametrize("p, want", [
    # from the bottom arm the ray grazing the reflex corner (3, 3) goes on to (1, 5) on the top wall
    ((5, 1), [[0, 0], [6, 0], [6, 3], [3, 3], [1, 5], [0, 5]]),
    # from the top arm it goes on to (6, 1.5) on the right wall
    ((1, 4), [[0, 0], [6, 0], [6, 1.5], [3, 3], [3, 5], [0, 5]]),
    ((4.5, 0), [[0, 0], [6, 0], [6, 3], [3, 3], [2, 5], [0, 5]]),       # on the bottom wall
    ((3, 3), L_ROOM),                                                   # at the reflex corner: sees all
    ((1.5, 1.5), L_ROOM),                                               # in the kernel [0,3]^2: sees all
    ((6, 3), [[6, 3], [0, 3], [0, 0], [6, 0]]),                         # at a convex corner
    ((3, 4), [[3, 5], [0, 5], [0, 0], [3, 0]]),                         # on the inner wall x = 3
])
def test_l_shaped_room(p, want):
    vis = visibility_polygon(L_ROOM, p)
    assert same_cycle(vis, want), vis.tolist()
    check_against_reference(L_ROOM, p, seed=1)


STAIRS = np.array([[0, 0], [8, 0], [8, 2], [6, 2], [6, 4], [4, 4], [4, 6], [0, 6]], float)
# (room, an extra collinear vertex to insert after vertex 0, [(viewpoint, visibility polygon)]), by hand
TURNED_CASES = [
    (L_ROOM, [3, 0], [
        ((5, 1), [[0, 0], [6, 0], [6, 3], [3, 3], [1, 5], [0, 5]]),
        ((4.5, 2), [[0, 0], [6, 0], [6, 3], [3, 3], [0, 5]]),      # the grazing ray ends at the corner (0, 5)
        ((6, 1), [[6, 3], [3, 3], [0, 5], [0, 0], [6, 0]]),        # same from the wall (p is collinear: dropped)
        ((3, 3), L_ROOM), ((6, 3), [[6, 3], [0, 3], [0, 0], [6, 0]]),
        ((3, 4), [[3, 5], [0, 5], [0, 0], [3, 0]])]),              # the ray along x = 3 passes (3, 3)
    (STAIRS, [6, 0], [   # two steps: the ray along x + y = 8 grazes (6, 2) and (4, 4), both on one side
        ((7, 1), [[0, 0], [8, 0], [8, 2], [6, 2], [2, 6], [0, 6]]),
        ((8, 0), [[0, 0], [8, 0], [8, 2], [6, 2], [2, 6], [0, 6]]),
        ((7.5, 0.5), [[0, 0], [8, 0], [8, 2], [6, 2], [2, 6], [0, 6]]),
        ((6, 3), [[6, 4], [4, 4], [0, 6], [0, 0], [6, 0]]),       # grazes (4, 4) on to the corner (0, 6)
        ((5, 3), [[0, 0], [8, 0], [6, 2], [6, 4], [4, 4], [2, 6], [0, 6]])]),
]


@SETTINGS
@given(angle=st.floats(0, 2 * np.pi), shift=st.tuples(st.floats(-50, 50), st.floats(-50, 50)),
       first=st.integers(0, 8), extra=st.booleans())
@pytest.mark.slow
@example(angle=4.689386800826943, shift=(0.0, 0.0), first=3, extra=False)   # the first ray's vertices straddle 0 rad
def test_rooms_moved_and_turned(angle, shift, first, extra):
    """Rotated and shifted, rays through several vertices stop being exactly collinear in floating point.

    Any vertex may come first, and an extra collinear vertex may lie where a ray along a wall ends.
    """
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])

    def move(pts):
        return np.asarray(pts, float) @ rot.T + np.asarray(shift)

    for room, vertex, cases in TURNED_CASES:
        room = np.insert(room, 1, vertex, axis=0) if extra else room
        room = np.roll(room, -(first % len(room)), axis=0)
        for p, want in cases:
            assert same_cycle(visibility_polygon(move(room), move(p)), move(want), atol=1e-9)


def test_visible_from_reference_on_hand_cases():
    # a square room with a V notch cut into its top wall, reflex corner at (2, 1)
    notch = np.array([[0, 0], [4, 0], [4, 2], [3, 2], [2, 1], [1, 2], [0, 2]], float)
    p = (1, 2)
    q = np.array([[3, 2],        # over the notch: touches the walls only at its ends, outside between
                  [2.5, 0.2],    # passes below the reflex corner, inside
                  [3, 0],        # through the reflex corner (2, 1) exactly: still in the closed room
                  [3.5, 1.8],    # crosses the notch's right wall
                  [0, 2],        # along the top wall
                  [5, 1]])       # outside the room
    np.testing.assert_array_equal(visible_from(notch, p, q), [False, True, True, False, True, False])
    np.testing.assert_array_equal(contains(visibility_polygon(notch, p), q[[1, 3]]), [True, False])


def test_l_shaped_room_area_from_bottom_arm():
    # bottom arm 6 x 3 plus, in the top arm, the part left of x = 6 - y: integral_3^5 (6 - y) dy = 4
    assert signed_area(visibility_polygon(L_ROOM, (5, 1))) == pytest.approx(22.0, abs=1e-12)


def test_shipped_partition_room():
    poly = load_scene(SCENES / "partition_room.yaml").floorplan
    assert not is_convex(poly)
    # from (1, 1) the partition's top-left corner (2.95, 2.6) hides the right bay's lower part;
    # the grazing ray reaches y = 4.5 at x = 1 + 3.5 * 1.95 / 1.6
    assert same_cycle(visibility_polygon(poly, (1, 1)),
                      [[0, 0], [2.95, 0], [2.95, 2.6], [1 + 3.5 * 1.95 / 1.6, 4.5], [0, 4.5]])
    assert same_cycle(visibility_polygon(poly, (4.5, 1)),
                      [[3.05, 0], [6, 0], [6, 4.5], [4.5 - 3.5 * 1.45 / 1.6, 4.5], [3.05, 2.6]])
    # standing on the partition's top: only the strip y >= 2.6
    assert same_cycle(visibility_polygon(poly, (3, 2.6)), [[6, 2.6], [6, 4.5], [0, 4.5], [0, 2.6]])
    for i, p in enumerate([(1, 1), (4.5, 1), (3, 3.5), (2.95, 1.3), (3.05, 2.6), (0, 4.5), (5.2, 4.5), (2.9, 0.2)]):
        check_against_reference(poly, p, seed=i, samples=800)


def test_shipped_l_shaped_lounge_and_convex_room():
    poly = load_scene(SCENES / "l_shaped_lounge.yaml").floorplan
    assert not is_convex(poly)
    for i, p in enumerate([(5, 1), (1, 4), (3, 3), (0.2, 0.2), (6, 1.7), (2.5, 5), (4, 2.9)]):
        check_against_reference(poly, p, seed=10 + i, samples=800)
    assert is_convex(load_scene(SCENES / "convex_room.yaml").floorplan)


def test_is_convex():
    assert is_convex([[0, 0], [1, 0], [2, 0], [2, 1], [2, 2], [0, 2], [0, 1]])   # collinear vertices
    assert not is_convex([[0, 0], [2, 0], [2, 2], [1, 1.9], [0, 2]])             # a slight dent
    assert not is_convex(L_ROOM)


# ---------------------------------------------------------------- random rooms (hypothesis)

@st.composite
def star_rooms(draw, convex: bool = False):
    """Simple CCW polygons star-shaped from the origin (on a circle when ``convex``)."""
    n = draw(st.integers(3 if convex else 4, 24))
    gaps = np.array(draw(st.lists(st.floats(0.5, 1.0), min_size=n, max_size=n)))
    if convex:
        gaps[0] = min(gaps[0], 0.9 * (gaps.sum() - gaps[0]))   # every gap < pi keeps the origin inside
    radii = np.full(n, 1.5) if convex else np.array(draw(st.lists(st.floats(0.3, 2.0), min_size=n, max_size=n)))
    ang = draw(st.floats(0, 2 * np.pi)) + 2 * np.pi * np.cumsum(gaps) / gaps.sum()
    return np.c_[radii * np.cos(ang), radii * np.sin(ang)]


@st.composite
def orthogonal_rooms(draw):
    """x-monotone rectilinear rooms on a grid: a ragged floor below y = 0 and a ragged ceiling above.

    Grid coordinates make rays through several vertices at once, and equal neighbouring heights
    leave collinear vertices.
    """
    m = draw(st.integers(1, 7))
    x = np.concatenate([[0], np.cumsum(draw(st.lists(st.integers(1, 3), min_size=m, max_size=m)))])
    lo = draw(st.lists(st.integers(-3, -1), min_size=m, max_size=m))
    hi = draw(st.lists(st.integers(1, 3), min_size=m, max_size=m))
    pts = [(x[0], hi[0]), (x[0], lo[0])]
    for j in range(m):
        pts += [(x[j + 1], lo[j])] + ([(x[j + 1], lo[j + 1])] if j + 1 < m else [])
    pts.append((x[m], hi[m - 1]))
    for j in range(m - 1, 0, -1):
        pts += [(x[j], hi[j]), (x[j], hi[j - 1])]
    poly = np.array([q for i, q in enumerate(pts) if q != pts[i - 1]], float)
    poly *= draw(st.sampled_from([1.0, 0.5, 0.3]))
    if draw(st.booleans()):   # swap x and y: mirror image, so reverse to stay counter-clockwise
        poly = poly[::-1, ::-1].copy()
    return poly


@st.composite
def with_collinear(draw, rooms):
    """A room with extra vertices inserted on its edges (collinear up to rounding)."""
    poly = draw(rooms)
    for _ in range(draw(st.integers(1, 4))):
        i = draw(st.integers(0, len(poly) - 1))
        s = draw(st.sampled_from([0.5, 0.25]) | st.floats(0.05, 0.95))
        poly = np.insert(poly, i + 1, poly[i] + s * (poly[(i + 1) % len(poly)] - poly[i]), axis=0)
    return poly


@st.composite
def viewpoints(draw, poly: np.ndarray):
    """A viewpoint inside ``poly`` (random or at a grid point), on an edge, or at a vertex."""
    kind = draw(st.sampled_from(["inside", "grid", "edge", "vertex"]))
    i = draw(st.integers(0, len(poly) - 1))
    if kind == "vertex":
        return poly[i].copy()
    if kind == "edge":
        s = draw(st.sampled_from([0.5, 1 / 3]) | st.floats(0.01, 0.99))
        return poly[i] + s * (poly[(i + 1) % len(poly)] - poly[i])
    rng = np.random.default_rng(draw(st.integers(0, 2 ** 32 - 1)))
    lo, hi = poly.min(axis=0), poly.max(axis=0)
    q = rng.uniform(lo, hi, (200, 2))
    if kind == "grid":
        q = np.round(q * 2) / 2
    q = q[contains(poly, q)]
    return q[0] if len(q) else poly[i].copy()


rooms = st.one_of(star_rooms(), orthogonal_rooms(), with_collinear(star_rooms()), with_collinear(orthogonal_rooms()))


@pytest.mark.slow
@SETTINGS
@given(data=st.data(), poly=rooms, seed=st.integers(0, 2 ** 32 - 1))
def test_random_rooms_match_brute_force(data, poly, seed):
    check_floorplan(poly)
    p = data.draw(viewpoints(poly))
    check_against_reference(poly, p, seed)


@SETTINGS
@given(poly=st.one_of(star_rooms(), with_collinear(star_rooms())), seed=st.integers(0, 2 ** 32 - 1))
def test_star_room_seen_whole_from_its_centre(poly, seed):
    vis = check_against_reference(poly, (0.0, 0.0), seed, samples=100)
    assert signed_area(vis) == pytest.approx(signed_area(poly), rel=1e-9)


@SETTINGS
@given(data=st.data(), poly=st.one_of(star_rooms(convex=True), with_collinear(star_rooms(convex=True))),
       seed=st.integers(0, 2 ** 32 - 1))
def test_convex_room_seen_whole_from_anywhere(data, poly, seed):
    assert is_convex(poly)
    p = data.draw(viewpoints(poly))
    vis = check_against_reference(poly, p, seed, samples=100)
    assert signed_area(vis) == pytest.approx(signed_area(poly), rel=1e-9)


# ---------------------------------------------------------------- errors

@pytest.mark.parametrize("poly, match", [
    ([[0, 0], [1, 0]], "N >= 3"),
    ([[0, 0], [0, 1], [1, 1], [1, 0]], "counter-clockwise"),
    ([[0, 0], [1, 1], [1, 0], [0, 1]], "not simple"),                     # bow tie
    ([[0, 0], [2, 0], [2, 2], [1, 0], [0, 2]], "not simple"),             # a vertex touching an edge
    ([[0, 0], [1, 0], [1, 0], [1, 1]], "coincide"),
    ([[0, 0], [2, 0], [1, 0], [1, 1]], "folds back"),
    ([[0, 0], [np.nan, 0], [1, 1]], "non-finite"),
])
def test_invalid_floorplans(poly, match):
    for fn in (lambda: visibility_polygon(poly, (0.5, 0.2)), lambda: is_convex(poly)):
        with pytest.raises(GeometryError, match=match):
            fn()


def test_viewpoint_outside_or_malformed():
    with pytest.raises(GeometryError, match="outside the floorplan"):
        visibility_polygon(L_ROOM, (5, 4))          # in the missing quadrant of the L
    with pytest.raises(GeometryError, match="outside the floorplan"):
        visibility_polygon(L_ROOM, (-1e-6, 1))
    with pytest.raises(GeometryError, match="two finite numbers"):
        visibility_polygon(L_ROOM, (1, 2, 3))
    assert issubclass(GeometryError, ProbelessError)
    # within the tolerance (1e-9 of the room size) a viewpoint counts as on the wall
    assert same_cycle(visibility_polygon(L_ROOM, (-1e-12, 1)), L_ROOM)
