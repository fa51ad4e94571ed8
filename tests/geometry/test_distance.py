"""Tests of geometry.distance: values vs brute force, closest-feature types, derivatives vs
finite differences (every feature type, 2D and 3D), invariances and input validation."""

import numpy as np
import pytest

from geometry import distance as gd
from tests.geometry.conftest import cols, triangle_samples

RNG_SEED = 20240611


def seg_dist_ref(p, a, b):
    """Independent numpy point-segment distance (clamped projection), arrays (..., d)."""
    e = b - a
    ee = np.einsum("...i,...i->...", e, e)
    s = np.einsum("...i,...i->...", p - a, e) / np.where(ee > 0, ee, 1.0)
    s = np.clip(np.where(ee > 0, s, 0.0), 0.0, 1.0)
    return np.linalg.norm(p - a - s[..., None] * e, axis=-1)


KINDS = {
    # name: (number of vertices, allowed dims)
    "point_point": (2, (2, 3)),
    "point_edge": (3, (2, 3)),
    "point_triangle": (4, (3,)),
    "edge_edge": (4, (3,)),
}
N_TYPES = {"point_edge": 3, "point_triangle": 7, "edge_edge": 9}


def fn(kind, squared=False, order=0):
    name = kind + "_distance" + ("_squared" if squared else "")
    return getattr(gd, name + ("", "_gradient", "_hessian")[order])


# --------------------------------------------------------------------------- values
@pytest.mark.parametrize("dim", [2, 3])
def test_point_edge_matches_dense_sampling(dim):
    rng = np.random.default_rng(RNG_SEED)
    X = rng.uniform(-1, 1, (400, 3, dim))
    d = gd.point_edge_distance(*cols(X))
    s = np.linspace(0, 1, 2001)
    pts = X[:, None, 1] + s[None, :, None] * (X[:, None, 2] - X[:, None, 1])
    d_sampled = np.linalg.norm(pts - X[:, None, 0], axis=-1).min(axis=1)
    h = np.linalg.norm(X[:, 2] - X[:, 1], axis=1) / 2000 / 2  # half sample spacing
    assert np.all(d <= d_sampled + 1e-12)
    assert np.all(d_sampled - d <= h + 1e-12)


def test_point_triangle_matches_dense_sampling():
    rng = np.random.default_rng(RNG_SEED + 1)
    X = rng.uniform(-1, 1, (300, 4, 3))
    X[:100, 0] = X[:100, 1:].mean(axis=1) + 0.05 * rng.standard_normal((100, 3))  # near face
    d = gd.point_triangle_distance(*cols(X))
    N = 120
    pts, longest = triangle_samples(X, N)
    d_sampled = np.linalg.norm(pts - X[:, None, 0], axis=-1).min(axis=1)
    assert np.all(d <= d_sampled + 1e-12)
    assert np.all(d_sampled - d <= longest / N + 1e-12)
    assert np.mean(d_sampled - d < 1e-3) > 0.9


def test_edge_edge_matches_dense_sampling():
    rng = np.random.default_rng(RNG_SEED + 2)
    X = rng.uniform(-1, 1, (400, 4, 3))
    d = gd.edge_edge_distance(*cols(X))
    s = np.linspace(0, 1, 2001)
    pa = X[:, None, 0] + s[None, :, None] * (X[:, None, 1] - X[:, None, 0])
    d_sampled = seg_dist_ref(pa, X[:, None, 2], X[:, None, 3]).min(axis=1)
    h = np.linalg.norm(X[:, 1] - X[:, 0], axis=1) / 2000 / 2
    assert np.all(d <= d_sampled + 1e-12)
    assert np.all(d_sampled - d <= h + 1e-12)


def test_adversarial_point_edge_cases():
    e0, e1 = np.array([0.0, 0.0]), np.array([1.0, 0.0])
    cases = [  # (p, e0, e1, distance, type)
        ((0.0, 0.0), e0, e1, 0.0, 0),  # on the vertex
        ((1.0, 0.0), e0, e1, 0.0, 1),
        ((0.5, 0.0), e0, e1, 0.0, 2),  # on the edge
        ((0.5, 2.0), e0, e1, 2.0, 2),
        ((-3.0, 4.0), e0, e1, 5.0, 0),
        ((4.0, -4.0), e0, e1, 5.0, 1),
        ((2.0, 0.0), e0, e1, 1.0, 1),  # collinear beyond the end
        ((0.3, 0.7), (0.5, 0.5), (0.5, 0.5), np.hypot(0.2, 0.2), 0),  # zero-length edge
        ((0.7, 1.0), (0.5, 0.0), (0.5 + 1e-9, 0.0), np.hypot(0.2 - 1e-9, 1.0), 1),  # tiny edge
        ((0.5 + 5e-10, 1.0), (0.5, 0.0), (0.5 + 1e-9, 0.0), 1.0, 2),  # over a tiny edge
    ]
    P, A, B, dist, typ = (np.array([c[k] for c in cases], dtype=float) for k in range(5))
    np.testing.assert_allclose(gd.point_edge_distance(P, A, B), dist, atol=1e-15, rtol=1e-14)
    np.testing.assert_array_equal(gd.point_edge_type(P, A, B), typ.astype(np.int8))
    P3, A3, B3 = (np.pad(Z, ((0, 0), (0, 1))) for Z in (P, A, B))  # the same in 3D
    np.testing.assert_allclose(gd.point_edge_distance(P3, A3, B3), dist, atol=1e-15, rtol=1e-14)


def test_point_triangle_types_and_values_on_constructed_cases():
    t0, t1, t2 = [0.0, 0, 0], [1.0, 0, 0], [0.0, 1, 0]
    cases = [  # (p, type, distance)
        ([-1.0, -1.0, 1.0], 0, np.sqrt(3.0)),
        ([2.0, -0.5, 0.0], 1, np.hypot(1.0, 0.5)),  # on the plane, outside
        ([-0.2, 1.5, -1.0], 2, np.sqrt(0.04 + 0.25 + 1.0)),
        ([0.5, -1.0, 2.0], 3, np.sqrt(5.0)),
        ([1.0, 1.0, 0.0], 4, np.sqrt(0.5)),  # on the plane, outside edge t1t2
        ([-0.5, 0.5, 0.0], 5, 0.5),
        ([0.25, 0.25, -0.3], 6, 0.3),
        ([0.25, 0.25, 0.0], 6, 0.0),  # in the triangle
        ([0.0, 0.0, 0.4], 6, 0.4),  # exactly over a vertex: the face (closest point is t0)
        ([0.5, 0.0, 0.0], 6, 0.0),  # exactly on an edge
    ]
    n = len(cases)
    P = np.array([c[0] for c in cases])
    T = [np.tile(t, (n, 1)) for t in (t0, t1, t2)]
    np.testing.assert_allclose(gd.point_triangle_distance(P, *T), [c[2] for c in cases], atol=1e-15)
    np.testing.assert_array_equal(gd.point_triangle_type(P, *T), [c[1] for c in cases])
    # Degenerate (collinear) triangle: the distance to the segment it collapses to.
    Tdeg = [np.tile(t, (2, 1)) for t in ([0.0, 0, 0], [1.0, 0, 0], [2.0, 0, 0])]
    Pdeg = np.array([[1.5, 1.0, 0.0], [3.0, 0.0, 0.0]])
    np.testing.assert_allclose(gd.point_triangle_distance(Pdeg, *Tdeg), [1.0, 1.0])
    assert set(gd.point_triangle_type(Pdeg, *Tdeg)) <= {2, 4}


def test_edge_edge_types_and_values_on_constructed_cases():
    a0, a1 = [0.0, 0, 0], [1.0, 0, 0]
    cases = [  # (b0, b1, type, distance)
        ([-1.0, 0, 1], [-1.0, 0, 3], 0, np.sqrt(2.0)),
        ([-1.0, 0, 3], [-1.0, 0, 1], 1, np.sqrt(2.0)),
        ([2.0, 0, 1], [2.0, 0, 3], 2, np.sqrt(2.0)),
        ([2.0, 0, 3], [2.0, 0, 1], 3, np.sqrt(2.0)),
        ([0.5, 0, 1], [0.5, 0, 3], 4, 1.0),
        ([0.5, 1, 3], [0.5, 0, 1], 5, 1.0),
        ([-1.0, -1, 1], [-1.0, 1, 1], 6, np.sqrt(2.0)),
        ([2.0, -1, 1], [2.0, 1, 1], 7, np.sqrt(2.0)),
        ([0.5, -1, 1], [0.5, 1, 1], 8, 1.0),  # skew, crossing above
        ([0.5, -1, 0], [0.5, 1, 0], 8, 0.0),  # intersecting
        ([0.3, 0, 0.5], [0.8, 0, 0.5], 4, 0.5),  # parallel, overlapping
        ([1.5, 0, 0.5], [2.5, 0, 0.5], 2, np.hypot(0.5, 0.5)),  # parallel, disjoint
        ([3.0, 0, 0], [2.0, 0, 0], 3, 1.0),  # collinear, disjoint
        ([0.5, 0, 0], [3.0, 0, 0], 4, 0.0),  # collinear, overlapping
        ([0.4, 0.2, 0.1], [0.4, 0.2, 0.1], 4, np.hypot(0.2, 0.1)),  # zero-length edge b
    ]
    n = len(cases)
    A0, A1 = np.tile(a0, (n, 1)), np.tile(a1, (n, 1))
    B0, B1 = np.array([c[0] for c in cases]), np.array([c[1] for c in cases])
    dist = np.array([c[3] for c in cases])
    np.testing.assert_allclose(gd.edge_edge_distance(A0, A1, B0, B1), dist, atol=1e-15)
    np.testing.assert_array_equal(gd.edge_edge_type(A0, A1, B0, B1), [c[2] for c in cases])
    assert gd.edge_edge_parallel(A0, A1, B0, B1).tolist() == [False] * 10 + [True] * 5
    # Nearly parallel edges: continuous with the parallel value from both sides.
    for eps in (1e-13, 1e-9, 1e-6):
        B1t = np.array([[0.8, eps, 0.5]])
        d = gd.edge_edge_distance(A0[:1], A1[:1], np.array([[0.3, 0, 0.5]]), B1t)
        np.testing.assert_allclose(d, 0.5, rtol=1e-6)


def test_squared_versions_consistent_and_invariances():
    rng = np.random.default_rng(RNG_SEED + 3)
    for kind, (k, dims) in KINDS.items():
        for dim in dims:
            X = rng.uniform(-1, 1, (300, k, dim))
            d, g, H = (fn(kind, False, o)(*cols(X)) for o in range(3))
            D, gD, HD = (fn(kind, True, o)(*cols(X)) for o in range(3))
            np.testing.assert_allclose(D, d**2, rtol=1e-12, atol=1e-15)
            np.testing.assert_allclose(gD, 2 * d[:, None] * g, rtol=1e-10, atol=1e-12)
            HD_chain = 2 * g[:, :, None] * g[:, None, :] + 2 * d[:, None, None] * H
            np.testing.assert_allclose(HD, HD_chain, rtol=1e-9, atol=1e-9)
            # Moving side A (the point, or edge a) rigidly changes d at unit rate along g.
            n_a = 2 if kind == "edge_edge" else 1
            g_a = g.reshape(-1, k, dim)[:, :n_a].sum(axis=1)
            np.testing.assert_allclose(np.linalg.norm(g_a, axis=1), 1.0, rtol=1e-10)
            np.testing.assert_allclose(H, H.transpose(0, 2, 1), atol=1e-10)
            # Translation invariance: the vertex forces balance (linear momentum).
            np.testing.assert_allclose(g.reshape(-1, k, dim).sum(axis=1), 0.0, atol=1e-12)
            Hsum = H.reshape(-1, k * dim, k, dim).sum(axis=2)
            np.testing.assert_allclose(Hsum, 0.0, atol=1e-8 * (1 + np.abs(H).max()))
            # Rigid motion invariance of the value; forces carry no net torque (3D).
            Q, _ = np.linalg.qr(rng.standard_normal((dim, dim)))
            Xr = X @ Q.T + rng.standard_normal(dim)
            np.testing.assert_allclose(fn(kind)(*cols(Xr)), d, rtol=1e-10, atol=1e-13)
            if dim == 3:
                torque = np.cross(X, g.reshape(-1, k, dim)).sum(axis=1)
                np.testing.assert_allclose(torque, 0.0, atol=1e-12)


# --------------------------------------------------------------------------- derivatives
def central_fd(f, X, h):
    """Central differences of f(*cols(X)) -> (n, ...) w.r.t. the flattened X; (n, ..., k d)."""
    n, k, d = X.shape
    out = None
    for j in range(k * d):
        Xp, Xm = X.copy(), X.copy()
        Xp.reshape(n, -1)[:, j] += h
        Xm.reshape(n, -1)[:, j] -= h
        col = (f(*cols(Xp)) - f(*cols(Xm))) / (2 * h)
        out = np.zeros(col.shape + (k * d,)) if out is None else out
        out[..., j] = col
    return out


def stable_type_mask(kind, X, h):
    """Pairs whose closest-feature type is unchanged by every +-h coordinate perturbation."""
    if kind == "point_point":
        return np.ones(len(X), bool), np.zeros(len(X), int)
    types = getattr(gd, kind + "_type")
    t0 = types(*cols(X))
    ok = np.ones(len(X), bool)
    n = len(X)
    for j in range(X[0].size):
        for sgn in (-1, 1):
            Xp = X.copy()
            Xp.reshape(n, -1)[:, j] += sgn * h
            ok &= types(*cols(Xp)) == t0
    return ok, t0


def sample_all_types(kind, k, dim, rng, n):
    """Random pairs plus ones placed to make every closest-feature type frequent."""
    X = rng.uniform(-1, 1, (n, k, dim))
    if kind == "point_triangle":  # points above the face, near the edges and the vertices
        bary = rng.dirichlet(np.ones(3), n // 3)
        normal = np.cross(X[: n // 3, 2] - X[: n // 3, 1], X[: n // 3, 3] - X[: n // 3, 1])
        X[: n // 3, 0] = np.einsum("ni,nid->nd", bary, X[: n // 3, 1:]) + 0.1 * normal
    if kind == "edge_edge":  # edges crossing above each other
        m = n // 3
        mid_a = X[:m, 0] + rng.uniform(0.1, 0.9, (m, 1)) * (X[:m, 1] - X[:m, 0])
        off = mid_a + 0.2 * rng.standard_normal((m, 3))
        w = rng.standard_normal((m, 3))
        t = rng.uniform(0.1, 0.9, (m, 1))
        X[:m, 2], X[:m, 3] = off - t * w, off + (1 - t) * w
    return X


@pytest.mark.parametrize(
    ("kind", "dim"),
    [("point_point", 2), ("point_point", 3), ("point_edge", 2), ("point_edge", 3)]
    + [("point_triangle", 3), ("edge_edge", 3)],
)
@pytest.mark.parametrize("squared", [False, True])
def test_derivatives_match_finite_differences_for_every_type(kind, dim, squared):
    rng = np.random.default_rng(RNG_SEED + 4)
    k = KINDS[kind][0]
    X = sample_all_types(kind, k, dim, rng, 1500)
    # A near-contact band as well (d ~ 1e-2): the barrier lives there.
    X[-200:, 0] = X[-200:, 1] + 1e-2 * rng.standard_normal((200, dim))
    h = 1e-6
    ok, types = stable_type_mask(kind, X, 10 * h)
    d = fn(kind)(*cols(X))
    ok &= d > 1e-3  # away from d = 0, where d is not differentiable
    X, types = X[ok], types[ok]
    if kind != "point_point":
        counts = np.bincount(types, minlength=N_TYPES[kind])
        assert np.all(counts >= 5), f"type coverage {counts}"
    g = fn(kind, squared, 1)(*cols(X))
    H = fn(kind, squared, 2)(*cols(X))
    g_fd = central_fd(fn(kind, squared, 0), X, h)
    H_fd = central_fd(fn(kind, squared, 1), X, h)
    gscale = 1.0 + np.linalg.norm(g, axis=1)
    hscale = 1.0 + np.linalg.norm(H, axis=(1, 2))
    g_err = np.linalg.norm(g - g_fd, axis=1) / gscale
    H_err = np.linalg.norm(H - H_fd, axis=(1, 2)) / hscale
    assert g_err.max() < 1e-6, (g_err.max(), types[g_err.argmax()])
    assert H_err.max() < 1e-5, (H_err.max(), types[H_err.argmax()])
    assert np.median(H_err) < 1e-7


def test_derivatives_at_zero_distance_are_zero_subgradient():
    p = np.array([[0.5, 0.0, 0.0], [0.0, 0.0, 0.0]])
    e0, e1 = np.zeros((2, 3)), np.tile([1.0, 0, 0], (2, 1))
    assert np.all(gd.point_edge_distance_gradient(p, e0, e1) == 0.0)
    assert np.all(gd.point_edge_distance_hessian(p, e0, e1) == 0.0)
    g_sq = gd.point_edge_distance_squared_gradient(p, e0, e1)
    assert np.all(g_sq == 0.0)  # the squared distance is smooth, with zero gradient at contact


def test_hessian_output_shapes_and_empty_batches():
    for kind, (k, dims) in KINDS.items():
        for dim in dims:
            X = np.zeros((0, k, dim))
            assert fn(kind)(*cols(X)).shape == (0,)
            assert fn(kind, order=1)(*cols(X)).shape == (0, k * dim)
            assert fn(kind, order=2)(*cols(X)).shape == (0, k * dim, k * dim)


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (
            lambda: gd.point_edge_distance(np.zeros((2, 4)), np.zeros((2, 4)), np.zeros((2, 4))),
            r"p must have shape \(n, 2 or 3\)",
        ),
        (
            lambda: gd.point_edge_distance(np.zeros((2, 2)), np.zeros((3, 2)), np.zeros((2, 2))),
            r"e0 must have shape \(2, 2\)",
        ),
        (
            lambda: gd.point_triangle_distance(*(np.zeros((2, 2)),) * 4),
            r"p must have shape \(n, 3\)",
        ),
        (lambda: gd.edge_edge_type(*(np.zeros(3),) * 4), r"ea0 must have shape"),
        (
            lambda: gd.point_point_distance(
                np.zeros((3, 2)), np.array([[0, 0], [np.nan, 0], [0, 0]])
            ),
            r"q has non-finite entries in rows \[1\]",
        ),
    ],
)
def test_bad_input_raises_naming_the_argument(call, match):
    with pytest.raises(ValueError, match=match):
        call()
