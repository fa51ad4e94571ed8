"""Tests of geometry.frames: closest-point parameters against the distance module and dense
sampling; tangent bases orthonormal and orthogonal to the distance gradient, also in degenerate
configurations."""

import numpy as np
import pytest

from geometry import distance as gd
from geometry import frames as gf
from tests.geometry.conftest import cols, triangle_samples

RNG_SEED = 7


def assert_orthonormal(T):
    k = T.shape[2]
    gram = np.einsum("nik,nil->nkl", T, T)
    np.testing.assert_allclose(gram, np.broadcast_to(np.eye(k), gram.shape), atol=1e-12)


def assert_orthogonal_to(T, normal):
    """Columns of T (n, d, k) orthogonal to the non-zero normals (n, d)."""
    norm = np.linalg.norm(normal, axis=1)
    keep = norm > 1e-9
    assert keep.any()
    nh = normal[keep] / norm[keep, None]
    assert np.abs(np.einsum("nik,ni->nk", T[keep], nh)).max() < 1e-10


# --------------------------------------------------------------------------- parameters
@pytest.mark.parametrize("dim", [2, 3])
def test_point_edge_parameter_matches_sampling_and_distance(dim):
    rng = np.random.default_rng(RNG_SEED)
    X = rng.uniform(-1, 1, (300, 3, dim))
    beta = gf.point_edge_closest_parameter(*cols(X))
    assert np.all((beta >= 0) & (beta <= 1))
    closest = (1 - beta[:, None]) * X[:, 1] + beta[:, None] * X[:, 2]
    d = np.linalg.norm(X[:, 0] - closest, axis=1)
    np.testing.assert_allclose(d, gd.point_edge_distance(*cols(X)), rtol=1e-12, atol=1e-14)
    s = np.linspace(0, 1, 4001)
    pts = X[:, None, 1] + s[None, :, None] * (X[:, None, 2] - X[:, None, 1])
    s_best = s[np.linalg.norm(pts - X[:, None, 0], axis=-1).argmin(axis=1)]
    assert np.abs(beta - s_best).max() <= 1.0 / 4000
    # Feature type agrees: 0 -> beta = 0, 1 -> beta = 1, 2 -> interior.
    typ = gd.point_edge_type(*cols(X))
    assert np.all(beta[typ == 0] == 0.0) and np.all(beta[typ == 1] == 1.0)
    assert np.all((beta[typ == 2] > 0) & (beta[typ == 2] < 1))
    # Zero-length edge.
    Y = X[:3].copy()
    Y[:, 2] = Y[:, 1]
    assert np.all(gf.point_edge_closest_parameter(*cols(Y)) == 0.0)


def test_point_triangle_barycentric_matches_sampling_and_distance():
    rng = np.random.default_rng(RNG_SEED + 1)
    X = rng.uniform(-1, 1, (300, 4, 3))
    X[:100, 0] = X[:100, 1:].mean(axis=1) + 0.05 * rng.standard_normal((100, 3))  # near face
    bc = gf.point_triangle_closest_barycentric(*cols(X))
    assert np.all(bc >= -1e-12) and np.all(bc.sum(axis=1) <= 1 + 1e-12)
    closest = X[:, 1] + bc[:, :1] * (X[:, 2] - X[:, 1]) + bc[:, 1:] * (X[:, 3] - X[:, 1])
    d = np.linalg.norm(X[:, 0] - closest, axis=1)
    np.testing.assert_allclose(d, gd.point_triangle_distance(*cols(X)), rtol=1e-10, atol=1e-13)
    N = 100
    pts, longest = triangle_samples(X, N)
    best = np.linalg.norm(pts - X[:, None, 0], axis=-1).argmin(axis=1)
    sampled = pts[np.arange(X.shape[0]), best]
    # The minimiser is unique (strictly convex); the sampled one is within a few cells of it.
    assert np.mean(np.linalg.norm(sampled - closest, axis=1) <= 3 * longest / N) > 0.95
    # Vertex types give the vertices' barycentrics exactly.
    typ = gd.point_triangle_type(*cols(X))
    for t, ref in enumerate([(0, 0), (1, 0), (0, 1)]):
        assert np.all(bc[typ == t] == ref)


def test_edge_edge_parameters_match_distance_including_parallel():
    rng = np.random.default_rng(RNG_SEED + 2)
    X = rng.uniform(-1, 1, (300, 4, 3))
    # Exactly parallel (overlapping and not) and degenerate edges.
    X[:30, 3] = X[:30, 2] + rng.uniform(-2, 2, (30, 1)) * (X[:30, 1] - X[:30, 0])
    X[30:40, 1] = X[30:40, 0]
    st = gf.edge_edge_closest_parameters(*cols(X))
    assert np.all((st >= 0) & (st <= 1))
    a, b = X[:, 1] - X[:, 0], X[:, 3] - X[:, 2]
    pa = X[:, 0] + st[:, :1] * a
    pb = X[:, 2] + st[:, 1:] * b
    d = np.linalg.norm(pa - pb, axis=1)
    np.testing.assert_allclose(d, gd.edge_edge_distance(*cols(X)), rtol=1e-10, atol=1e-13)
    # Dense sampling of both segments never finds a closer pair of points.
    s = np.linspace(0, 1, 201)
    A = X[:, None, None, 0] + s[None, :, None, None] * a[:, None, None]
    B = X[:, None, None, 2] + s[None, None, :, None] * b[:, None, None]
    d_sampled = np.linalg.norm(A - B, axis=-1).min(axis=(1, 2))
    assert np.all(d <= d_sampled + 1e-12)


# --------------------------------------------------------------------------- bases
def _grad_p(fn, X):
    """Gradient of the distance w.r.t. the first vertex (n, d)."""
    return fn(*cols(X))[:, : X.shape[2]]


@pytest.mark.parametrize("dim", [2, 3])
def test_point_point_basis(dim):
    rng = np.random.default_rng(RNG_SEED + 3)
    X = rng.uniform(-1, 1, (100, 2, dim))
    X[:5, 1] = X[:5, 0]  # coincident
    T = gf.point_point_tangent_basis(*cols(X))
    assert T.shape == (100, dim, dim - 1)
    assert_orthonormal(T)
    assert_orthogonal_to(T, X[:, 0] - X[:, 1])


@pytest.mark.parametrize("dim", [2, 3])
def test_point_edge_basis(dim):
    rng = np.random.default_rng(RNG_SEED + 4)
    X = rng.uniform(-1, 1, (200, 3, dim))
    T = gf.point_edge_tangent_basis(*cols(X))
    assert T.shape == (200, dim, dim - 1)
    assert_orthonormal(T)
    assert_orthogonal_to(T, _grad_p(gd.point_edge_distance_gradient, X))
    # Interior closest point: first column is the edge direction.
    interior = gd.point_edge_type(*cols(X)) == 2
    e = X[:, 2] - X[:, 1]
    e /= np.linalg.norm(e, axis=1)[:, None]
    np.testing.assert_allclose(T[interior, :, 0], e[interior], atol=1e-12)
    # Degenerate: p on the segment, p on the line beyond the segment, zero-length edge.
    Y = X[:30].copy()
    Y[:10, 0] = 0.3 * Y[:10, 1] + 0.7 * Y[:10, 2]
    Y[10:20, 0] = -0.5 * Y[10:20, 1] + 1.5 * Y[10:20, 2]
    Y[20:, 2] = Y[20:, 1]
    T = gf.point_edge_tangent_basis(*cols(Y))
    assert np.all(np.isfinite(T))
    assert_orthonormal(T)
    assert_orthogonal_to(T[10:20], Y[10:20, 0] - Y[10:20, 2])
    assert_orthogonal_to(T[20:], Y[20:, 0] - Y[20:, 1])


def test_point_triangle_basis():
    rng = np.random.default_rng(RNG_SEED + 5)
    X = rng.uniform(-1, 1, (300, 4, 3))
    X[:100, 0] = X[:100, 1:].mean(axis=1) + 0.05 * rng.standard_normal((100, 3))
    T = gf.point_triangle_tangent_basis(*cols(X))
    assert T.shape == (300, 3, 2)
    assert_orthonormal(T)
    assert_orthogonal_to(T, _grad_p(gd.point_triangle_distance_gradient, X))
    # Face interior: the basis spans the triangle's plane, first column along t1 - t0.
    face = gd.point_triangle_type(*cols(X)) == 6
    assert face.sum() > 50
    nrm = np.cross(X[:, 2] - X[:, 1], X[:, 3] - X[:, 1])
    assert_orthogonal_to(T[face], nrm[face])
    u = X[:, 2] - X[:, 1]
    u /= np.linalg.norm(u, axis=1)[:, None]
    np.testing.assert_allclose(T[face, :, 0], u[face], atol=1e-12)
    # Degenerate: p in the triangle, and a collapsed triangle.
    Y = X[:20].copy()
    Y[:10, 0] = 0.2 * Y[:10, 1] + 0.3 * Y[:10, 2] + 0.5 * Y[:10, 3]
    Y[10:, 3] = Y[10:, 1]
    T = gf.point_triangle_tangent_basis(*cols(Y))
    assert_orthonormal(T)
    assert_orthogonal_to(T[:10], nrm[:10])


def test_edge_edge_basis():
    rng = np.random.default_rng(RNG_SEED + 6)
    X = rng.uniform(-1, 1, (300, 4, 3))
    X[:30, 3] = X[:30, 2] + 0.7 * (X[:30, 1] - X[:30, 0])  # parallel
    T = gf.edge_edge_tangent_basis(*cols(X))
    assert T.shape == (300, 3, 2)
    assert_orthonormal(T)
    g = gd.edge_edge_distance_gradient(*cols(X))
    assert_orthogonal_to(T, g[:, :3] + g[:, 3:6])  # d(distance)/d(translation of edge a)
    # Interiors: the plane of the two edge directions.
    inner = gd.edge_edge_type(*cols(X)) == 8
    assert inner.sum() > 20
    nrm = np.cross(X[:, 1] - X[:, 0], X[:, 3] - X[:, 2])
    assert_orthogonal_to(T[inner], nrm[inner])
    # Degenerate: intersecting edges, collinear overlapping edges, zero-length edges.
    Y = X[30:60].copy()
    mid, b_dir = 0.5 * (Y[:10, 0] + Y[:10, 1]), Y[:10, 3] - Y[:10, 2]
    Y[:10, 2], Y[:10, 3] = mid - 0.5 * b_dir, mid + 0.3 * b_dir
    Y[10:20, 2] = Y[10:20, 0] + 0.25 * (Y[10:20, 1] - Y[10:20, 0])
    Y[10:20, 3] = Y[10:20, 0] + 1.5 * (Y[10:20, 1] - Y[10:20, 0])
    Y[20:, 1] = Y[20:, 0]
    Y[20:, 3] = Y[20:, 2]
    T = gf.edge_edge_tangent_basis(*cols(Y))
    assert np.all(np.isfinite(T))
    assert_orthonormal(T)
    assert np.all(gd.edge_edge_distance(*cols(Y[:10])) < 1e-12)
    assert_orthogonal_to(T[:10], np.cross(Y[:10, 1] - Y[:10, 0], Y[:10, 3] - Y[:10, 2]))
    assert_orthogonal_to(T[20:], Y[20:, 0] - Y[20:, 2])


def test_frames_reject_bad_input():
    with pytest.raises(ValueError, match="e1"):
        gf.point_edge_tangent_basis(np.zeros((2, 3)), np.zeros((2, 3)), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="p must have shape"):
        gf.point_triangle_closest_barycentric(*([np.zeros((2, 2))] * 4))
    with pytest.raises(ValueError, match="eb0"):
        bad = np.zeros((2, 3))
        bad[1, 0] = np.nan
        gf.edge_edge_closest_parameters(np.zeros((2, 3)), np.ones((2, 3)), bad, np.ones((2, 3)))
