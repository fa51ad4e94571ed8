"""The fused barrier kernels and the chain rule to node DOFs against their plain definitions.

_barrier_hessians projects each pair's Hessian in the difference coordinates of its closest
feature; that must equal the PSD projection of the full (m d)^2 block. _chain_hessian sums the
pairs' node blocks as it goes; the matrix must equal sum_p W_p^T H_p W_p.
"""

import numpy as np
import pytest

from bfemp.contact._assembly_kernels import _chain_hessian
from bfemp.contact._barrier_kernels import _barrier_gradients, _barrier_hessians, _pair_distances
from geometry import distance as dist
from geometry._distance_kernels import KIND_EE, KIND_PE, KIND_PP, KIND_PT
from solvers.assembly import TripletAssembler, Triplets
from solvers.psd import is_symmetric_psd, project_psd

_FUNCTIONS = {
    KIND_PP: (
        dist.point_point_distance,
        dist.point_point_distance_gradient,
        dist.point_point_distance_hessian,
    ),
    KIND_PE: (
        dist.point_edge_distance,
        dist.point_edge_distance_gradient,
        dist.point_edge_distance_hessian,
    ),
    KIND_PT: (
        dist.point_triangle_distance,
        dist.point_triangle_distance_gradient,
        dist.point_triangle_distance_hessian,
    ),
}
_POINTS = {KIND_PP: 2, KIND_PE: 3, KIND_PT: 4, KIND_EE: 4}


def _pairs(kind, dim, n, rng):
    """Collision positions (C, dim) and pairs (n, m) of every closest-feature type: random
    primitives (unit size) and points scattered around them."""
    m = _POINTS[kind]
    pos = rng.uniform(-1.0, 1.0, (n * m, dim))
    pos[::m] *= 1.5  # the query points, often beyond the primitive's ends / edges
    return pos, np.arange(n * m).reshape(n, m)


@pytest.mark.parametrize(
    "kind, dim", [(KIND_PP, 2), (KIND_PP, 3), (KIND_PE, 2), (KIND_PE, 3), (KIND_PT, 3)]
)
def test_barrier_kernels_equal_the_full_block_formulas(kind, dim, rng):
    pos, pts = _pairs(kind, dim, 400, rng)
    args = [pos[pts[:, a]] for a in range(pts.shape[1])]
    value, grad, hess = (fn(*args) for fn in _FUNCTIONS[kind])
    np.testing.assert_array_equal(_pair_distances(pos, pts, kind), value)
    if kind != KIND_PP:
        types = (dist.point_edge_type if kind == KIND_PE else dist.point_triangle_type)(*args)
        assert np.unique(types).size == (3 if kind == KIND_PE else 7)  # every type met
    c1 = -rng.uniform(1.0, 1e3, len(pts))  # b' < 0
    c2 = rng.uniform(1.0, 1e5, len(pts))  # b'' > 0
    full = c2[:, None, None] * grad[:, :, None] * grad[:, None, :] + c1[:, None, None] * hess
    scale = np.abs(full).max(axis=(1, 2))[:, None, None]
    local = c1[:, None] * grad
    row_scale = np.abs(local).max(axis=1)[:, None]
    assert np.all(np.abs(_barrier_gradients(pos, pts, kind, c1) - local) <= 1e-14 * row_scale)
    raw = _barrier_hessians(pos, pts, kind, c1, c2, False)
    assert np.all(np.abs(raw - full) <= 1e-14 * scale)
    projected = _barrier_hessians(pos, pts, kind, c1, c2, True)
    assert np.all(np.abs(projected - project_psd(full)) <= 1e-12 * scale)
    np.testing.assert_array_equal(projected, projected.transpose(0, 2, 1))
    assert is_symmetric_psd(projected, rtol=1e-12)


def test_barrier_hessian_of_a_touching_pair_is_nan_when_projected():
    pos = np.array([[0.0, 0.0], [-1.0, 0.0], [1.0, 0.0]])
    pts = np.array([[0, 1, 2]])
    out = _barrier_hessians(pos, pts, KIND_PE, np.array([-np.inf]), np.array([np.inf]), True)
    assert np.isnan(out).all()


def _collision_map(rng, n_points, k, n_all, n_fixed):
    """Random stencils: some zero weights, some prescribed nodes (dof_node -1)."""
    nodes = rng.integers(0, n_all, (n_points, k))
    weights = rng.uniform(0.1, 1.0, (n_points, k))
    weights[rng.random((n_points, k)) < 0.2] = 0.0
    dof_node = np.full(n_all, -1, dtype=np.int64)
    free = np.sort(rng.choice(n_all, n_all - n_fixed, replace=False))
    dof_node[free] = np.arange(free.size)
    return nodes, weights, dof_node


@pytest.mark.parametrize("dim, m", [(2, 3), (3, 4), (3, 2)])
def test_chain_hessian_equals_the_dense_chain_rule(dim, m, rng):
    n_pairs, n_points, k, n_all = 300, 120, 9, 60
    nodes, weights, dof_node = _collision_map(rng, n_points, k, n_all, n_fixed=8)
    pts = np.stack([rng.choice(n_points, m, replace=False) for _ in range(n_pairs)])
    a = rng.standard_normal((n_pairs, m * dim, m * dim))
    hess = a + a.transpose(0, 2, 1)
    rows, cols, vals = _chain_hessian(hess, pts, nodes, weights, dof_node)
    n_dof = int(dof_node.max() + 1) * dim
    keys = rows * n_dof + cols
    assert np.unique(keys).size == keys.size  # one triplet per coupled DOF pair
    got = TripletAssembler(n_dof).assemble(Triplets(rows, cols, vals)).toarray()
    np.testing.assert_array_equal(got, got.T)
    # dense reference: W_p (m d, n_dof) maps node DOFs to the pair's points
    expected = np.zeros((n_dof, n_dof))
    for p in range(n_pairs):
        w = np.zeros((m * dim, n_dof))
        for a_, c in enumerate(pts[p]):
            for j in range(k):
                dn = dof_node[nodes[c, j]]
                if weights[c, j] != 0.0 and dn >= 0:
                    for i in range(dim):
                        w[a_ * dim + i, dn * dim + i] += weights[c, j]
        expected += w.T @ hess[p] @ w
    np.testing.assert_allclose(got, expected, rtol=0.0, atol=1e-12 * np.abs(expected).max())


def test_chain_hessian_of_no_free_node_is_empty(rng):
    nodes, weights, _ = _collision_map(rng, 10, 4, 12, n_fixed=0)
    dof_node = np.full(12, -1, dtype=np.int64)
    hess = np.ones((5, 6, 6))
    rows, cols, vals = _chain_hessian(
        hess, np.arange(15).reshape(5, 3) % 10, nodes, weights, dof_node
    )
    assert rows.size == cols.size == vals.size == 0
