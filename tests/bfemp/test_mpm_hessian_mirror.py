"""The MPM node-pair Hessian accumulated over half the pairs and mirrored equals the full sum."""

import numpy as np
import pytest

from bfemp.mpm._hessian_kernels import _accumulate_blocks, _neighbour_table
from bfemp.mpm.elasticity import pair_codes
from geometry.grid import stencil_offsets


@pytest.mark.parametrize("dim", [2, 3])
def test_mirrored_accumulation_equals_the_full_double_sum(dim):
    rng = np.random.default_rng(dim)
    side = 6
    offsets = stencil_offsets(dim)  # (K, d) in {0, 1, 2}^d
    n_p, k = 40, offsets.shape[0]
    base = rng.integers(0, side - 2, (n_p, dim))
    cells = base[:, None, :] + offsets[None, :, :]
    nodes = np.ravel_multi_index(tuple(np.moveaxis(cells, -1, 0)), (side,) * dim)
    weights = rng.random((n_p, k)) + 0.1
    grads = rng.standard_normal((n_p, k, dim))
    a = rng.standard_normal((n_p, dim * dim, dim * dim))
    dpdf = a + np.transpose(a, (0, 2, 1))  # symmetric, indefinite: exact Hessians too
    volume = rng.random(n_p) + 0.5
    codes = pair_codes(dim)
    n_nodes, n_codes = side**dim, 5**dim
    nbr = _neighbour_table(nodes, weights, grads, codes, n_nodes, n_codes)
    got = _accumulate_blocks(nodes, weights, grads, dpdf, volume, codes, nbr, n_nodes, n_codes, 2)
    want = np.zeros_like(got)
    dp = dpdf.reshape(n_p, dim, dim, dim, dim)  # [p, i, m, j, l]
    for p in range(n_p):
        blk = volume[p] * np.einsum("am,imjl,bl->abij", grads[p], dp[p], grads[p])
        for ia in range(k):
            for ib in range(k):
                want[nodes[p, ia], codes[ia, ib]] += blk[ia, ib]
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12 * np.abs(want).max())
