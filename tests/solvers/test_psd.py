"""PSD projection of stacks of symmetric blocks."""

import numpy as np
import pytest
from numba import njit

from solvers._psd_kernels import _symmetric_eigen_2x2
from solvers.psd import is_symmetric_psd, project_psd


def _random_symmetric(rng, s, n):
    a = rng.standard_normal((s, n, n))
    return 0.5 * (a + a.transpose(0, 2, 1))


@pytest.mark.parametrize("n", [2, 3, 6, 9])
def test_projection_is_symmetric_psd_and_keeps_eigenvectors(n):
    rng = np.random.default_rng(n)
    blocks = _random_symmetric(rng, 50, n)
    assert not is_symmetric_psd(blocks)
    out = project_psd(blocks)
    assert out.shape == blocks.shape and out.dtype == np.float64 and out.flags.c_contiguous
    np.testing.assert_array_equal(out, out.transpose(0, 2, 1))
    assert is_symmetric_psd(out, rtol=1e-12)
    w, v = np.linalg.eigh(blocks)
    # Each eigenvector of the input is an eigenvector of the output, eigenvalue max(w, 0).
    out_v = out @ v
    np.testing.assert_allclose(out_v, v * np.maximum(w, 0.0)[:, None, :], atol=1e-12)
    # Closest PSD matrix in Frobenius norm: the discarded part is exactly the negative spectrum.
    removed = np.linalg.norm(out - blocks, axis=(1, 2))
    np.testing.assert_allclose(removed, np.sqrt((np.minimum(w, 0.0) ** 2).sum(axis=1)), rtol=1e-10)


def test_psd_input_is_unchanged_and_input_not_modified():
    rng = np.random.default_rng(7)
    a = rng.standard_normal((20, 4, 4))
    psd = a @ a.transpose(0, 2, 1)
    copy = psd.copy()
    out = project_psd(psd)
    np.testing.assert_array_equal(out, psd)
    np.testing.assert_array_equal(psd, copy)
    assert out is not psd


def test_eps_clamps_eigenvalues_from_below():
    blocks = np.array([np.diag([-3.0, 0.5, 2.0]), np.diag([1.0, 1.0, 1.0])])
    out = project_psd(blocks, eps=1.0)
    np.testing.assert_allclose(np.linalg.eigvalsh(out), [[1.0, 1.0, 2.0], [1.0, 1.0, 1.0]])


def test_empty_stack_and_bad_input():
    assert project_psd(np.zeros((0, 3, 3))).shape == (0, 3, 3)
    with pytest.raises(ValueError, match="square"):
        project_psd(np.zeros((2, 3, 2)))
    with pytest.raises(ValueError, match="eps"):
        project_psd(np.zeros((1, 2, 2)), eps=-1.0)


def test_is_symmetric_psd_rejects_asymmetric():
    blocks = np.array([[[2.0, 1.0], [0.0, 2.0]]])
    assert not is_symmetric_psd(blocks)
    assert is_symmetric_psd(np.array([[[2.0, 1.0], [1.0, 2.0]]]))


@pytest.mark.parametrize("n", [1, 4, 12])
def test_projection_matches_eigh_on_degenerate_blocks(n):
    """Repeated, zero and tiny eigenvalues (rank-deficient blocks like the barrier's): the
    result is V max(w, 0) V^T of numpy's eigh up to round-off."""
    rng = np.random.default_rng(n)
    q, _ = np.linalg.qr(rng.standard_normal((30, n, n)))
    w = rng.choice([-2.0, 0.0, 1e-14, 1.0, 1.0, 3.0], (30, n))
    blocks = (q * w[:, None, :]) @ q.transpose(0, 2, 1)
    blocks = 0.5 * (blocks + blocks.transpose(0, 2, 1))
    ew, ev = np.linalg.eigh(blocks)
    expected = (ev * np.maximum(ew, 0.0)[:, None, :]) @ ev.transpose(0, 2, 1)
    out = project_psd(blocks)
    np.testing.assert_allclose(out, expected, atol=1e-13 * np.abs(blocks).max(), rtol=0.0)
    assert is_symmetric_psd(out, rtol=1e-12)


def test_non_finite_blocks_become_nan_and_leave_the_others():
    blocks = np.array([np.eye(3), np.full((3, 3), np.inf), -np.eye(3)])
    blocks[1, 0, 0] = np.nan
    out = project_psd(blocks)
    np.testing.assert_array_equal(out[0], np.eye(3))
    assert np.isnan(out[1]).all()
    np.testing.assert_array_equal(out[2], np.zeros((3, 3)))


@njit
def _eigen_2x2(a):  # noqa: ANN001, ANN202
    v = np.empty((2, 2))
    w = np.empty(2)
    ok = _symmetric_eigen_2x2(a, v, w)
    return ok, v, w


def test_closed_form_2x2_eigen_matches_eigh():
    rng = np.random.default_rng(7)
    cases = [rng.standard_normal((2, 2)) * 10.0 ** rng.integers(-6, 7) for _ in range(500)]
    cases += [3.0 * np.eye(2), np.diag([2.0, -1.0]), np.diag([-1.0, 2.0]), np.zeros((2, 2))]
    cases += [np.array([[1.0, 1e-9], [1e-9, 1.0]]), np.array([[1e8, 1.0], [1.0, 1e-8]])]
    for a in cases:
        ok, v, w = _eigen_2x2(a)
        sym = 0.5 * (a + a.T)
        assert ok
        np.testing.assert_allclose(
            np.sort(w), np.linalg.eigvalsh(sym), atol=1e-14 * np.abs(sym).max()
        )
        np.testing.assert_allclose(v.T @ v, np.eye(2), atol=1e-14)  # orthonormal
        np.testing.assert_allclose(sym @ v, v * w, atol=1e-13 * max(np.abs(sym).max(), 1e-300))
    for bad in (np.nan, np.inf):
        ok, _, _ = _eigen_2x2(np.array([[1.0, bad], [0.0, 1.0]]))
        assert not ok
