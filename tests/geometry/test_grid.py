"""Tests of geometry.grid: quadratic B-spline stencils, active-node compaction, cell counts."""

import numpy as np
import pytest

import geometry.grid as grid_mod
from geometry.grid import (
    Grid,
    grid_cell_counts,
    particle_stencils,
    particles_per_cell,
    stencil_offsets,
)
from geometry.sampling import sample_box


def bspline(r):
    """Direct 1-D quadratic B-spline N(r), r in cell units."""
    r = np.abs(r)
    return np.where(r < 0.5, 0.75 - r**2, np.where(r < 1.5, 0.5 * (1.5 - r) ** 2, 0.0))


def random_particles(dim, n=200, seed=0):
    grid = Grid(dx=0.37, origin=(0.3, -1.1, 0.05)[:dim])
    x = np.random.default_rng(seed).uniform(-2.0, 3.0, size=(n, dim))
    return grid, x


# --------------------------------------------------------------------------- Grid
def test_grid_make_and_node_positions():
    grid = Grid.make(0.5, 3)
    assert grid.origin == (0.0, 0.0, 0.0) and grid.dim == 3
    g2 = Grid.make(0.25, 2, origin=(1.0, -1.0))
    pos = g2.node_positions(np.array([[0, 0], [2, -4]]))
    np.testing.assert_array_equal(pos, [[1.0, -1.0], [1.5, -2.0]])
    np.testing.assert_array_equal(
        g2.cells_of(np.array([[1.1, -1.1], [0.99, -0.76]])),
        [
            [0, -1],
            [-1, 0],
        ],
    )


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"dx": 0.0, "origin": (0.0, 0.0)}, "dx"),
        ({"dx": -1.0, "origin": (0.0, 0.0)}, "dx"),
        ({"dx": float("nan"), "origin": (0.0, 0.0)}, "dx"),
        ({"dx": "a", "origin": (0.0, 0.0)}, "dx"),
        ({"dx": 0.1, "origin": (0.0,)}, "origin"),
        ({"dx": 0.1, "origin": (0.0, float("inf"))}, "origin"),
    ],
)
def test_grid_validation_names_the_field(kwargs, match):
    with pytest.raises(ValueError, match=match):
        Grid(**kwargs)


def test_grid_rejects_bad_inputs():
    grid = Grid.make(0.1, 2)
    with pytest.raises(ValueError, match="dim"):
        Grid.make(0.1, 4)
    with pytest.raises(ValueError, match="ijk"):
        grid.node_positions(np.zeros((3, 2)))  # float, not integer
    with pytest.raises(ValueError, match=r"x must have shape \(P, 2\)"):
        particle_stencils(grid, np.zeros((4, 3)))
    with pytest.raises(ValueError, match="non-finite"):
        particle_stencils(grid, np.array([[0.0, np.nan]]))


def test_stencil_offsets_are_lexicographic_first_axis_slowest():
    off = stencil_offsets(2)
    assert off.shape == (9, 2)
    np.testing.assert_array_equal(off[3 * 2 + 1], [2, 1])
    off3 = stencil_offsets(3)
    np.testing.assert_array_equal(off3[9 * 1 + 3 * 2 + 0], [1, 2, 0])
    np.testing.assert_array_equal(off3[13], [1, 1, 1])  # the centre node


# --------------------------------------------------------------------------- B-spline identities
@pytest.mark.parametrize("dim", [2, 3])
def test_partition_of_unity_and_linear_completeness(dim):
    grid, x = random_particles(dim)
    st = particle_stencils(grid, x)
    assert st.nodes.shape == (len(x), 3**dim) and st.grads.shape == (len(x), 3**dim, dim)
    assert st.dim == dim and st.n_particles == len(x)
    xi = st.active_x[st.nodes]  # (P, K, d)
    np.testing.assert_allclose(st.weights.sum(axis=1), 1.0, atol=1e-14)
    np.testing.assert_allclose(st.grads.sum(axis=1), 0.0, atol=1e-12)
    np.testing.assert_allclose(np.einsum("pk,pka->pa", st.weights, xi), x, atol=1e-13)
    eye = np.broadcast_to(np.eye(dim), (len(x), dim, dim))
    np.testing.assert_allclose(np.einsum("pka,pkb->pab", xi, st.grads), eye, atol=1e-12)
    assert np.all(st.weights >= 0.0)


@pytest.mark.parametrize("dim", [2, 3])
def test_weights_match_direct_tensor_product_formula(dim):
    grid, x = random_particles(dim, seed=1)
    st = particle_stencils(grid, x, drop_zero_weights=False)
    r = (x[:, None, :] - st.active_x[st.nodes]) / grid.dx  # (P, K, d) in cell units
    np.testing.assert_allclose(st.weights, bspline(r).prod(axis=2), atol=1e-14)
    # The stencil is base + offsets: node ijk - base runs over {0,1,2}^d in the documented order.
    ijk = st.active_ijk[st.nodes]
    base = np.floor((x - np.asarray(grid.origin)) / grid.dx - 0.5).astype(np.int64)
    np.testing.assert_array_equal(
        ijk - base[:, None, :], np.broadcast_to(stencil_offsets(dim), ijk.shape)
    )


@pytest.mark.parametrize("dim", [2, 3])
def test_gradients_match_central_finite_differences(dim):
    grid, x = random_particles(dim, n=50, seed=2)
    st = particle_stencils(grid, x, drop_zero_weights=False)
    h = 1e-6 * grid.dx
    for a in range(dim):  # loop over the axes only
        step = np.zeros(dim)
        step[a] = h
        plus = particle_stencils(grid, x + step, drop_zero_weights=False)
        minus = particle_stencils(grid, x - step, drop_zero_weights=False)
        # Same base nodes (no particle crosses a base boundary for so small a step).
        np.testing.assert_array_equal(plus.active_ijk[plus.nodes], st.active_ijk[st.nodes])
        np.testing.assert_array_equal(minus.active_ijk[minus.nodes], st.active_ijk[st.nodes])
        fd = (plus.weights - minus.weights) / (2.0 * h)
        np.testing.assert_allclose(st.grads[:, :, a], fd, atol=1e-6 / grid.dx)


def test_particle_on_a_node_has_the_1_8_3_4_1_8_weights():
    grid = Grid(dx=0.5, origin=(1.0, -2.0))
    x = np.array([[1.0 + 0.5 * 3, -2.0 + 0.5 * -5]])  # exactly node (3, -5)
    st = particle_stencils(grid, x)
    w1 = np.array([0.125, 0.75, 0.125])
    np.testing.assert_array_equal(st.weights[0], np.outer(w1, w1).ravel())
    np.testing.assert_array_equal(st.active_ijk[st.nodes[0, 4]], [3, -5])  # centre entry
    np.testing.assert_array_equal(st.active_ijk[st.nodes[0, 0]], [2, -6])
    # Gradient of the centre node vanishes (symmetric); the node one cell to the -x side
    # (offset (0, 1)) has d/dx = -(1.5 - 1) / dx * 3/4 (weight falls as the particle leaves it).
    np.testing.assert_allclose(st.grads[0, 4], 0.0, atol=1e-15)
    np.testing.assert_allclose(st.grads[0, 1], [-0.5 / grid.dx * 0.75, 0.0], atol=1e-15)
    np.testing.assert_allclose(st.grads[0, 7], [0.5 / grid.dx * 0.75, 0.0], atol=1e-15)
    assert st.n_nodes == 9


@pytest.mark.parametrize("dim", [2, 3])
def test_particle_at_a_cell_centre_drops_zero_weight_nodes(dim):
    grid = Grid.make(0.25, dim)
    x = np.full((1, dim), 0.25 * 2.5)  # centre of cell 2 on every axis
    kept = particle_stencils(grid, x, drop_zero_weights=False)
    assert kept.n_nodes == 3**dim
    w1 = np.array([0.5, 0.5, 0.0])
    expected = w1
    for _ in range(dim - 1):
        expected = np.multiply.outer(expected, w1)
    np.testing.assert_array_equal(kept.weights[0], expected.ravel())
    dropped = particle_stencils(grid, x)  # default: zero-weight entries -> centre node
    assert dropped.n_nodes == 2**dim
    np.testing.assert_array_equal(dropped.weights, kept.weights)
    corners = np.array(np.meshgrid(*[[2, 3]] * dim, indexing="ij")).reshape(dim, -1).T
    np.testing.assert_array_equal(dropped.active_ijk, corners)
    zero = kept.weights[0] == 0.0
    assert np.all(dropped.nodes[0, zero] == dropped.nodes[0, (3**dim - 1) // 2])


def test_one_particle_per_cell_block_has_no_zero_mass_node():
    grid = Grid.make(0.1, 2)
    x, _ = sample_box((0.0, 0.0), (1.0, 0.5), 0.1, 1)  # all particles on cell centres
    st = particle_stencils(grid, x)
    mass = np.bincount(st.nodes.ravel(), weights=st.weights.ravel(), minlength=st.n_nodes)
    assert np.all(mass > 0.0)
    assert st.n_nodes == 11 * 6  # nodes 0..10 x 0..5
    full = particle_stencils(grid, x, drop_zero_weights=False)
    assert full.n_nodes == 12 * 7


# --------------------------------------------------------------------------- active nodes
@pytest.mark.parametrize("dim", [2, 3])
def test_active_nodes_unique_sorted_and_indices_valid(dim):
    grid, x = random_particles(dim, seed=3)
    st = particle_stencils(grid, x)
    ijk = st.active_ijk
    assert ijk.dtype == np.int64 and st.nodes.dtype == np.int64
    assert np.unique(ijk, axis=0).shape[0] == ijk.shape[0]
    assert np.all(np.lexsort(ijk.T[::-1]) == np.arange(len(ijk)))  # lexicographic, axis 0 first
    assert st.nodes.min() >= 0 and st.nodes.max() < st.n_nodes
    assert np.unique(st.nodes).size == st.n_nodes  # every active node is used
    np.testing.assert_array_equal(st.active_x, grid.node_positions(ijk))
    for arr in (st.nodes, st.weights, st.grads, st.active_ijk, st.active_x):
        assert arr.flags.c_contiguous


@pytest.mark.parametrize("dim", [2, 3])
def test_dense_and_sorting_compaction_agree(dim, monkeypatch):
    grid, x = random_particles(dim, seed=4)
    x[:5] += 1e3  # far-away cluster: a sparse bounding box
    dense = particle_stencils(grid, x[5:])
    sparse_box = particle_stencils(grid, x)
    monkeypatch.setattr(grid_mod, "_DENSE_LIMIT", 0)
    sorted_path = particle_stencils(grid, x[5:])
    np.testing.assert_array_equal(dense.active_ijk, sorted_path.active_ijk)
    np.testing.assert_array_equal(dense.nodes, sorted_path.nodes)
    # The far cluster adds its own nodes; the near ones are the same nodes.
    near = sparse_box.active_ijk[sparse_box.nodes[5:]]
    np.testing.assert_array_equal(near, dense.active_ijk[dense.nodes])


def test_no_particles_gives_empty_stencils():
    st = particle_stencils(Grid.make(0.1, 3), np.zeros((0, 3)))
    assert st.nodes.shape == (0, 27) and st.active_ijk.shape == (0, 3) and st.n_nodes == 0


# --------------------------------------------------------------------------- cell counts
@pytest.mark.parametrize("dim", [2, 3])
def test_cell_counts_and_particles_per_cell(dim):
    ppc = 2**dim
    x, vol = sample_box((0.0,) * dim, (0.4,) * dim, 0.1, ppc)
    grid = Grid.make(0.1, dim)
    cells, counts = grid_cell_counts(grid, x)
    assert cells.shape == (4**dim, dim) and np.all(counts == ppc)
    assert particles_per_cell(grid, x) == pytest.approx(ppc)
    assert particles_per_cell(grid, x, vol) == pytest.approx(ppc)
    fine = Grid.make(0.025, dim)  # finer than the particle spacing 0.05: cells go empty
    assert particles_per_cell(fine, x, vol) == pytest.approx(0.5**dim)
    assert particles_per_cell(fine, x) == pytest.approx(1.0)  # occupied cells only
    with pytest.raises(ValueError, match="volume"):
        particles_per_cell(grid, x, vol[:-1])
