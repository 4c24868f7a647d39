"""Bounding sphere hierarchy (paper 001 §5.1): each property checked against an independent reference."""

from __future__ import annotations

import math

import numpy as np
import pytest

from probeless.errors import PbgiError
from probeless.pbgi import bsh
from probeless.pbgi import bsh_kernels as k

TOL = 1e-5


def ref_morton(x: int, y: int, z: int) -> int:
    code = 0
    for b in range(21):
        code |= ((x >> b) & 1) << (3 * b + 2) | ((y >> b) & 1) << (3 * b + 1) | ((z >> b) & 1) << (3 * b)
    return code


def ref_tree(codes: list[int]) -> tuple[list[int], list[int]]:
    """Radix tree by recursive split at the highest differing bit; Karras' numbering (the inner node of a range is
    named by the split of its parent: left child = split, right child = split + 1; leaves n - 1 + j)."""
    n = len(codes)
    left, right = [None] * (n - 1), [None] * (n - 1)

    def rec(lo: int, hi: int, idx: int) -> None:
        bit = (codes[lo] ^ codes[hi]).bit_length() - 1
        m = max(i for i in range(lo, hi + 1) if not (codes[i] >> bit) & 1)
        left[idx] = n - 1 + lo if m == lo else m
        right[idx] = n - 1 + hi if m + 1 == hi else m + 1
        if m > lo:
            rec(lo, m, m)
        if m + 1 < hi:
            rec(m + 1, hi, m + 1)

    if n > 1:
        rec(0, n - 1, 0)
    return left, right


def leaf_ranges(tree: bsh.Bsh) -> np.ndarray:
    """(first, last) leaf index under every node, by recursion over left/right."""
    nl = tree.codes.shape[0]
    out = np.zeros((2 * nl - 1, 2), np.int64)

    def rec(v: int) -> tuple[int, int]:
        if v >= nl - 1:
            out[v] = v - (nl - 1)
        else:
            a, b = rec(int(tree.left[v])), rec(int(tree.right[v]))
            out[v] = (a[0], b[1])
        return tuple(out[v])

    rec(0)
    return out


def sphere_cloud(n: int, seed: int):
    """Points in a unit box with colours and normals spread over a hemisphere-ish range (varied cones)."""
    rng = np.random.default_rng(seed)
    pts = rng.random((n, 3))
    col = rng.random((n, 3))
    nrm = rng.normal(0, 1, (n, 3)) + np.array([0, 0, 1.5])
    return pts, col, nrm


def test_morton_codes_hand_made():
    cells = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (3, 5, 7), (2**21 - 1, 0, 2**20), (12345, 2**21 - 1, 777)]
    pts = np.array(cells, np.float64) + 0.5
    codes = k.morton_codes(pts, np.zeros(3), 1.0)
    assert [int(c) for c in codes] == [ref_morton(*c) for c in cells]
    assert int(codes[1]) == 4 and int(codes[2]) == 2 and int(codes[3]) == 1


def test_leaf_codes_of_a_build_are_the_sorted_unique_cells():
    rng = np.random.default_rng(3)
    pts = rng.integers(0, 40, (500, 3)).astype(np.float64) * 0.1 + 0.05
    pts[0] = 0.0
    tree = bsh.build_bsh(pts, rng.random((500, 3)), np.tile([0.0, 0, 1], (500, 1)), voxel=0.1)
    cells = np.floor(pts / 0.1).astype(int)
    ref = sorted({ref_morton(*c) for c in cells})
    assert [int(c) for c in tree.codes] == ref
    assert tree.report.n_leaves == len(ref) and tree.report.n_nodes == 2 * len(ref) - 1


@pytest.mark.parametrize("seed", range(6))
def test_radix_tree_matches_recursive_split(seed):
    rng = np.random.default_rng(seed)
    n = [2, 3, 17, 100, 257, 1000][seed]
    hi = 2**63 if seed % 2 else 2**12  # wide and narrow (long common prefixes) code ranges
    codes = np.unique(rng.integers(0, hi, n * 2, dtype=np.uint64))[:n]
    left, right, parent = k.karras(codes)
    rl, rr = ref_tree([int(c) for c in codes])
    assert left.tolist() == rl and right.tolist() == rr
    assert parent[0] == -1
    for i in range(len(rl)):
        assert parent[rl[i]] == i and parent[rr[i]] == i


@pytest.fixture(scope="module")
def tree_and_cloud():
    pts, col, nrm = sphere_cloud(3000, 1)
    return bsh.build_bsh(pts, col, nrm, voxel=0.05, tc=0.02, tn=0.9), (pts, col, nrm)


def _points_by_node(tree):
    order = np.argsort(tree.point_leaf, kind="stable")
    nl = tree.codes.shape[0]
    bounds = np.searchsorted(tree.point_leaf[order], np.arange(nl - 1, 2 * nl))
    lr = leaf_ranges(tree)
    return [order[bounds[a]:bounds[b + 1]] for a, b in lr]


def test_spheres_cones_colours_against_the_points(tree_and_cloud):
    tree, (pts, col, nrm) = tree_and_cloud
    nrm = nrm / np.linalg.norm(nrm, axis=1, keepdims=True)
    under = _points_by_node(tree)
    nl = tree.codes.shape[0]
    assert tree.count[0] == len(pts)
    for v, idx in enumerate(under):
        assert tree.count[v] == len(idx) > 0
        assert np.linalg.norm(pts[idx] - tree.center[v], axis=1).max() <= tree.radius[v] + TOL
        if tree.angle[v] < math.pi:
            assert (nrm[idx] @ tree.axis[v]).min() >= math.cos(tree.angle[v]) - TOL
        np.testing.assert_allclose(tree.color[v], col[idx].mean(0), atol=1e-9)
        np.testing.assert_allclose(tree.position[v], pts[idx].mean(0), atol=1e-9)
        assert tree.color_dev[v] == pytest.approx(math.sqrt(col[idx].var(0).sum()), abs=1e-9)
        mean_dist = np.linalg.norm(col[idx] - col[idx].mean(0), axis=1).mean()  # the paper's measure
        assert mean_dist <= tree.color_dev[v] + 1e-9
        m = nrm[idx].mean(0)
        np.testing.assert_allclose(tree.normal[v], m / np.linalg.norm(m), atol=1e-9)
        if v < nl - 1:
            for c in (tree.left[v], tree.right[v]):
                d = np.linalg.norm(tree.center[v] - tree.center[c])
                assert d + tree.radius[c] <= tree.radius[v] + TOL
                if tree.angle[v] < math.pi:
                    ang = math.acos(np.clip(tree.axis[v] @ tree.axis[c], -1, 1))
                    assert ang + tree.angle[c] <= tree.angle[v] + TOL


def test_gpu_records_are_conservative(tree_and_cloud):
    tree, (pts, col, nrm) = tree_and_cloud
    nrm = nrm / np.linalg.norm(nrm, axis=1, keepdims=True)
    under = _points_by_node(tree)
    nodes = tree.nodes
    assert bsh.NODE_DTYPE.itemsize == 40 and nodes.dtype == bsh.NODE_DTYPE
    axis, angle = bsh.unpack_cone(nodes["cone"])
    for s, v in enumerate(tree.ids):
        idx = under[v]
        c = nodes["center"][s].astype(np.float64)
        assert np.linalg.norm(pts[idx] - c, axis=1).max() <= float(nodes["radius"][s]) + 1e-9
        assert angle[s] >= tree.angle[v] - 1e-12
        if angle[s] < math.pi:
            assert (nrm[idx] @ axis[s]).min() >= math.cos(angle[s]) - 1e-9
        np.testing.assert_allclose(nodes["color"][s], col[idx].mean(0), atol=1e-6)


def test_minimal_cone_of_one_leaf():
    a = 0.3
    phi = np.arange(5) * 2 * math.pi / 5
    nrm = np.stack([np.sin(a) * np.cos(phi), np.sin(a) * np.sin(phi), np.full(5, np.cos(a))], 1)
    nrm = np.vstack([nrm, [0, 0, 1]])
    pts = np.random.default_rng(0).random((6, 3)) * 0.01
    tree = bsh.build_bsh(pts, np.ones((6, 3)), nrm, voxel=1.0)
    assert tree.report.n_leaves == 1 and tree.report.n_nodes == 1 and tree.nodes.shape == (1,)
    np.testing.assert_allclose(tree.axis[0], [0, 0, 1], atol=1e-6)
    assert tree.angle[0] == pytest.approx(a, abs=1e-6)
    # two opposite normals: no cone narrower than all directions... a half-space is the best
    tree = bsh.build_bsh(pts[:2], np.ones((2, 3)), [[0, 0, 1], [0, 0, -1]], voxel=1.0)
    assert tree.angle[0] == pytest.approx(math.pi)


@pytest.mark.parametrize("deg", [0.0, 40.0, 120.0, 179.0, 180.0])
def test_two_leaves_merge_into_the_minimal_sphere_and_cone(deg):
    t = math.radians(deg)
    pts = np.array([[0.0, 0, 0], [1.0, 2.0, 2.0]])  # d = 3, one point per leaf (radius 0, cone angle 0)
    nrm = np.array([[0.0, 0, 1], [math.sin(t), 0, math.cos(t)]])
    tree = bsh.build_bsh(pts, np.zeros((2, 3)), nrm, voxel=0.5, tc=-1.0)
    assert tree.report.n_leaves == 2 and tree.report.n_nodes_pruned == 3
    assert tree.radius[0] == pytest.approx(1.5) and np.allclose(tree.center[0], [0.5, 1, 1])
    assert tree.angle[0] == pytest.approx(t / 2, abs=1e-9)
    if deg < 180:
        np.testing.assert_allclose(tree.axis[0], [math.sin(t / 2), 0, math.cos(t / 2)], atol=1e-9)


def wall(n_side: int, checker: bool):
    g = (np.arange(n_side) + 0.5) / n_side  # 1 m x 1 m wall in the z = 0 plane
    x, y = np.meshgrid(g, g)
    pts = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], 1)
    rng = np.random.default_rng(0)
    if checker:
        c = np.where((np.floor(pts[:, 0] / 0.1) + np.floor(pts[:, 1] / 0.1)) % 2 == 0, 0.1, 0.9)
    else:
        c = np.full(len(pts), 0.5)
    col = np.repeat(c[:, None], 3, 1) + rng.normal(0, 0.005, (len(pts), 3))
    nrm = np.tile([0.0, 0.0, 1.0], (len(pts), 1)) + rng.normal(0, 0.01, (len(pts), 3))
    return pts, col, nrm


def test_pruning_flat_wall_collapses_checkerboard_does_not():
    flat = bsh.build_bsh(*wall(100, False), max_radius=math.inf).report  # the paper's rule alone
    chk = bsh.build_bsh(*wall(100, True), max_radius=math.inf).report
    assert flat.n_nodes > 10_000 and chk.n_nodes > 10_000
    assert flat.n_clusters <= 4 and flat.n_nodes_pruned <= 7
    assert chk.n_clusters >= 100  # at least one per square of the 10 x 10 checkerboard
    assert chk.n_nodes_pruned == 2 * chk.n_clusters - 1
    capped = bsh.build_bsh(*wall(100, False))  # default max_radius: clusters of at most 3 cm
    leaf = capped.nodes["right"] == bsh.NO_CHILD
    assert capped.nodes["radius"][leaf].max() <= bsh.MAX_CLUSTER_RADIUS + 1e-6
    assert 100 < capped.report.n_clusters < capped.report.n_leaves / 5


def rec_traversal(tree, refine_id):
    """Visited node ids, pre-order, by recursion over the binary tree pruned at tree.cluster."""
    nl = tree.codes.shape[0]
    visited, used = [], []

    def rec(v):
        visited.append(v)
        if v < nl - 1 and not tree.cluster[v] and refine_id(v):
            rec(int(tree.left[v]))
            rec(int(tree.right[v]))
        else:
            used.append(v)

    rec(0)
    return visited, used


def test_skip_traversal_equals_recursive_traversal(tree_and_cloud):
    tree, _ = tree_and_cloud
    nodes = tree.nodes
    nl = tree.codes.shape[0]
    n_inner = int((nodes["right"] != bsh.NO_CHILD).sum())
    assert n_inner == len(nodes) - tree.report.n_clusters
    for s, v in enumerate(tree.ids):  # the layout itself
        if nodes["right"][s] != bsh.NO_CHILD:
            assert tree.ids[s + 1] == tree.left[v] and tree.ids[nodes["right"][s]] == tree.right[v]
            assert nodes["skip"][s] == nodes["skip"][nodes["right"][s]]
        else:
            assert nodes["skip"][s] == s + 1
            assert v >= nl - 1 or tree.cluster[v]
    rng = np.random.default_rng(5)
    for q in list(rng.random((4, 3)) * 1.4 - 0.2) + [None]:
        if q is None:
            def ref(v):
                return True
        else:
            def ref(v, q=q):  # solid-angle-like criterion of a PBGI cut
                return tree.radius[v] > 0.3 * np.linalg.norm(tree.center[v] - q)
        visited, used = bsh.traverse(nodes, lambda s, node: ref(int(tree.ids[s])))
        rv, ru = rec_traversal(tree, ref)
        assert tree.ids[visited].tolist() == rv
        assert tree.ids[bsh.cut(tree, lambda s, node: ref(int(tree.ids[s])))].tolist() == ru
    assert len(visited) == len(nodes)  # refine everything: every record once


def test_build_is_deterministic():
    cloud = bsh.synthetic_room(20_000, 2)
    a, b = bsh.build_bsh(*cloud), bsh.build_bsh(*cloud)
    assert a.nodes.tobytes() == b.nodes.tobytes()
    r = a.report
    assert set(r.times) == set(bsh.STAGES) and r.total > 0
    assert r.n_points == 20_000 and r.n_nodes == 2 * r.n_leaves - 1 and r.n_nodes_pruned == len(a.nodes)
    assert r.n_nodes_pruned < r.n_nodes


def test_point_spacing_of_a_grid():
    pts = wall(100, False)[0]
    assert bsh.point_spacing(pts) == pytest.approx(0.01, rel=0.05)  # sqrt(area per point); more: test_spacing.py
    big = np.random.default_rng(0).random((200_000, 2))
    big = np.hstack([big, np.zeros((len(big), 1))])
    assert 0.3 / math.sqrt(len(big)) < bsh.point_spacing(big) < 1.5 / math.sqrt(len(big))


@pytest.mark.parametrize("kwargs, name", [
    (dict(points=[[0.0, 0, 0], [np.nan, 0, 0]]), "points"),
    (dict(points=np.zeros((0, 3)), colors=np.zeros((0, 3)), normals=np.zeros((0, 3))), "points"),
    (dict(colors=np.ones((3, 3))), "colors"),
    (dict(normals=np.ones((2, 2))), "normals"),
    (dict(normals=[[0.0, 0, 1], [0, 0, 0]]), "normals"),
    (dict(colors=[[0.0, 0, 1], [0, np.inf, 0]]), "colors"),
    (dict(voxel=-1.0), "voxel"),
    (dict(voxel=1e-9), "voxel"),
    (dict(tc=float("nan")), "tc"),
])
def test_bad_inputs_name_the_argument(kwargs, name):
    args = dict(points=[[0.0, 0, 0], [1.0, 2, 3]], colors=np.ones((2, 3)), normals=[[0.0, 0, 1], [0, 1, 0]])
    args.update(kwargs)
    kw = {a: args.pop(a) for a in ("voxel", "tc") if a in args}
    with pytest.raises(PbgiError, match=f"'{name}'"):
        bsh.build_bsh(args["points"], args["colors"], args["normals"], **kw)
