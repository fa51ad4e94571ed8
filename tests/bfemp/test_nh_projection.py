"""The analytic PSD projection of the Neo-Hookean dP/dF equals the generic eigenvalue clamp."""

import numpy as np
import pytest

from bfemp._material_kernels import NEO_HOOKEAN
from solvers.psd import is_symmetric_psd, project_psd


def _blocks(F, mu=3e4, lam=8e4):
    n = F.shape[0]
    mu, lam = np.full(n, mu), np.full(n, lam)
    d = F.shape[1]
    A = NEO_HOOKEAN.first_piola_derivative(F, mu, lam).reshape(-1, d * d, d * d)
    return np.ascontiguousarray(A), mu, lam


@pytest.mark.parametrize("d", [2, 3])
def test_analytic_projection_is_the_nearest_psd_matrix(d):
    rng = np.random.default_rng(d)
    F = np.concatenate(
        [
            np.eye(d) + 0.01 * rng.standard_normal((300, d, d)),  # near rest
            0.5 * (np.eye(d) + 0.3 * rng.standard_normal((300, d, d))),  # compressed, sheared
            np.eye(d) + 0.6 * rng.standard_normal((300, d, d)),
            np.repeat(np.diag([1.2] * (d - 1) + [0.7])[None], 5, axis=0),  # equal singular values
            np.repeat(np.eye(d)[None], 5, axis=0),
        ]
    )
    F = F[np.linalg.det(F) > 0.05]
    A, mu, lam = _blocks(F)
    got = NEO_HOOKEAN.project_derivative(A, F, mu, lam)
    ref = project_psd(A)
    scale = np.abs(A).max(axis=(1, 2))
    assert (np.abs(got - ref).max(axis=(1, 2)) / scale).max() < 1e-10
    assert is_symmetric_psd(got, rtol=1e-10)
    indefinite = np.linalg.eigvalsh(A)[:, 0] < 0.0
    assert indefinite.any() and (~indefinite).any()  # both kinds of block were met
    # blocks with no negative eigenvalue are returned bit-for-bit
    assert all(np.array_equal(g, a) for g, a in zip(got[~indefinite], A[~indefinite], strict=True))
    # a negative control: the unprojected blocks are not PSD
    assert not is_symmetric_psd(A, rtol=1e-10)


def test_ill_conditioned_and_non_finite_blocks():
    F = np.array([np.diag([1.0, 1.0, 1e-6]), np.diag([2.0, 1.0, 0.5])])
    A, mu, lam = _blocks(F)
    A[1, 0, 0] = np.nan
    got = NEO_HOOKEAN.project_derivative(A, F, mu, lam)
    # s_min / s_max = 1e-6: the generic projection of that block
    np.testing.assert_allclose(
        got[0], project_psd(A[:1])[0], rtol=0, atol=1e-9 * np.abs(A[0]).max()
    )
    assert np.isnan(got[1]).all()


def _rotations(rng, n):
    q, _ = np.linalg.qr(rng.standard_normal((n, 3, 3)))
    return q * np.sign(np.linalg.det(q))[:, None, None]


def test_analytic_projection_holds_near_inversion_and_at_large_stretch():
    """F = R1 diag(s) R2 with s_min down to 1.3e-4 s_max (near inversion: the fallback to the
    generic projection starts at 1e-4) and s_max up to 32 (stretch): equal to the generic clamp
    to 1e-10 of the block. With s from the square roots of the eigenvalues of F^T F the
    near-inverted blocks differed by 3e-8 (eps s_max^2 / s_min^2); with s_a = |F v_a|, 6e-12."""
    rng = np.random.default_rng(11)
    n = 400
    near = np.column_stack([rng.uniform(0.5, 1.5, (n, 2)), 10 ** rng.uniform(-3.9, -2.0, n)])
    stretched = np.column_stack([10 ** rng.uniform(0.5, 1.5, (n, 1)), rng.uniform(0.3, 2, (n, 2))])
    for s in (near, stretched):
        F = _rotations(rng, n) @ (s[:, :, None] * _rotations(rng, n))
        A, mu, lam = _blocks(F)
        got = NEO_HOOKEAN.project_derivative(A, F, mu, lam)
        scale = np.abs(A).max(axis=(1, 2))
        assert (np.abs(got - project_psd(A)).max(axis=(1, 2)) / scale).max() < 1e-10
        assert (np.linalg.eigvalsh(A)[:, 0] < 0.0).mean() > 0.5  # mostly indefinite blocks
