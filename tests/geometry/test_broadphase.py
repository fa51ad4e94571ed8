"""Broad phase: spatial hash and fcl BVH equal brute force; conservativeness; edge cases."""

import numpy as np
import pytest

from geometry import broadphase
from geometry.broadphase import (
    box_overlap_pairs,
    edge_edge_candidates,
    point_simplex_candidates,
    unique_keys,
)

FAST = ("scan", "hash", "fcl")
ALL = ("brute", "scan", "hash", "fcl")


# ---------------------------------------------------------------------------- helpers


def _soup(rng, dim, n_simplices, size=0.08):
    """Random soup in the unit box: (V, d) vertices, (S, d) simplices (segments / triangles)."""
    k = dim
    centre = rng.random((n_simplices, 1, dim))
    vertices = (centre + size * rng.standard_normal((n_simplices, k, dim))).reshape(-1, dim)
    return vertices, np.arange(n_simplices * k).reshape(n_simplices, k)


def _points_near(rng, vertices, simplices, n_points, noise):
    """Points on random simplices (random barycentric coordinates) plus normal noise in m."""
    pick = rng.integers(0, simplices.shape[0], n_points)
    bary = rng.dirichlet(np.ones(simplices.shape[1]), n_points)
    on = np.einsum("pk,pkd->pd", bary, vertices[simplices[pick]])
    return on + noise * rng.standard_normal(on.shape)


def _segment_distance(p, a, b):
    """(P, S) distances of points p (P, d) to segments a, b (S, d) (zero-length segments too)."""
    ab = b - a
    ap = p[:, None] - a[None]
    t = np.einsum("psd,sd->ps", ap, ab) / np.maximum(np.einsum("sd,sd->s", ab, ab), 1e-300)
    t = np.clip(t, 0.0, 1.0)
    return np.linalg.norm(ap - t[..., None] * ab[None], axis=-1)


def _simplex_distance(points, vertices, simplices):
    """(P, S) true distances of points to segments (2D) or triangles (3D)."""
    x = vertices[simplices]
    if simplices.shape[1] == 2:
        return _segment_distance(points, x[:, 0], x[:, 1])
    a, b, c = x[:, 0], x[:, 1], x[:, 2]
    edges = np.minimum(
        np.minimum(_segment_distance(points, a, b), _segment_distance(points, b, c)),
        _segment_distance(points, c, a),
    )
    n = np.cross(b - a, c - a)
    nn = np.einsum("sd,sd->s", n, n)
    # the projection lies inside when it is on the inner side of all three edges
    inside = np.ones(edges.shape, dtype=bool)
    for u, v in ((a, b), (b, c), (c, a)):
        side = np.einsum("psd,sd->ps", np.cross(v - u, points[:, None] - u), n)
        inside &= side >= 0.0
    plane = np.abs(np.einsum("psd,sd->ps", points[:, None] - a, n)) / np.sqrt(
        np.maximum(nn, 1e-300)
    )
    return np.where(inside & (nn > 0.0), np.minimum(plane, edges), edges)


def _as_set(pairs):
    return set(map(tuple, pairs.tolist()))


def _check_format(pairs):
    assert pairs.dtype == np.int64 and pairs.ndim == 2 and pairs.shape[1] == 2
    assert pairs.flags.c_contiguous
    if pairs.shape[0] > 1:
        keys = pairs[:, 0] * (pairs[:, 1].max() + 1) + pairs[:, 1]
        assert np.all(np.diff(keys) > 0), "pairs must be unique and sorted"


# ---------------------------------------------------------------------------- agreement


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("swept", [False, True])
@pytest.mark.parametrize("inflation", [0.0, 0.02])
def test_point_simplex_methods_equal_brute_force(dim, swept, inflation):
    rng = np.random.default_rng(10 * dim + swept)
    vertices, simplices = _soup(rng, dim, 150)
    points = np.concatenate(
        [rng.random((250, dim)), _points_near(rng, vertices, simplices, 150, 0.02)]
    )
    kwargs = {"inflation": inflation}
    if swept:
        kwargs["points_end"] = points + 0.05 * rng.standard_normal(points.shape)
        kwargs["vertices_end"] = vertices + 0.05 * rng.standard_normal(vertices.shape)
    reference = point_simplex_candidates(points, vertices, simplices, method="brute", **kwargs)
    assert reference.shape[0] > 50  # the comparison is not vacuous
    for method in (*FAST, "auto"):
        pairs = point_simplex_candidates(points, vertices, simplices, method=method, **kwargs)
        _check_format(pairs)
        np.testing.assert_array_equal(pairs, reference, err_msg=method)
    # with group labels (bodies): the same rows less those of one group, in the same order
    groups = rng.integers(0, 3, points.shape[0]), rng.integers(0, 3, simplices.shape[0])
    other = groups[0][reference[:, 0]] != groups[1][reference[:, 1]]
    assert 0 < other.sum() < reference.shape[0]
    for method in (*FAST, "brute"):
        pairs = point_simplex_candidates(
            points, vertices, simplices, groups=groups, method=method, **kwargs
        )
        np.testing.assert_array_equal(pairs, reference[other], err_msg=method)
    with pytest.raises(ValueError, match=r"groups must be \(400,\) and \(150,\)"):
        point_simplex_candidates(points, vertices, simplices, groups=(groups[0][:5], groups[1]))


def test_auto_scans_up_to_its_pair_count_and_hashes_above(monkeypatch):
    """auto: the all-pairs scan up to ``_SCAN_PAIRS`` point-simplex pairs, the hash from one
    pair more; both give the brute-force rows."""
    used = []

    def spy(name, impl):
        def run(*args):
            used.append(name)
            return impl(*args)

        return run

    monkeypatch.setattr(broadphase, "_hash_pairs", spy("hash", broadphase._hash_pairs))
    monkeypatch.setattr(broadphase.hk, "_scan", spy("scan", broadphase.hk._scan))
    rng = np.random.default_rng(3)
    vertices, simplices = _soup(rng, 2, 100)
    n_points = broadphase._SCAN_PAIRS // 100
    points = rng.random((n_points + 1, 2))
    for pts in (points[:n_points], points):
        reference = point_simplex_candidates(
            pts, vertices, simplices, method="brute", inflation=0.01
        )
        pairs = point_simplex_candidates(pts, vertices, simplices, inflation=0.01, method="auto")
        np.testing.assert_array_equal(pairs, reference)
        assert reference.shape[0] > 100
    assert used == ["scan", "hash"]


def test_brute_force_is_the_box_overlap_definition(monkeypatch):
    rng = np.random.default_rng(1)
    vertices, simplices = _soup(rng, 3, 40)
    points = rng.random((90, 3))
    points_end = points + 0.1 * rng.standard_normal(points.shape)
    monkeypatch.setattr(broadphase, "_BRUTE_CHUNK", 7 * 40 * 3)  # several chunks
    pairs = point_simplex_candidates(
        points, vertices, simplices, inflation=0.03, points_end=points_end, method="brute"
    )
    x = vertices[simplices]
    s_lo, s_hi = x.min(axis=1) - 0.03, x.max(axis=1) + 0.03
    p_lo, p_hi = np.minimum(points, points_end), np.maximum(points, points_end)
    hit = np.all((p_lo[:, None] <= s_hi[None]) & (s_lo[None] <= p_hi[:, None]), axis=2)
    assert _as_set(pairs) == set(zip(*np.nonzero(hit), strict=True))


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("swept", [False, True])
def test_edge_edge_methods_equal_brute_force(dim, swept):
    rng = np.random.default_rng(5 + dim)
    vertices = rng.random((300, dim))
    edges_a = rng.integers(0, 300, (200, 2))
    edges_b = np.stack([np.arange(0, 300, 2), np.arange(1, 300, 2)], axis=1)
    vertices[1::2] = vertices[::2] + 0.05 * rng.standard_normal((150, dim))  # short b edges
    end = vertices + 0.03 * rng.standard_normal(vertices.shape) if swept else None
    ref = edge_edge_candidates(
        vertices, edges_a, edges_b, inflation=0.01, vertices_end=end, method="brute"
    )
    assert ref.shape[0] > 100
    for method in FAST:
        pairs = edge_edge_candidates(
            vertices, edges_a, edges_b, inflation=0.01, vertices_end=end, method=method
        )
        np.testing.assert_array_equal(pairs, ref, err_msg=method)


def test_large_sweeps_and_far_points_equal_brute_force():
    # a few points sweep across the whole scene (the hash must grow its cells), others are far
    rng = np.random.default_rng(3)
    vertices, simplices = _soup(rng, 3, 200, size=0.01)
    points = rng.random((300, 3))
    end = points.copy()
    end[:20] += rng.uniform(-1.0, 1.0, (20, 3))
    points[-30:] += 100.0
    end[-30:] += 100.0
    ref = point_simplex_candidates(points, vertices, simplices, points_end=end, method="brute")
    assert ref.shape[0] > 0 and not np.any(ref[:, 0] >= 270)
    for method in FAST:
        pairs = point_simplex_candidates(points, vertices, simplices, points_end=end, method=method)
        np.testing.assert_array_equal(pairs, ref, err_msg=method)


# ---------------------------------------------------------------------------- conservativeness


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("method", ALL)
def test_every_pair_within_inflation_is_returned(dim, method):
    rng = np.random.default_rng(20 + dim)
    vertices, simplices = _soup(rng, dim, 120, size=0.05)
    inflation = 0.01
    points = _points_near(rng, vertices, simplices, 400, inflation)
    close = _simplex_distance(points, vertices, simplices) <= inflation
    assert close.sum() > 100
    pairs = point_simplex_candidates(
        points, vertices, simplices, inflation=inflation, method=method
    )
    assert set(zip(*np.nonzero(close), strict=True)) <= _as_set(pairs)
    # and the filter is selective: far pairs are not all returned
    assert pairs.shape[0] < 0.2 * close.size


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("method", ALL)
def test_every_pair_touching_along_the_motion_is_returned(dim, method):
    rng = np.random.default_rng(30 + dim)
    vertices, simplices = _soup(rng, dim, 80, size=0.05)
    vertices_end = vertices + 0.03 * rng.standard_normal(vertices.shape)
    mid = 0.5 * (vertices + vertices_end)
    # half the points pass through a simplex at t = 1/2 (and are far from it at both ends)
    crossing = _points_near(rng, mid, simplices, 100, 0.0)
    jump = 0.1 * rng.standard_normal(crossing.shape)
    others = _points_near(rng, vertices, simplices, 100, 0.05)
    points = np.concatenate([crossing + jump, others])
    points_end = np.concatenate(
        [crossing - jump, others + 0.08 * rng.standard_normal(others.shape)]
    )
    inflation = 2e-3
    # the distance at any sampled time bounds the per-axis gap of the swept boxes
    touching = np.zeros((points.shape[0], simplices.shape[0]), dtype=bool)
    for t in np.linspace(0.0, 1.0, 41):
        p_t = (1.0 - t) * points + t * points_end
        v_t = (1.0 - t) * vertices + t * vertices_end
        touching |= _simplex_distance(p_t, v_t, simplices) <= inflation
    at_ends = (_simplex_distance(points, vertices, simplices) <= inflation) | (
        _simplex_distance(points_end, vertices_end, simplices) <= inflation
    )
    assert touching.sum() > 100 and (touching & ~at_ends).sum() > 50
    pairs = point_simplex_candidates(
        points,
        vertices,
        simplices,
        inflation=inflation,
        points_end=points_end,
        vertices_end=vertices_end,
        method=method,
    )
    assert set(zip(*np.nonzero(touching), strict=True)) <= _as_set(pairs)


@pytest.mark.parametrize("method", ALL)
def test_edge_pairs_within_inflation_are_returned(method):
    rng = np.random.default_rng(40)
    vertices = 0.5 * rng.random((200, 3))
    vertices[1::2] = vertices[::2] + 0.1 * rng.standard_normal((100, 3))
    edges = np.arange(200).reshape(100, 2)
    inflation = 0.03
    # sampled distance >= true distance, so sampled <= inflation implies a true close pair
    s = np.linspace(0.0, 1.0, 11)
    x = vertices[edges]
    samples = x[:, None, 0] + s[None, :, None] * (x[:, 1] - x[:, 0])[:, None]  # (E, 11, 3)
    diff = samples[:, None, :, None] - samples[None, :, None, :]
    close = np.linalg.norm(diff, axis=-1).min(axis=(2, 3)) <= inflation
    assert (close & ~np.eye(100, dtype=bool)).sum() > 100
    pairs = edge_edge_candidates(vertices, edges, edges, inflation=inflation, method=method)
    assert set(zip(*np.nonzero(close), strict=True)) <= _as_set(pairs)


# ---------------------------------------------------------------------------- edge cases


@pytest.mark.parametrize("method", ALL)
def test_point_exactly_on_a_box_face(method):
    vertices = np.array([[0.0, 0.0], [1.0, 1.0], [0.0, 2.0], [1.0, 2.0]])
    simplices = np.array([[0, 1], [2, 3]])  # second segment: box degenerate in y
    points = np.array(
        [
            [1.0, 0.3],  # on the face x = 1 of box 0
            [np.nextafter(1.0, 2.0), 0.3],  # one ulp outside
            [0.5, 2.0],  # on the degenerate box 1
            [0.5, np.nextafter(2.0, 3.0)],  # one ulp above it
            [1.0, 1.0],  # on a corner of box 0 (the vertex itself)
        ]
    )
    pairs = point_simplex_candidates(points, vertices, simplices, method=method)
    assert _as_set(pairs) == {(0, 0), (2, 1), (4, 0)}
    # with an inflation, a gap of exactly the inflation still counts and one ulp more does not
    points = np.array([[1.25, 0.5], [np.nextafter(1.25, 2.0) + 1e-12, 0.5], [0.5, 2.25]])
    pairs = point_simplex_candidates(points, vertices, simplices, inflation=0.25, method=method)
    assert _as_set(pairs) == {(0, 0), (2, 1)}


@pytest.mark.parametrize("method", ALL)
def test_zero_size_simplices_and_repeated_boxes(method):
    # every triangle collapsed to a point, several at the same place; points repeated too
    spots = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    vertices = np.repeat(spots, 3, axis=0)
    simplices = np.arange(9).reshape(3, 3)
    points = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [1.0, 0.0, 1e-9], [0.5, 0.0, 0.0]])
    pairs = point_simplex_candidates(points, vertices, simplices, method=method)
    assert _as_set(pairs) == {(0, 0), (0, 2), (1, 0), (1, 2)}
    pairs = point_simplex_candidates(points, vertices, simplices, inflation=1e-6, method=method)
    assert _as_set(pairs) == {(0, 0), (0, 2), (1, 0), (1, 2), (2, 1)}


@pytest.mark.parametrize("method", ALL)
def test_single_simplex_no_points_and_no_simplices(method):
    vertices = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    tri = np.array([[0, 1, 2]])
    points = np.array([[0.2, 0.2, 0.05], [0.2, 0.2, 0.2], [2.0, 2.0, 0.0]])
    pairs = point_simplex_candidates(points, vertices, tri, inflation=0.1, method=method)
    np.testing.assert_array_equal(pairs, [[0, 0]])
    for empty in (
        point_simplex_candidates(np.empty((0, 3)), vertices, tri, method=method),
        point_simplex_candidates(points, vertices, np.empty((0, 3), np.int64), method=method),
    ):
        assert empty.shape == (0, 2) and empty.dtype == np.int64


@pytest.mark.parametrize("method", ALL)
def test_huge_inflation_returns_every_pair(method):
    rng = np.random.default_rng(7)
    vertices, simplices = _soup(rng, 2, 30)
    points = rng.random((40, 2)) * 100.0
    pairs = point_simplex_candidates(points, vertices, simplices, inflation=1e6, method=method)
    expected = np.stack(np.meshgrid(np.arange(40), np.arange(30), indexing="ij"), -1)
    np.testing.assert_array_equal(pairs, expected.reshape(-1, 2))


@pytest.mark.parametrize("method", ALL)
def test_box_overlap_pairs_matches_the_definition(method):
    a_lo = np.array([[0.0, 0.0], [2.0, 2.0], [5.0, 5.0]])
    a_hi = a_lo + 1.0
    b_lo = np.array([[1.0, 1.0], [0.5, -3.0], [10.0, 10.0]])
    b_hi = b_lo + np.array([[1.0, 1.0], [0.1, 3.0], [1.0, 1.0]])
    pairs = box_overlap_pairs(a_lo, a_hi, b_lo, b_hi, method=method)
    assert _as_set(pairs) == {(0, 0), (1, 0), (0, 1)}


# ---------------------------------------------------------------------------- validation


def test_invalid_input_names_the_argument():
    pts = np.zeros((2, 3))
    verts = np.eye(3)
    tri = np.array([[0, 1, 2]])
    cases = [
        (dict(method="octree"), "method"),
        (dict(inflation=-1.0), "inflation"),
        (dict(inflation=np.nan), "inflation"),
        (dict(points=np.zeros((2, 4))), "points"),
        (dict(points=np.array([[0.0, 0.0, np.inf], [0, 0, 0]])), "points"),
        (dict(simplex_vertices=np.zeros((3, 2))), "simplex_vertices"),
        (dict(simplices=np.array([[0, 1, 3]])), "simplices"),
        (dict(simplices=np.array([[0.0, 1.0, 2.0]])), "simplices"),
        (dict(simplices=np.array([0, 1, 2])), "simplices"),
        (dict(points_end=np.zeros((3, 3))), "points_end"),
        (dict(vertices_end=np.full((3, 3), np.nan)), "vertices_end"),
    ]
    for override, name in cases:
        kwargs = dict(points=pts, simplex_vertices=verts, simplices=tri)
        kwargs.update(override)
        with pytest.raises(ValueError, match=name):
            point_simplex_candidates(
                kwargs.pop("points"),
                kwargs.pop("simplex_vertices"),
                kwargs.pop("simplices"),
                **kwargs,
            )
    with pytest.raises(ValueError, match="edges_b"):
        edge_edge_candidates(verts, np.array([[0, 1]]), np.array([[0, 1, 2]]))
    with pytest.raises(ValueError, match="b_lo > b_hi"):
        box_overlap_pairs(pts, pts, np.ones((1, 3)), np.zeros((1, 3)))


def test_unique_keys_are_numpys_unique_values():
    rng = np.random.default_rng(5)
    for keys in (rng.integers(-50, 50, 400), rng.integers(0, 3, 7), np.zeros(0, dtype=np.int64)):
        got = unique_keys(keys)
        np.testing.assert_array_equal(got, np.unique(keys))
        assert got.dtype == np.int64
