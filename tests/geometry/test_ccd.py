"""Tests of geometry.ccd: never a missed or late impact against a dense-sampled reference, always a
positive distance at the reported time, not uselessly conservative, and the special motions
(grazing, sliding parallel edges, through a vertex, zero motion, close start, min_distance); no
false negative against an exact rational oracle on adversarial families and on cases ported from
ipc-toolkit's CCD tests, and a bounded cost of parallel sliding (issue 44)."""

import json
import logging
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

from benchmarks import ccd_oracle as oracle
from geometry import ccd
from geometry import distance as gd
from tests.geometry.conftest import cols

N_RANDOM = 2000
N_SAMPLES = 2048


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
    # A triangle tilting about the foot of a point 1e-3 above it (3D: no line step): the gap
    # stays ~1e-3 but the separating direction turns, so the steps stay ~gap / speed (~1100 to
    # reach t = 1).
    X = one([0.0, 0.0, 1e-3], [-1, -1, 0], [1, -1, 0], [0, 1, 0])
    dX = one([0.0, 0.0, 0.0], [0, 0, -1], [0, 0, -1], [0, 0, 1])
    assert run_ccd("point_triangle", X, dX)[0] == 1.0
    with caplog.at_level(logging.WARNING, logger="geometry.ccd"):
        capped = run_ccd("point_triangle", X, dX, max_iterations=10)[0]
    assert 0 < capped < 0.02 and "max_iterations" in caplog.text
    d = gd.point_triangle_distance(*cols(at(X, dX, np.array([capped]))))[0]
    assert d > 1e-4


@pytest.mark.parametrize("gap", [1e-3, 1e-6, 1e-9, 1e-12])
def test_edge_turning_near_a_point_is_one_step_in_2d(gap):
    # An edge turning about the foot of a point `gap` above it: the distance, gap / sqrt(1 +
    # t^2), never reaches 0 but the separating direction turns, so ACCD's steps stay ~gap / speed
    # (1130 iterations at 1e-3, the 1e6 cap below; 197 ms at 1e-9). The orientation e0 x e1 is a
    # quadratic in t (here the constant 2 gap): its certified root bound clears [0, 1] at once.
    X, dX = one([0.0, gap], [-1, 0], [1, 0]), one([0.0, 0.0], [0, -1], [0, 1])
    assert oracle.exact_toi_point_edge_2d(X[0], dX[0]) is None
    toi, iterations = oracle.bfemp_toi("point_edge", X, dX)
    assert toi[0] == 1.0 and iterations[0] == 1
    # Turned the other way (the point sweeps across the line at t = 1 / 2), a contact at 1 / 2
    X2, dX2 = one([0.5, 0.0], [-1, -0.5 * gap], [1, 0.5 * gap]), one([0, 0], [0, gap], [0, -gap])
    t_exact = oracle.exact_toi_point_edge_2d(X2[0], dX2[0])
    toi, iterations = oracle.bfemp_toi("point_edge", X2, dX2)
    assert not oracle.false_negative(toi[0], t_exact) and 0.4 < toi[0] < float(t_exact) == 0.5
    assert iterations[0] <= 3


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


# --------------------------------------------------------------------------- issue 44
# Defect 3: a pair starting at rounding level was stepped through; defect 4: parallel sliding at
# a small gap took 1e6 steps and still reported an impact. Exact reference: the rational
# Minkowski-difference oracle of benchmarks.ccd_oracle (relative translation of the two sides).
N_FAMILY = 40
DATA = Path(__file__).parent / "data"


def test_point_starting_at_rounding_level_above_a_segment_reports_zero():
    # The point starts 1.3e-17 m above the segment and ends 0.79 m beyond it (issue 44).
    X = one([0.7, 0.21], [0, 0], [1, 0.3])
    dX = one([0, -1.0], [0, 0], [0, 0])
    assert oracle.exact_toi("point_edge", X[0], dX[0]) is not None  # a real contact
    assert run_ccd("point_edge", X, dX)[0] == 0.0


def test_gap_above_rounding_far_from_the_origin_still_moves():
    # Rounding scales with the pair's size, not with |x|: a one-ulp gap (1.2e-10 m, pair size
    # ~1 m) at 1e6 m from the origin is above it and must not be reported as contact at t = 0.
    X = one([1e6 + 0.5, np.nextafter(1e6, 2e6)], [1e6, 1e6], [1e6 + 1, 1e6])  # 1 ulp above
    dX = one([0.0, -1.0], [0, 0], [0, 0])
    t_exact = oracle.exact_toi("point_edge", X[0], dX[0])
    toi = run_ccd("point_edge", X, dX)[0]
    assert 0.0 < toi < t_exact


@pytest.mark.parametrize("kind", oracle.KINDS)
@pytest.mark.parametrize("family", oracle.FAMILIES)
def test_adversarial_families_have_no_false_negative(family, kind):
    X, dX = oracle.family(family, kind, N_FAMILY, seed=44)
    exact = [oracle.exact_toi(kind, X[i], dX[i]) for i in range(N_FAMILY)]
    toi, _ = oracle.bfemp_toi(kind, X, dX)
    late = [i for i in range(N_FAMILY) if oracle.false_negative(toi[i], exact[i])]
    assert not late, [(i, toi[i], exact[i]) for i in late[:5]]
    if family in ("gap_through", "far", "grazing"):
        assert sum(e is not None for e in exact) > N_FAMILY // 4  # the family does hit


@pytest.mark.parametrize("kind", oracle.KINDS)
def test_parallel_sliding_at_a_fixed_gap_is_one_step_and_no_impact(kind):
    # Gaps 1e-12 .. 1e-3 m, sliding 0.2 .. 2 m along the feature: never touching. Before the
    # fix: up to 1e6 ACCD steps (the cap) and toi down to 1e-3.
    X, dX = oracle.family("sliding", kind, N_FAMILY, seed=44)
    assert all(oracle.exact_toi(kind, X[i], dX[i]) is None for i in range(N_FAMILY))
    toi, iterations = oracle.bfemp_toi(kind, X, dX)
    assert np.all(iterations <= 2), iterations.max()
    assert np.all(toi == 1.0), toi.min()


def test_point_sliding_parallel_to_a_segment_at_1e_9():
    # issue 44, defect 4: constant 1e-9 m gap, never touching; was toi 9e-4 after 1e6 steps.
    X = one([0.5, 1e-9], [0, 0], [1, 0])
    dX = one([0.4, 0.0], [0, 0], [0, 0])
    toi, iterations = oracle.bfemp_toi("point_edge", X, dX)
    assert toi[0] == 1.0 and iterations[0] == 1


def _ported_cases():
    with open(DATA / "ipctk_ccd_cases.json") as fh:
        return json.load(fh)["cases"]


def test_ported_ipc_toolkit_cases():
    cases = _ported_cases()
    assert len(cases) > 500
    missed, too_early, not_exact = [], [], []
    for c in cases:
        x0, x1 = np.array(c["x0"]), np.array(c["x1"])
        dX = x1 - x0
        toi = run_ccd(c["kind"], x0[None], dX[None], t_max=c["t_max"])[0]
        assert 0.0 <= toi <= c["t_max"]
        if c["collision"] and not (
            toi < c["t_max"] and (c["toi_expected"] is None or toi <= c["toi_expected"])
        ):
            missed.append((c["name"], toi))
        if c["must_match"] and not c["collision"] and toi != c["t_max"]:
            too_early.append((c["name"], toi))
        try:  # where each side translates, the exact oracle too
            exact = oracle.exact_toi(c["kind"], x0, dX, c["t_max"])
        except ValueError:
            continue
        if oracle.false_negative(toi, exact):
            not_exact.append((c["name"], toi, exact))
    assert not missed and not too_early and not not_exact, (missed, too_early, not_exact)


def test_exact_oracle_on_known_cases():
    # head-on at t = 1/2, a miss beside the segment, touching at t = 0, collinear entry at 1/4
    X, dX = one([0.5, 1.0], [0, 0], [1, 0]), one([0, -2.0], [0, 0], [0, 0])
    assert oracle.exact_toi("point_edge", X[0], dX[0]) == Fraction(1, 2)
    point = np.array([[1.0], [0.0], [0.0]])
    assert oracle.exact_toi("point_edge", X[0] + point * [2.0, 0.0], dX[0]) is None
    assert oracle.exact_toi("point_edge", X[0] - point * [0.0, 1.0], -dX[0]) == 0
    X, dX = one([-1.0, 0.0], [0, 0], [1, 0]), one([4.0, 0.0], [0, 0], [0, 0])
    assert oracle.exact_toi("point_edge", X[0], dX[0]) == Fraction(1, 4)
    # crossing edges at t = 1/8 (as test_parallel_edges_sliding_and_approaching)
    X = one([0.0, 0, 0], [1, 0, 0], [0.5, -1, 1], [0.5, 1, 1])
    dX = one([0.0, 0, 0], [0, 0, 0], [0, 0, -8.0], [0, 0, -8.0])
    assert oracle.exact_toi("edge_edge", X[0], dX[0]) == Fraction(1, 8)
    turning = dX[0].copy()
    turning[1] = [0.0, 1.0, 0.0]  # a1 moves, a0 does not: not a translation of edge a
    with pytest.raises(ValueError, match="translate rigidly"):
        oracle.exact_toi("edge_edge", X[0], turning)


def test_general_motion_point_edge_from_rounding_level_has_no_false_negative():
    # Every vertex its own displacement (the segment turns and stretches), starting 1e-18 ..
    # 1e-12 x size from the segment; exact oracle: the quadratic orientation's roots as surds.
    X, dX = oracle.turning_point_edge(150, seed=44)
    exact = [oracle.exact_toi_point_edge_2d(X[i], dX[i]) for i in range(len(X))]
    assert sum(e is not None for e in exact) > 50
    toi = run_ccd("point_edge", X, dX)
    late = [i for i in range(len(X)) if oracle.false_negative(toi[i], exact[i])]
    assert not late, [(i, toi[i], float(exact[i])) for i in late[:5]]


def test_turning_near_contact_cost_is_bounded_without_false_negative():
    # The turning family's seed with the costliest pair (212965 ACCD iterations, 85 ms, before
    # the line step: an edge turning about the foot of a point ~1e-14 above it) and the
    # tangent family (the segment's line touching the point: a near-double root of the
    # orientation quadratic, the line step's hardest case; 16171 iterations before). Now 22 and
    # 8 at most.
    for X, dX in (oracle.turning_point_edge(2000, seed=1), oracle.tangent_point_edge(2000, 3)):
        exact = [oracle.exact_toi_point_edge_2d(X[i], dX[i]) for i in range(len(X))]
        assert sum(e is not None for e in exact) > 100
        toi, iterations = oracle.bfemp_toi("point_edge", X, dX)
        late = [i for i in range(len(X)) if oracle.false_negative(toi[i], exact[i])]
        assert not late, [(i, toi[i], float(exact[i])) for i in late[:5]]
        assert iterations.max() <= 64, (iterations.max(), np.argmax(iterations))
        # not uselessly conservative: where the exact oracle finds no contact, mostly t_max
        none = np.array([e is None for e in exact])
        assert np.mean(toi[none] == 1.0) > 0.5


def test_quadratic_oracle_agrees_with_the_translation_oracle():
    for family in oracle.FAMILIES:
        X, dX = oracle.family(family, "point_edge", 10, seed=45)
        for i in range(10):
            a = oracle.exact_toi("point_edge", X[i], dX[i])
            b = oracle.exact_toi_point_edge_2d(X[i], dX[i])
            assert a == b, (family, i, a, b)  # both rational here (linear orientation)
    # A turning edge: its line is y = t x. A point at (0, 0.5) is never on it; one at
    # (0.5 + 0.5 t, 0.5) is when t^2 + t - 1 = 0, t = (sqrt 5 - 1) / 2, inside the segment.
    X = one([0.0, 0.5], [-1, 0], [1, 0])
    dX = one([0.0, 0.0], [0, -1.0], [0, 1.0])
    assert oracle.exact_toi_point_edge_2d(X[0], dX[0]) is None
    X, dX = one([0.5, 0.5], [-1, 0], [1, 0]), one([0.5, 0.0], [0, -1.0], [0, 1.0])
    t = oracle.exact_toi_point_edge_2d(X[0], dX[0])
    assert isinstance(t, oracle.Surd) and (t * t + t - 1).sign() == 0
    assert float(t) == pytest.approx((5**0.5 - 1) / 2)
    toi = run_ccd("point_edge", X, dX)[0]
    assert 0.5 * float(t) < toi < float(t)
