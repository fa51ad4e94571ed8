"""numba set-up kernels of the MPM elasticity term against the numpy routes they replace."""

import numpy as np
import pytest

from bfemp.mpm._hessian_kernels import _effective_gradients, _neighbour_table, _pair_pattern
from bfemp.mpm.elasticity import pair_codes
from geometry.grid import Grid, particle_stencils


@pytest.mark.parametrize("dim", [2, 3])
def test_effective_gradients_equal_the_einsum_route(dim):
    """g = F^nT grad w and C = F^n - sum_k x_k g_k^T (BFEMP eq. 25) of a subset of particles:
    the same bits as the two ``np.einsum`` calls of ``mpm_particle_stencils`` before, and C is
    zero to round-off (linear completeness: F(x^n) = F^n)."""
    rng = np.random.default_rng(dim)
    grid = Grid.make(dx=0.1, dim=dim)
    x = rng.random((300, dim))
    x[:20] = np.round(x[:20] / 0.1 + 0.5) * 0.1 - 0.05  # on cell-centre planes: zero weights
    st = particle_stencils(grid, x)
    F_n = np.eye(dim) + 0.2 * rng.standard_normal((300, dim, dim))
    particles = np.sort(rng.choice(300, 150, replace=False))
    g, const = _effective_gradients(F_n, st.grads, st.nodes, st.active_x, particles)
    want_g = np.einsum("pji,pkj->pki", F_n[particles], st.grads[particles])
    x_n = st.active_x[st.nodes[particles]]
    want_c = F_n[particles] - np.einsum("pki,pkj->pij", x_n, want_g)
    assert np.array_equal(g, want_g)
    assert np.array_equal(const, want_c)
    assert np.abs(const).max() < 1e-12


def _numpy_pair_pattern(nbr, dof_grid, d):
    """The rows, columns and kept mask of ``MpmElasticityTerm.begin_step`` before the kernel."""
    n_grid, n_codes = nbr.shape
    row_node = np.repeat(np.arange(n_grid), n_codes)
    col_node = nbr.reshape(-1)
    has = col_node >= 0
    dof_row = dof_grid[row_node]
    dof_col = np.where(has, dof_grid[np.where(has, col_node, 0)], -1)
    comp = np.arange(d)
    rows = (dof_row[:, None, None] * d + comp[None, :, None]) * np.ones(d, dtype=np.int64)
    cols = (dof_col[:, None, None] * d + comp[None, None, :]) * np.ones((d, 1), dtype=np.int64)
    keep = ((dof_row >= 0) & (dof_col >= 0))[:, None, None] & np.ones((d, d), dtype=bool)
    keep = keep.reshape(-1)
    return rows.reshape(-1)[keep], cols.reshape(-1)[keep], keep


@pytest.mark.parametrize("dim", [2, 3])
def test_pair_pattern_equals_the_numpy_route_before_and_after_particles_cross_cells(dim):
    """The node-pair pattern of the MPM Hessian (numba ``_pair_pattern``) equals the numpy
    route it replaces, with sticky (dropped) grid nodes, on particles sampled on cell faces and
    cell-centre planes and again after they move across cells (a new active grid)."""
    rng = np.random.default_rng(10 + dim)
    grid = Grid.make(dx=0.1, dim=dim)
    x = rng.random((400, dim))
    x[:30] = np.round(x[:30] / 0.1) * 0.1  # on cell faces
    x[30:60] = np.round(x[30:60] / 0.1 + 0.5) * 0.1 - 0.05  # on cell-centre planes
    codes = pair_codes(dim)
    sizes = []
    for moved in (x, x + rng.uniform(0.05, 0.15, dim)):
        st = particle_stencils(grid, moved)
        nbr = _neighbour_table(st.nodes, st.weights, st.grads, codes, st.n_nodes, 5**dim)
        dof_grid = np.arange(st.n_nodes) + 7  # unknowns numbered after some FEM nodes
        dof_grid[rng.random(st.n_nodes) < 0.2] = -1  # sticky nodes
        dof_grid[dof_grid >= 0] = np.arange(np.count_nonzero(dof_grid >= 0)) + 7
        got = _pair_pattern(nbr, dof_grid, dim)
        want = _numpy_pair_pattern(nbr, dof_grid, dim)
        for name, g, w in zip(("rows", "cols", "keep"), got, want, strict=True):
            assert np.array_equal(g, w), name
        sizes.append(got[0].size)
    assert sizes[0] > 0 and sizes[1] > 0
