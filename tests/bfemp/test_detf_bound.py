"""The det F > 0 step bound against exact references (rational arithmetic, Sturm sequences)."""

from __future__ import annotations

import itertools
from fractions import Fraction

import numpy as np
import pytest

from bfemp._detf_bound import first_det_root, max_step_det_positive

# ------------------------------------------------------------------------------------------
# exact reference: det(F + a D) as a polynomial with rational coefficients, Sturm counts
# ------------------------------------------------------------------------------------------


def _parity(perm):
    inversions = sum(perm[i] > perm[j] for i in range(len(perm)) for j in range(i + 1, len(perm)))
    return -1 if inversions % 2 else 1


def _exact_poly(F, D):
    """Coefficients (low to high) of det(F + a D), exact for the float64 entries given."""
    d = F.shape[0]
    coeffs = [Fraction(0)] * (d + 1)
    for perm in itertools.permutations(range(d)):
        poly = [Fraction(1)]
        for i in range(d):
            x, y = Fraction(F[i, perm[i]]), Fraction(D[i, perm[i]])
            nxt = [Fraction(0)] * (len(poly) + 1)
            for k, c in enumerate(poly):
                nxt[k] += c * x
                nxt[k + 1] += c * y
            poly = nxt
        sign = _parity(perm)
        coeffs = [c + sign * p for c, p in zip(coeffs, poly, strict=True)]
    return _strip(coeffs)


def _strip(p):
    p = list(p)
    while len(p) > 1 and p[-1] == 0:
        p.pop()
    return p


def _eval(p, x):
    v = Fraction(0)
    for c in reversed(p):
        v = v * x + c
    return v


def _rem(a, b):
    a = list(a)
    while len(a) >= len(b) and any(a):
        q = a[-1] / b[-1]
        shift = len(a) - len(b)
        for k, c in enumerate(b):
            a[shift + k] -= q * c
        a.pop()
    return _strip(a) if a else [Fraction(0)]


def _deflate(p, r):
    """p(a) / (a - r) for a root r (synthetic division)."""
    out = [Fraction(0)] * (len(p) - 1)
    acc = Fraction(0)
    for k in range(len(p) - 1, 0, -1):
        acc = acc * r + p[k]
        out[k - 1] = acc
    return _strip(out)


def _roots_in(p, lo, hi):
    """Number of distinct real roots of p in (lo, hi) (Sturm's theorem; p(lo) != 0)."""
    p = _strip(p)
    while len(p) > 1 and _eval(p, hi) == 0:
        p = _deflate(p, hi)
    if len(p) == 1:
        return 0
    seq = [p, _strip([k * c for k, c in enumerate(p)][1:])]
    while len(seq[-1]) > 1 or seq[-1][0] != 0:
        r = _rem(seq[-2], seq[-1])
        if len(r) == 1 and r[0] == 0:
            break
        seq.append([-c for c in r])

    def changes(x):
        signs = [s for s in (_eval(q, x) for q in seq) if s != 0]
        return sum((a > 0) != (b > 0) for a, b in itertools.pairwise(signs))

    return changes(lo) - changes(hi)


def _first_root_float(p, alpha_max):
    """Smallest positive real root of p (float, from np.roots), or inf."""
    c = np.array([float(x) for x in reversed(p)])
    if len(c) == 1:
        return np.inf
    r = np.roots(c)
    r = r[(np.abs(r.imag) <= 1e-12 * np.abs(r)) & (r.real > 0)].real
    return r.min() if r.size else np.inf


def _check_exact(F, D, alpha, alpha_max):
    """No root of det(F_s + a D_s) in (0, alpha_s): exact check, every point."""
    for s in range(len(F)):
        assert Fraction(alpha[s]) <= Fraction(alpha_max)
        p = _exact_poly(F[s], D[s])
        assert p[0] > 0
        assert _roots_in(p, Fraction(0), Fraction(alpha[s])) == 0, (s, F[s], D[s], alpha[s])


def _det_along(F, D, t):
    """det(F + t D) in float64 for t (S, n_t): (S, n_t)."""
    return np.linalg.det(F[:, None] + t[:, :, None, None] * D[:, None])


# ------------------------------------------------------------------------------------------
# random cases
# ------------------------------------------------------------------------------------------


def _random_F(rng, n, d):
    """Half near identity, half general (singular values 0.2..5, random rotations); det > 0."""
    near = np.eye(d) + 0.3 * rng.standard_normal((n // 2, d, d))
    q1, _ = np.linalg.qr(rng.standard_normal((n - n // 2, d, d)))
    q2, _ = np.linalg.qr(rng.standard_normal((n - n // 2, d, d)))
    sv = np.exp(rng.uniform(np.log(0.2), np.log(5.0), (n - n // 2, d)))
    general = (q1 * sv[:, None, :]) @ q2
    F = np.concatenate([near, general])
    F[np.linalg.det(F) < 0, 0] *= -1.0
    return F


def _random_F_and_direction(seed, n, d):
    """``_random_F`` and standard normal directions D (n, d, d) from ``default_rng(seed)``."""
    rng = np.random.default_rng(seed)
    F = _random_F(rng, n, d)
    return F, rng.standard_normal((n, d, d))


@pytest.mark.parametrize("d", [2, 3])
def test_random_cases_against_exact_and_dense_references(d):
    rng = np.random.default_rng(100 + d)
    n = 3000
    F = _random_F(rng, n, d)
    D = rng.standard_normal((n, d, d)) * 10.0 ** rng.uniform(-1.5, 1.5, (n, 1, 1))
    alpha = first_det_root(F, D)
    assert alpha.shape == (n,) and (alpha > 0).all() and (alpha <= 1.0).all()
    assert 0.2 < (alpha < 1.0).mean() < 0.8  # both regimes are exercised

    # The caller's step 0.9 alpha is feasible, and so is a dense grid of smaller steps.
    assert (np.linalg.det(F + 0.9 * alpha[:, None, None] * D) > 0).all()
    grid = alpha[:, None] * np.linspace(0.0, 0.999, 200)[None, :]
    assert (_det_along(F, D, grid) > 0).all()

    # Reference first root from the exactly computed polynomial (np.roots); generic roots are
    # simple, so the bound is tight: relative error below 1e-9 on both sides.
    ref = np.array([min(_first_root_float(_exact_poly(F[s], D[s]), 1.0), 1.0) for s in range(n)])
    assert (alpha <= ref * (1 + 1e-9)).all()
    assert (alpha >= ref * (1 - 1e-9)).all()
    assert (alpha[ref >= 1.0] == 1.0).all()

    # Rigorous: no root in (0, alpha) (Sturm's theorem in rational arithmetic), on a subset.
    _check_exact(F[:300], D[:300], alpha[:300], 1.0)


@pytest.mark.parametrize("d", [2, 3])
def test_max_step_is_the_minimum_over_points(d):
    F, D = _random_F_and_direction(7, 50, d)
    roots = first_det_root(F, D, alpha_max=2.0)
    assert max_step_det_positive(F, D, alpha_max=2.0) == roots.min()
    assert max_step_det_positive(F[:0], D[:0], alpha_max=0.3) == 0.3
    assert first_det_root(F[:0], D[:0]).shape == (0,)


# ------------------------------------------------------------------------------------------
# adversarial cases
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("d", [2, 3])
def test_zero_and_tiny_directions_give_alpha_max_exactly(d):
    rng = np.random.default_rng(1)
    F = _random_F(rng, 20, d)
    for alpha_max in (1.0, 0.37, 1e6):
        assert (first_det_root(F, np.zeros_like(F), alpha_max) == alpha_max).all()
    D = 1e-12 * rng.standard_normal(F.shape)
    assert (first_det_root(F, D, 1.0) == 1.0).all()


@pytest.mark.parametrize("d", [2, 3])
def test_collapse_direction_root_at_and_beyond_alpha_max(d):
    """D = -F / r: det(F + a D) = det F (1 - a/r)^d, a d-fold root at r."""
    rng = np.random.default_rng(2)
    F = _random_F(rng, 200, d)
    # Multiplicity d: the float root is uncertain by (K eps)^(1/d); the bound stays below it.
    slack = 1e-5 if d == 2 else 2e-3
    for r in (1.0, 0.5, 1e-3, 3.0):
        D = -F / r
        alpha = first_det_root(F, D, alpha_max=1.0)
        true = min(r, 1.0)
        assert (alpha <= true).all() and (alpha >= true * (1 - slack)).all()
        assert (np.linalg.det(F + 0.9 * alpha[:, None, None] * D) > 0).all()
        _check_exact(F[:20], D[:20], alpha[:20], 1.0)
    # Root exactly at alpha_max and beyond it.
    assert (first_det_root(F, -F, alpha_max=0.5) == 0.5).all()
    assert (first_det_root(F, -F / 1.001, alpha_max=1.0) == 1.0).all()


def _similar(rng, n, d, eig):
    """Matrices P diag(eig) P^-1 with well-conditioned random P: (n, d, d)."""
    P = np.eye(d) + 0.3 * rng.standard_normal((n, d, d))
    return np.linalg.solve(P.transpose(0, 2, 1), (P * eig).transpose(0, 2, 1)).transpose(0, 2, 1)


@pytest.mark.parametrize("third", [-2.0, 0.0, 0.25])
def test_touching_double_root_is_not_missed_3d(third):
    """det(F + a D) = det F (1 - a)^2 (1 - third a): det touches 0 at a = 1 without crossing."""
    rng = np.random.default_rng(3)
    n = 300
    F = _random_F(rng, n, 3)
    M = _similar(rng, n, 3, np.array([1.0, 1.0, third]))
    D = -F @ M
    alpha = first_det_root(F, D, alpha_max=2.0)
    # Built in floating point, the touching root may split in two or turn complex by ~1e-8:
    # the bound must sit at or below it either way.
    assert (alpha <= 1.0 + 1e-7).all() and (alpha >= 1.0 - 1e-4).all()
    assert (np.linalg.det(F + 0.9 * alpha[:, None, None] * D) > 0).all()
    _check_exact(F[:50], D[:50], alpha[:50], 2.0)


@pytest.mark.parametrize("d", [2, 3])
def test_exactly_representable_multiple_roots(d):
    eye = np.eye(d)
    cases = [  # (F, D, alpha_max, first root)
        (eye, -eye, 2.0, 1.0),
        (2 * eye, -eye, 3.0, 2.0),
        (eye, np.diag([-1.0, -1.0, 1.0][:d]), 2.0, 1.0),
        (eye, -eye + 5 * np.eye(d, k=1), 2.0, 1.0),  # defective (Jordan) direction
        (eye, np.diag([-1.0, 1.0, 1.0][:d]), 2.0, 1.0),  # simple root
        (eye, np.diag([-0.5, 0.0, 0.0][:d]), 1.5, 1.5),  # root at 2 > alpha_max
        (eye, np.diag([-0.75, 0.0, 0.0][:d]), 4.0 / 3.0, 4.0 / 3.0),  # root at alpha_max
    ]
    F = np.stack([c[0] for c in cases])
    D = np.stack([c[1] for c in cases])
    for s, (_, _, alpha_max, root) in enumerate(cases):
        alpha = first_det_root(F[s : s + 1], D[s : s + 1], alpha_max)[0]
        mult = 1 if s in (4, 5, 6) else d
        slack = {1: 1e-12, 2: 1e-6, 3: 1e-4}[mult]
        assert root * (1 - slack) <= alpha <= root, (s, alpha)
        if s == 5:
            assert alpha == alpha_max
        _check_exact(F[s : s + 1], D[s : s + 1], np.array([alpha]), alpha_max)


@pytest.mark.parametrize("d", [2, 3])
def test_rank_one_direction_has_linear_determinant(d):
    """det(F + a u v^T) = det F (1 + a v^T F^-1 u): a single root -1 / (v^T F^-1 u)."""
    rng = np.random.default_rng(4)
    n = 500
    F = _random_F(rng, n, d)
    u = rng.standard_normal((n, d))
    v = rng.standard_normal((n, d))
    D = u[:, :, None] * v[:, None, :]
    k = np.einsum("si,si->s", v, np.linalg.solve(F, u[..., None])[..., 0])
    root = np.where(k < 0, -1.0 / np.where(k < 0, k, -1.0), np.inf)
    alpha = first_det_root(F, D, alpha_max=10.0)
    expected = np.minimum(root, 10.0)
    np.testing.assert_allclose(alpha, expected, rtol=1e-9)
    assert (alpha[root > 10.0] == 10.0).all()


@pytest.mark.parametrize("d", [2, 3])
def test_near_singular_F_and_huge_D(d):
    rng = np.random.default_rng(5)
    n = 400
    q1, _ = np.linalg.qr(rng.standard_normal((n, d, d)))
    q2, _ = np.linalg.qr(rng.standard_normal((n, d, d)))
    sv = np.ones((n, d))
    sv[:, -1] = 10.0 ** rng.uniform(-10, -4, n)
    F = (q1 * sv[:, None, :]) @ q2
    F[np.linalg.det(F) < 0, 0] *= -1.0
    D = rng.standard_normal((n, d, d))
    alpha = first_det_root(F, D)
    assert (alpha > 0).all()
    assert (np.linalg.det(F + 0.9 * alpha[:, None, None] * D) > 0).all()
    _check_exact(F[:100], D[:100], alpha[:100], 1.0)
    # Roots are of the order of the smallest singular value. det F is computed with a relative
    # error up to ~eps perm(|F|) / det F (here 1e10 eps), so the certified bound may sit below
    # the root by that much; it never exceeds it.
    ref = np.array([min(_first_root_float(_exact_poly(F[s], D[s]), 1.0), 1.0) for s in range(n)])
    assert (alpha <= ref * (1 + 1e-9)).all()
    assert (alpha >= ref * (1 - 1e-3)).all()
    assert np.median(alpha / ref) > 1 - 1e-5

    # Huge directions: roots near 1e-12, same relative accuracy.
    F = _random_F(rng, n, d)
    D = 1e12 * rng.standard_normal((n, d, d))
    alpha = first_det_root(F, D)
    ref = np.array([_first_root_float(_exact_poly(F[s], D[s]), 1.0) for s in range(n)])
    has_root = ref < np.inf
    assert has_root.mean() > 0.5 and ref[has_root].max() < 1e-9
    np.testing.assert_allclose(alpha[has_root], ref[has_root], rtol=1e-9)
    assert (alpha[~has_root] == 1.0).all()
    assert (np.linalg.det(F + 0.9 * alpha[:, None, None] * D) > 0).all()


@pytest.mark.parametrize("d", [2, 3])
def test_extreme_scales_do_not_overflow_and_are_scale_invariant(d):
    F, D = _random_F_and_direction(6, 200, d)
    alpha = first_det_root(F, D, alpha_max=5.0)
    # Scaling F and D together by powers of two leaves the roots unchanged, bit for bit.
    for e in (-600, 600):
        np.testing.assert_array_equal(first_det_root(F * 2.0**e, D * 2.0**e, alpha_max=5.0), alpha)
    # Scaling D alone by 2^e divides the roots by 2^e.
    scaled = first_det_root(F, D * 2.0**300, alpha_max=5.0 * 2.0**-300)
    np.testing.assert_array_equal(scaled, alpha * 2.0**-300)
    # Roots 300 orders of magnitude below alpha_max: same roots up to the 1e-13 tolerance.
    found = alpha < 5.0
    scaled = first_det_root(F * 2.0**-500, D * 2.0**500, alpha_max=1.0)
    np.testing.assert_allclose(scaled[found], alpha[found] * 2.0**-1000, rtol=1e-12)
    scaled = first_det_root(F, D * 1e-9, alpha_max=1e12)
    np.testing.assert_allclose(scaled[found], alpha[found] * 1e9, rtol=1e-12)


def test_invalid_input_is_rejected_with_the_reason():
    F = np.broadcast_to(np.eye(3), (4, 3, 3)).copy()
    D = np.zeros((4, 3, 3))
    with pytest.raises(ValueError, match="F must have shape"):
        first_det_root(np.ones((4, 3)), np.ones((4, 3)))
    with pytest.raises(ValueError, match="D must have the shape of F"):
        first_det_root(F, np.zeros((4, 2, 2)))
    for bad in (0.0, -1.0, np.inf, np.nan):
        with pytest.raises(ValueError, match="alpha_max must be finite and > 0"):
            max_step_det_positive(F, D, alpha_max=bad)
    G = F.copy()
    G[2, 0, 0] = -1.0
    with pytest.raises(ValueError, match=r"det F <= 0 at points \[2\]"):
        first_det_root(G, D)
    E = D.copy()
    E[1, 2, 2] = np.nan
    with pytest.raises(ValueError, match=r"non-finite entries at points \[1\]"):
        first_det_root(F, E)
