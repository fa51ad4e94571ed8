"""Tests of geometry.mollifier: value against its definition, gradient and Hessian against finite
differences on both sides of the threshold, C1 continuity at c = eps_x, input validation."""

import numpy as np
import pytest

from geometry import mollifier as gm
from tests.geometry.conftest import cols


def cross_sq(X):
    n = np.cross(X[:, 1] - X[:, 0], X[:, 3] - X[:, 2])
    return np.einsum("ij,ij->i", n, n)


def edges(n, seed):
    return np.random.default_rng(seed).uniform(-1, 1, (n, 4, 3))


@pytest.mark.parametrize("x", [0.05, 0.4, 0.9])
def test_value_matches_definition(x):
    X = edges(50, 1)
    eps_x = cross_sq(X) / x
    np.testing.assert_allclose(gm.edge_edge_mollifier(*cols(X), eps_x), (2 - x) * x, rtol=1e-12)
    assert np.all(gm.edge_edge_mollifier(*cols(X), cross_sq(X) / 1.5) == 1.0)


def test_parallel_edges_have_zero_mollifier_and_threshold_formula():
    X = edges(10, 2)
    X[:, 3] = X[:, 2] + 0.3 * (X[:, 1] - X[:, 0])
    eps_x = gm.edge_edge_mollifier_threshold(*cols(X))
    a, b = X[:, 1] - X[:, 0], X[:, 3] - X[:, 2]
    np.testing.assert_allclose(eps_x, 1e-3 * (a * a).sum(axis=1) * (b * b).sum(axis=1), rtol=1e-14)
    assert np.all(gm.edge_edge_mollifier(*cols(X), eps_x) < 1e-12)


@pytest.mark.parametrize("x", [0.1, 0.6, 1.3])
def test_gradient_and_hessian_match_finite_differences(x):
    X = edges(20, 3)
    eps_x = cross_sq(X) / x
    g = gm.edge_edge_mollifier_gradient(*cols(X), eps_x)
    H = gm.edge_edge_mollifier_hessian(*cols(X), eps_x)
    assert np.allclose(H, np.swapaxes(H, 1, 2), atol=1e-12 * np.abs(H).max(initial=1.0))
    h = 1e-6
    flat = X.reshape(-1, 12)
    for j in range(12):
        dp, dm = flat.copy(), flat.copy()
        dp[:, j] += h
        dm[:, j] -= h
        Xp, Xm = dp.reshape(-1, 4, 3), dm.reshape(-1, 4, 3)
        fd_g = gm.edge_edge_mollifier(*cols(Xp), eps_x) - gm.edge_edge_mollifier(*cols(Xm), eps_x)
        fd_H = gm.edge_edge_mollifier_gradient(*cols(Xp), eps_x) - gm.edge_edge_mollifier_gradient(
            *cols(Xm), eps_x
        )
        scale_g = np.abs(g).max(axis=1, initial=1.0)
        scale_H = np.abs(H).max(axis=(1, 2), initial=1.0)
        assert np.all(np.abs(fd_g / (2 * h) - g[:, j]) <= 1e-6 * scale_g)
        assert np.all(np.abs(fd_H / (2 * h) - H[:, :, j]).max(axis=1) <= 1e-5 * scale_H)
    if x > 1:
        assert np.all(g == 0.0) and np.all(H == 0.0)
    else:
        assert np.abs(g).max() > 0.0


def test_c1_at_threshold():
    X = edges(20, 4)
    c = cross_sq(X)
    gmax = []
    for rel in (1e-4, 1e-6):
        below, above = c / (1 - rel), c / (1 + rel)  # c slightly below / above eps_x
        m_below = gm.edge_edge_mollifier(*cols(X), below)
        np.testing.assert_allclose(m_below, 1.0, atol=2 * rel**2)
        assert np.all(gm.edge_edge_mollifier(*cols(X), above) == 1.0)
        g = gm.edge_edge_mollifier_gradient(*cols(X), below)
        # |grad m| = m'(c) |grad c| with m'(c) = 2 (1 - c / eps_x) / eps_x -> 0 linearly.
        gc = np.linalg.norm(gm.edge_edge_mollifier_gradient(*cols(X), 2 * c), axis=1) * c
        gmax.append(np.max(np.linalg.norm(g, axis=1) / gc))
        assert np.all(gm.edge_edge_mollifier_gradient(*cols(X), above) == 0.0)
    assert gmax[1] < 1.1e-2 * gmax[0]


def test_numba_kernel_matches_python_reference():
    X = edges(5, 5)
    eps_x = cross_sq(X) / 0.5
    fast = gm._evaluate(X, eps_x, 2)
    slow = gm._evaluate.py_func(X, eps_x, 2)
    for a, b in zip(fast, slow, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-13, atol=1e-15)


def test_rejects_bad_input():
    X = edges(3, 6)
    with pytest.raises(ValueError, match="eps_x"):
        gm.edge_edge_mollifier(*cols(X), np.array([1.0, 0.0, 1.0]))
    with pytest.raises(ValueError, match="eps_x"):
        gm.edge_edge_mollifier(*cols(X), np.ones(2))
    with pytest.raises(ValueError, match="eb1"):
        gm.edge_edge_mollifier(X[:, 0], X[:, 1], X[:, 2], X[:2, 3], np.ones(3))
