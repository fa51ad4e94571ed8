"""Tests of the pointwise contact kernels: the barrier of eq. 27 and its derivatives, contact
weights (section 4.2), and the friction mollifier / local friction pseudo-potential (eq. 36-37)."""

import numpy as np
import pytest

from bfemp.contact.barrier import (
    barrier,
    barrier_derivative,
    barrier_second_derivative,
    boundary_vertex_weights,
    particle_contact_weight,
)
from bfemp.contact.friction_kernels import f0, f1, friction_local

DHAT = 1e-3
KAPPA = 1e7


# --------------------------------------------------------------------------- barrier
def _central(f, x, h):
    return (f(x + h) - f(x - h)) / (2.0 * h)


@pytest.mark.parametrize(
    "r",
    [
        np.array([1e-4, 1e-3, 1e-2]),  # near 0
        np.linspace(0.05, 0.95, 19),
        np.array([0.99, 0.999, 0.9999]),  # near dhat
    ],
)
def test_barrier_derivatives_match_finite_differences(r):
    d = r * DHAT
    h = 1e-6 * np.minimum(d, DHAT - d)
    fd1 = _central(lambda x: barrier(x, DHAT, KAPPA), d, h)
    fd2 = _central(lambda x: barrier_derivative(x, DHAT, KAPPA), d, h)
    b1 = barrier_derivative(d, DHAT, KAPPA)
    b2 = barrier_second_derivative(d, DHAT, KAPPA)
    np.testing.assert_allclose(b1, fd1, rtol=1e-6, atol=1e-9 * np.abs(b1).max())
    np.testing.assert_allclose(b2, fd2, rtol=1e-6, atol=1e-9 * np.abs(b2).max())


def test_barrier_is_c2_at_dhat_and_zero_beyond():
    scale = np.array([KAPPA, KAPPA / DHAT, KAPPA / DHAT**2])
    kernels = (barrier, barrier_derivative, barrier_second_derivative)
    for delta, bound in ((1e-3, 1e-2), (1e-5, 1e-4)):
        d = np.array([DHAT * (1.0 - delta)])
        for k, fn in enumerate(kernels):
            # b ~ delta^3, b' ~ delta^2, b'' ~ delta as d -> dhat from below.
            assert abs(fn(d, DHAT, KAPPA)[0]) < bound * scale[k]
    beyond = np.array([DHAT, 1.5 * DHAT, 1e3])
    for fn in kernels:
        assert np.all(fn(beyond, DHAT, KAPPA) == 0.0)


def test_barrier_positive_decreasing_convex_and_blows_up():
    d = np.linspace(1e-6, 1 - 1e-6, 2001) * DHAT
    b = barrier(d, DHAT, KAPPA)
    assert np.all(b > 0.0)
    assert np.all(np.diff(b) < 0.0)
    assert np.all(barrier_derivative(d, DHAT, KAPPA) < 0.0)
    assert np.all(barrier_second_derivative(d, DHAT, KAPPA) > 0.0)
    assert barrier(np.array([1e-12 * DHAT]), DHAT, KAPPA)[0] > 20 * KAPPA
    crossed = np.array([0.0, -1e-4])
    assert np.all(barrier(crossed, DHAT, KAPPA) == np.inf)
    assert np.all(barrier_derivative(crossed, DHAT, KAPPA) == -np.inf)
    assert np.all(barrier_second_derivative(crossed, DHAT, KAPPA) == np.inf)
    assert np.isnan(barrier(np.array([np.nan]), DHAT, KAPPA)[0])


def test_barrier_scales_with_kappa_and_matches_formula():
    d = np.array([0.25 * DHAT])
    expected = -KAPPA * (0.25 - 1.0) ** 2 * np.log(0.25)
    np.testing.assert_allclose(barrier(d, DHAT, KAPPA), expected, rtol=1e-14)
    np.testing.assert_allclose(barrier(d, DHAT, 2 * KAPPA), 2 * expected, rtol=1e-14)


@pytest.mark.parametrize(("dhat", "kappa", "name"), [(0.0, 1.0, "dhat"), (1.0, -1.0, "kappa")])
def test_barrier_rejects_bad_parameters(dhat, kappa, name):
    with pytest.raises(ValueError, match=name):
        barrier(np.array([0.5]), dhat, kappa)


# --------------------------------------------------------------------------- weights
def test_particle_weights_are_disk_and_sphere_cross_sections():
    R = np.array([0.1, 0.5, 2.0])
    np.testing.assert_allclose(particle_contact_weight(np.pi * R**2, 2), 2 * R, rtol=1e-14)
    np.testing.assert_allclose(
        particle_contact_weight(4.0 / 3.0 * np.pi * R**3, 3), np.pi * R**2, rtol=1e-14
    )
    with pytest.raises(ValueError, match="volume"):
        particle_contact_weight(np.array([1.0, -1.0]), 2)
    with pytest.raises(ValueError, match="dim"):
        particle_contact_weight(np.array([1.0]), 4)


def test_boundary_weights_2d_sum_to_perimeter():
    N, R = 64, 0.7
    th = 2 * np.pi * np.arange(N) / N
    pts = R * np.stack([np.cos(th), np.sin(th)], axis=1)
    edges = np.stack([np.arange(N), (np.arange(N) + 1) % N], axis=1)
    w = boundary_vertex_weights(pts, edges)
    side = 2 * R * np.sin(np.pi / N)
    np.testing.assert_allclose(w, side, rtol=1e-12)  # two half-edges each
    np.testing.assert_allclose(w.sum(), N * side, rtol=1e-12)
    # Open polyline: the two ends get half an edge; an unused vertex gets 0.
    pts = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 2.0], [5.0, 5.0]])
    w = boundary_vertex_weights(pts, np.array([[0, 1], [1, 2]]))
    np.testing.assert_allclose(w, [0.5, 1.5, 1.0, 0.0], rtol=1e-14)


def test_boundary_weights_3d_sum_to_area():
    # Surface of the box [0, 2] x [0, 1] x [0, 3] (area 2 (2 + 6 + 3) = 22).
    corners = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], float)
    pts = corners * np.array([2.0, 1.0, 3.0])
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    tris = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
    w = boundary_vertex_weights(pts, tris)
    np.testing.assert_allclose(w.sum(), 22.0, rtol=1e-14)
    assert np.all(w > 0)
    with pytest.raises(ValueError, match="facets"):
        boundary_vertex_weights(pts, np.array([[0, 1, 8]]))
    with pytest.raises(ValueError, match="facets"):
        boundary_vertex_weights(pts, np.array([[0, 1]]))


# --------------------------------------------------------------------------- mollifier
EPS = 1e-4


def test_f0_f1_mollifier_properties():
    y = np.concatenate([np.linspace(0.0, 3 * EPS, 301), [EPS]])
    v1 = f1(y, EPS)
    assert np.all((v1 >= 0.0) & (v1 <= 1.0))
    assert f1(np.array([0.0]), EPS)[0] == 0.0
    np.testing.assert_allclose(f1(np.array([EPS * (1 - 1e-9), EPS]), EPS), 1.0, atol=1e-15)
    # f0' = f1 (FD) on both sides of eps, f0 continuous at eps and equal to y beyond.
    yy = np.array([0.1, 0.5, 0.9, 1.2, 4.0]) * EPS
    h = 1e-7 * EPS
    np.testing.assert_allclose(_central(lambda x: f0(x, EPS), yy, h), f1(yy, EPS), rtol=1e-7)
    np.testing.assert_allclose(f0(np.array([EPS * (1 - 1e-12)]), EPS), EPS, rtol=1e-10)
    np.testing.assert_allclose(f0(np.array([0.0, 2 * EPS]), EPS), [EPS / 3, 2 * EPS], rtol=1e-14)
    with pytest.raises(ValueError, match="eps"):
        f1(y, 0.0)
    with pytest.raises(ValueError, match="y"):
        f0(np.array([-1.0]), EPS)


def _samples(k, norms, rng):
    direction = rng.standard_normal((norms.size, k))
    direction /= np.linalg.norm(direction, axis=1)[:, None]
    return direction * norms[:, None]


REGIMES = {
    "static": np.array([0.05, 0.3, 0.6, 0.95]) * EPS,
    "sliding": np.array([1.05, 2.0, 10.0, 1e3]) * EPS,
    "near_zero": np.array([1e-12, 1e-9, 1e-6]) * EPS,
}


@pytest.mark.parametrize("k", [1, 2])
@pytest.mark.parametrize("regime", sorted(REGIMES))
def test_friction_local_matches_finite_differences(k, regime, rng):
    u = _samples(k, REGIMES[regime], rng)
    mu_lambda = rng.uniform(0.5, 2.0, u.shape[0])
    value, grad, hess = friction_local(u, mu_lambda, EPS)
    np.testing.assert_allclose(value, mu_lambda * f0(np.linalg.norm(u, axis=1), EPS))
    h = 1e-7 * EPS
    for j in range(k):
        du = np.zeros_like(u)
        du[:, j] = h
        vp, gp, _ = friction_local(u + du, mu_lambda, EPS)
        vm, gm, _ = friction_local(u - du, mu_lambda, EPS)
        np.testing.assert_allclose(grad[:, j], (vp - vm) / (2 * h), rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(
            hess[:, :, j], (gp - gm) / (2 * h), rtol=1e-5, atol=1e-5 * mu_lambda.max() / EPS
        )
    assert np.allclose(hess, np.swapaxes(hess, 1, 2))


@pytest.mark.parametrize("k", [1, 2])
def test_friction_at_rest_is_finite_stiff_and_forceless(k):
    u = np.zeros((2, k))
    mu_lambda = np.array([1.0, 3.0])
    value, grad, hess = friction_local(u, mu_lambda, EPS)
    np.testing.assert_allclose(value, mu_lambda * EPS / 3)
    assert np.all(grad == 0.0)
    np.testing.assert_allclose(hess, (2 / EPS * mu_lambda)[:, None, None] * np.eye(k))


@pytest.mark.parametrize("k", [1, 2])
def test_friction_psd_and_coulomb_bound(k, rng):
    norms = np.concatenate([v for v in REGIMES.values()] + [np.array([0.0, EPS])])
    u = _samples(k, norms, rng)
    mu_lambda = rng.uniform(0.0, 5.0, u.shape[0])
    _, grad, hess = friction_local(u, mu_lambda, EPS)
    _, grad_p, hess_p = friction_local(u, mu_lambda, EPS, psd=True)
    np.testing.assert_array_equal(grad, grad_p)
    eig = np.linalg.eigvalsh(hess_p)
    assert np.all(eig >= -1e-12 * mu_lambda.max() / EPS)
    # Eigenvalues: mu_lambda f1'(y) along u, mu_lambda f1(y) / y across.
    y = np.linalg.norm(u, axis=1)
    along = mu_lambda * np.where(y < EPS, 2 * (1 - y / EPS) / EPS, 0.0)
    across = mu_lambda * np.where(y < EPS, (2 - y / EPS) / EPS, 1 / np.maximum(y, EPS))
    expected = np.sort(np.stack([along, across], axis=1)[:, :k], axis=1)
    moving = y > 0
    np.testing.assert_allclose(eig[moving], expected[moving], rtol=1e-10, atol=1e-10)
    # The friction force -grad never exceeds mu lambda, opposes u, and saturates when sliding.
    force = np.linalg.norm(grad, axis=1)
    assert np.all(force <= mu_lambda * (1 + 1e-14))
    assert np.all(np.einsum("ij,ij->i", grad, u) >= 0.0)
    sliding = y >= EPS
    np.testing.assert_allclose(force[sliding], mu_lambda[sliding], rtol=1e-14)


def test_friction_local_rejects_bad_input():
    with pytest.raises(ValueError, match="mu_lambda"):
        friction_local(np.zeros((2, 2)), np.array([1.0, -1.0]), EPS)
    with pytest.raises(ValueError, match="mu_lambda"):
        friction_local(np.zeros((2, 2)), np.array([1.0]), EPS)
    with pytest.raises(ValueError, match="u "):
        friction_local(np.zeros(3), np.ones(3), EPS)
