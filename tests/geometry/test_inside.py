"""geometry.inside.simplex_depth: the one point-in-simplex test, and its boundary convention."""

import numpy as np
import pytest

from geometry.inside import simplex_depth
from geometry.mesh import TriMesh
from geometry.sampling import points_in_mesh


def _reference_depth(y: np.ndarray, v: np.ndarray) -> float:
    """Smallest barycentric coordinate by a dense solve (independent of the closed forms)."""
    lam = np.linalg.solve((v[1:] - v[0]).T, y - v[0])
    return float(min(1.0 - lam.sum(), lam.min()))


@pytest.mark.parametrize("dim", [2, 3])
def test_depth_matches_a_dense_solve_on_random_points(dim):
    rng = np.random.default_rng(dim)
    for _ in range(200):
        v = rng.normal(size=(dim + 1, dim))
        y = rng.normal(size=dim)
        assert simplex_depth(y, v) == pytest.approx(_reference_depth(y, v), abs=1e-9)


@pytest.mark.parametrize("dim", [2, 3])
def test_boundary_points_are_inside_inclusively_and_outside_strictly(dim):
    rng = np.random.default_rng(10 + dim)
    v = rng.normal(size=(dim + 1, dim))
    w = rng.dirichlet(np.ones(dim), size=50)
    on_faces = [w @ np.delete(v, k, axis=0) for k in range(dim + 1)]
    for y in [*v, *np.concatenate(on_faces)]:
        depth = simplex_depth(y, v)
        assert depth >= -1e-12  # inclusive: the point belongs to the cell
        assert not depth > 1e-12  # strict: touching is not inside
    centroid = v.mean(axis=0)
    assert simplex_depth(centroid, v) == pytest.approx(1.0 / (dim + 1))
    assert simplex_depth(v[0] + 2.0 * (v[0] - centroid), v) < 0.0


def test_a_degenerate_cell_contains_nothing():
    v = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    assert simplex_depth(np.array([0.5, 0.0]), v) == -1.0


def test_points_in_mesh_counts_the_boundary_as_inside():
    mesh = TriMesh(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]), np.array([[0, 1, 2]]))
    x = np.array([[0.5, 0.5], [0.0, 0.0], [0.25, 0.25], [0.6, 0.6], [-1e-9, 0.5]])
    assert points_in_mesh(mesh, x).tolist() == [True, True, True, False, False]
