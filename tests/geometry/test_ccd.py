"""Tests of geometry.ccd: never a missed or late impact against a dense-sampled reference, always a
positive distance at the reported time, not uselessly conservative, and the special motions
(grazing, sliding parallel edges, through a vertex, zero motion, close start, min_distance)."""

import logging

import numpy as np
import pytest

from geometry import ccd
from geometry import distance as gd

N_RANDOM = 2000
N_SAMPLES = 2048


def cols(X):
    return tuple(np.ascontiguousarray(X[:, j]) for j in range(X.shape[1]))


# --------------------------------------------------------------------------- reference
# Contact of linear trajectories happens where the primitives become coplanar (collinear in
# 2D) with the contact point inside both: a sign change of an orientation polynomial in t with
# the in-primitive parameters in range. The reference samples the orientation densely, bisects
# every sign change and keeps the earliest root whose parameters are inside.
def at(X, dX, t):
    """Positions (m, k, d) at times t (m,)."""
    return X + t[:, None, None] * dX


def orientation(kind, Y):
    if kind == "point_edge":
        e, r = Y[:, 2] - Y[:, 1], Y[:, 0] - Y[:, 1]
        return e[:, 0] * r[:, 1] - e[:, 1] * r[:, 0]
    if kind == "point_triangle":
        u, v, r = Y[:, 2] - Y[:, 1], Y[:, 3] - Y[:, 1], Y[:, 0] - Y[:, 1]
    else:
        u, v, r = Y[:, 1] - Y[:, 0], Y[:, 3] - Y[:, 2], Y[:, 2] - Y[:, 0]
    return np.einsum("ij,ij->i", np.cross(u, v), r)


def inside(kind, Y):
    """Whether the contact point of the coplanar configuration Y lies in both primitives."""
    if kind == "point_edge":
        e, r = Y[:, 2] - Y[:, 1], Y[:, 0] - Y[:, 1]
        s = np.einsum("ij,ij->i", r, e) / np.einsum("ij,ij->i", e, e)
        return (s >= 0) & (s <= 1)
    if kind == "point_triangle":
        u, v, r = Y[:, 2] - Y[:, 1], Y[:, 3] - Y[:, 1], Y[:, 0] - Y[:, 1]
        n = np.cross(u, v)
        m = np.einsum("ij,ij->i", n, n)
        b1 = np.einsum("ij,ij->i", np.cross(r, v), n) / m
        b2 = np.einsum("ij,ij->i", np.cross(u, r), n) / m
        return (b1 >= 0) & (b2 >= 0) & (b1 + b2 <= 1)
    a, b, r = Y[:, 1] - Y[:, 0], Y[:, 3] - Y[:, 2], Y[:, 2] - Y[:, 0]
    n = np.cross(a, b)
    m = np.einsum("ij,ij->i", n, n)
    s = np.einsum("ij,ij->i", np.cross(r, b), n) / m
    t = np.einsum("ij,ij->i", np.cross(r, a), n) / m
    return (s >= 0) & (s <= 1) & (t >= 0) & (t <= 1)


def reference_toi(kind, X, dX):
    """First contact time (n,) on [0, 1] of linear trajectories (inf if none found)."""
    n = len(X)
    ts = np.linspace(0.0, 1.0, N_SAMPLES + 1)
    f = np.stack([orientation(kind, at(X, dX, np.full(n, t))) for t in ts], axis=1)
    pair, k = np.nonzero(f[:, :-1] * f[:, 1:] <= 0.0)
    lo, hi = ts[k], ts[k + 1]
    f_lo = f[pair, k]
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        f_mid = orientation(kind, at(X[pair], dX[pair], mid))
        left = f_lo * f_mid <= 0.0
        hi = np.where(left, mid, hi)
        lo = np.where(left, lo, mid)
        f_lo = np.where(left, f_lo, f_mid)
    root = 0.5 * (lo + hi)
    ok = inside(kind, at(X[pair], dX[pair], root))
    toi = np.full(n, np.inf)
    np.minimum.at(toi, pair[ok], root[ok])
    return toi


# --------------------------------------------------------------------------- random scenes
def random_trajectories(kind, rng, n):
    """Pairs built in contact at a random time tau (parameters sometimes outside the primitive,
    giving near misses), then given random vertex velocities and moved back to t = 0."""
    dim = 2 if kind == "point_edge" else 3
    tau = rng.uniform(0.05, 1.0, n)
    if kind == "point_edge":
        Y = rng.uniform(-1, 1, (n, 3, dim))
        s = rng.uniform(-0.3, 1.3, n)
        Y[:, 0] = Y[:, 1] + s[:, None] * (Y[:, 2] - Y[:, 1])
    elif kind == "point_triangle":
        Y = rng.uniform(-1, 1, (n, 4, dim))
        b = rng.uniform(-0.2, 1.0, (n, 2))
        Y[:, 0] = Y[:, 1] + b[:, :1] * (Y[:, 2] - Y[:, 1]) + b[:, 1:] * (Y[:, 3] - Y[:, 1])
    else:
        Y = rng.uniform(-1, 1, (n, 4, dim))
        s, u = rng.uniform(-0.2, 1.2, (2, n, 1))
        c = Y[:, 0] + s * (Y[:, 1] - Y[:, 0])
        w = rng.standard_normal((n, dim))
        Y[:, 2], Y[:, 3] = c - u * w, c + (1 - u) * w
    dX = rng.standard_normal(Y.shape)
    dX[: n // 4] *= 0.05  # slow, nearly rigid relative motions too
    dX[: n // 4] += rng.standard_normal((n // 4, 1, dim))
    return Y - tau[:, None, None] * dX, dX


def pair_distance(kind, Y):
    return getattr(gd, kind + "_distance")(*cols(Y))


def run_ccd(kind, X, dX, **kw):
    return getattr(ccd, kind + "_ccd")(*cols(X), *cols(dX), **kw)


@pytest.mark.parametrize("kind", ["point_edge", "point_triangle", "edge_edge"])
def test_random_trajectories_never_miss_and_stay_separated(kind):
    rng = np.random.default_rng(7)
    X, dX = random_trajectories(kind, rng, N_RANDOM)
    d0 = pair_distance(kind, X)
    t_ref = reference_toi(kind, X, dX)
    toi = run_ccd(kind, X, dX)
    hit = np.isfinite(t_ref)
    assert 0.3 < hit.mean() < 0.95  # a mix of impacts and misses
    # Never later than the first contact; never beyond t_max.
    assert np.all(toi[hit] <= t_ref[hit] + 1e-12), np.max(toi[hit] - t_ref[hit])
    assert np.all((toi >= 0) & (toi <= 1))
    # Still separated at the reported time, by at least the stopping fraction of the gap.
    d_toi = pair_distance(kind, at(X, dX, toi))
    assert np.all(d_toi > 0)
    assert np.all(d_toi >= 0.1 * d0 * (1 - 1e-9))
    # Not uselessly conservative.
    ratio = toi[hit] / t_ref[hit]
    assert np.mean(ratio >= 0.5) > 0.95 and np.median(ratio) > 0.75, np.percentile(ratio, [5, 50])
    # No false alarm where the pair clearly never comes close: sampled d(t) >> 0.1 d0.
    ts = np.linspace(0, 1, 257)
    d_min = np.min([pair_distance(kind, at(X, dX, np.full(len(X), t))) for t in ts], axis=0)
    speed = 2 * np.linalg.norm(dX, axis=2).max(axis=1)
    far = d_min > 0.2 * d0 + speed / 256
    assert far.sum() > 50 and np.all(toi[far] == 1.0)


# --------------------------------------------------------------------------- special motions
def one(*rows):
    return np.array(rows, dtype=float)[:, None, :].transpose(1, 0, 2)


def test_head_on_reports_about_ninety_percent_of_the_impact_time():
    X, dX = one([0.5, 1.0], [0, 0], [1, 0]), one([0, -2.0], [0, 0], [0, 0])
    toi = run_ccd("point_edge", X, dX)
    assert 0.4 <= toi[0] < 0.5  # true impact at 0.5
    toi_tight = run_ccd("point_edge", X, dX, tolerance=0.01)
    assert toi[0] < toi_tight[0] < 0.5


def test_point_sliding_collinear_into_the_edge():
    # Orientation is identically zero: contact when the point reaches e0 at t = 0.5.
    X, dX = one([-1.0, 0.0], [0, 0], [1, 0]), one([2.0, 0.0], [0, 0], [0, 0])
    toi = run_ccd("point_edge", X, dX)[0]
    assert 0.25 <= toi < 0.5
    assert gd.point_edge_distance(*cols(at(X, dX, np.array([toi]))))[0] > 0


def test_grazing_pass_is_conservative_but_safe():
    # The point passes 1e-3 above the whole segment: no contact, ACCD stops early by design.
    X, dX = one([-1.0, 1e-3], [0, 0], [1, 0]), one([3.0, 0.0], [0, 0], [0, 0])
    toi = run_ccd("point_edge", X, dX)[0]
    d = gd.point_edge_distance(*cols(at(X, dX, np.array([toi]))))[0]
    assert 0.0 < toi <= 1.0 and d > 0
    assert toi >= 0.3  # reaches the edge's end (t = 1/3) before the gap drops below 0.1 d0


def test_point_through_a_vertex():
    # 2D: through e1 at t = 0.5; 3D: through t0 at t = 0.25 along the diagonal.
    X, dX = one([1.0, 1.0], [0, 0], [1, 0]), one([0.0, -2.0], [0, 0], [0, 0])
    toi = run_ccd("point_edge", X, dX)[0]
    assert 0.25 <= toi < 0.5
    X = one([-1.0, -1, -1], [0, 0, 0], [1, 0, 0], [0, 1, 0])
    dX = one([4.0, 4, 4], [0, 0, 0], [0, 0, 0], [0, 0, 0])
    toi = run_ccd("point_triangle", X, dX)[0]
    assert 0.125 <= toi < 0.25


def test_parallel_edges_sliding_and_approaching():
    X = one([0.0, 0, 0], [1, 0, 0], [0.2, 0, 1e-3], [1.2, 0, 1e-3])
    slide = one([0.0, 0, 0], [0, 0, 0], [1.0, 0, 0], [1.0, 0, 0])
    assert run_ccd("edge_edge", X, slide)[0] == 1.0  # constant gap 1e-3: never an impact
    X = one([0.0, 0, 0], [1, 0, 0], [0.2, 0, 0.5], [1.2, 0, 0.5])
    approach = one([0.0, 0, 0], [0, 0, 0], [0.5, 0, -1.0], [0.5, 0, -1.0])
    toi = run_ccd("edge_edge", X, approach)[0]
    assert 0.25 <= toi < 0.5  # contact at t = 0.5 (still overlapping in x)
    # Crossing edges sweeping through each other.
    X = one([0.0, 0, 0], [1, 0, 0], [0.5, -1, 1], [0.5, 1, 1])
    cross = one([0.0, 0, 0], [0, 0, 0], [0, 0, -4.0], [0, 0, -4.0])
    toi = run_ccd("edge_edge", X, cross)[0]
    assert 0.125 <= toi < 0.25


def test_zero_and_rigid_motion_never_impact():
    X = one([0.2, 0.2, 1e-6], [0, 0, 0], [1, 0, 0], [0, 1, 0])
    assert run_ccd("point_triangle", X, np.zeros_like(X))[0] == 1.0
    rigid = np.tile([[[3.0, -2.0, 5.0]]], (1, 4, 1))
    assert run_ccd("point_triangle", X, rigid, t_max=2.5)[0] == 2.5


def test_close_start_and_min_distance():
    e = ([0.0, 0], [1, 0])
    away = run_ccd("point_edge", one([0.5, 1e-9], *e), one([0, 1.0], [0, 0], [0, 0]))
    assert away[0] == 1.0
    towards = run_ccd("point_edge", one([0.5, 1e-9], *e), one([0, -1.0], [0, 0], [0, 0]))
    assert 0.0 < towards[0] < 1e-9
    touching = run_ccd("point_edge", one([0.5, 0.0], *e), one([0, 1.0], [0, 0], [0, 0]))
    assert touching[0] == 0.0
    # min_distance: reaches 0.1 at t = 0.45; starting within it reports 0.
    X, dX = one([0.5, 1.0], *e), one([0, -2.0], [0, 0], [0, 0])
    toi = run_ccd("point_edge", X, dX, min_distance=0.1)[0]
    assert 0.4 < toi < 0.45
    assert gd.point_edge_distance(*cols(at(X, dX, np.array([toi]))))[0] > 0.1
    assert run_ccd("point_edge", X, dX, min_distance=1.5)[0] == 0.0


def test_t_max_bounds_the_result():
    X, dX = one([0.5, 1.0], [0, 0], [1, 0]), one([0, -2.0], [0, 0], [0, 0])
    assert run_ccd("point_edge", X, dX, t_max=0.3)[0] == 0.3
    slow = one([0, -0.5], [0, 0], [0, 0])  # impact at t = 2
    assert 1.6 < run_ccd("point_edge", X, slow, t_max=3.0)[0] < 2.0


def test_iteration_cap_returns_a_safe_time_and_warns(caplog):
    # Sliding along a long edge at a constant 1e-3 gap: ~1100 ACCD steps to reach t = 1.
    X, dX = one([0.0, 1e-3], [-1, 0], [2, 0]), one([1.0, 0.0], [0, 0], [0, 0])
    assert run_ccd("point_edge", X, dX)[0] == 1.0
    with caplog.at_level(logging.WARNING, logger="geometry.ccd"):
        capped = run_ccd("point_edge", X, dX, max_iterations=10)[0]
    assert 0 < capped < 0.02 and "max_iterations" in caplog.text


def test_earliest_impact_takes_the_minimum_over_pair_kinds():
    # A triangle, a point falling on it and an edge falling across one of its edges.
    x = np.array(
        [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.2, 0.2, 1.0], [0.5, -0.5, 0.5], [0.5, 0.5, 0.5]],
        dtype=float,
    )
    dx = np.zeros_like(x)
    dx[3] = [0, 0, -2.0]  # point hits the face at t = 0.5
    dx[4:] = [0, 0, -4.0]  # edge 4-5 hits edge 0-1 at t = 0.125
    pt, ee = np.array([[3, 0, 1, 2]]), np.array([[0, 1, 4, 5]])
    t_pt = ccd.earliest_impact(x, dx, point_triangle=pt)
    t_ee = ccd.earliest_impact(x, dx, edge_edge=ee)
    assert 0.4 < t_pt < 0.5 and 0.1 < t_ee < 0.125
    assert ccd.earliest_impact(x, dx, point_triangle=pt, edge_edge=ee) == t_ee
    assert ccd.earliest_impact(x, dx) == 1.0
    assert ccd.earliest_impact(x, dx, edge_edge=np.zeros((0, 4), int), t_max=0.7) == 0.7
    x2, dx2 = x[:3, :2], np.array([[0, 0], [0, 0], [0, -2.0]])  # 2D point 2 onto edge 0-1
    assert 0.4 < ccd.earliest_impact(x2, dx2, point_edge=np.array([[2, 0, 1]])) < 0.5


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"tolerance": 1.0}, "tolerance must be in"),
        ({"t_max": 0.0}, "t_max must be"),
        ({"min_distance": -1.0}, "min_distance must be"),
        ({"max_iterations": 0}, "max_iterations must be"),
        ({"point_edge": np.array([[0, 1, 9]])}, r"point_edge rows \[0\] reference"),
        ({"point_triangle": np.array([[0, 1, 2, 3]])}, "need 3D positions"),
        ({"point_edge": np.array([[0.0, 1, 2]])}, "integer array"),
    ],
)
def test_bad_options_raise_naming_the_field(kwargs, match):
    x, dx = np.zeros((4, 2)), np.zeros((4, 2))
    with pytest.raises(ValueError, match=match):
        ccd.earliest_impact(x, dx, **kwargs)


def test_bad_displacement_shape_raises():
    X = one([0.5, 1.0], [0, 0], [1, 0])
    with pytest.raises(ValueError, match="dp must have shape"):
        ccd.point_edge_ccd(*cols(X), np.zeros((2, 2)), np.zeros((1, 2)), np.zeros((1, 2)))
