"""Every term of the FEM core passes the finite-difference harness, 2D and 3D."""

import numpy as np
import pytest

import bfemp
from bfemp.testing import check_term, dense_hessian
from tests.bfemp.conftest import block_scene, started_stepper

MATERIALS = {
    "neo_hookean": bfemp.NeoHookean(E=1e5, nu=0.35, density=500.0),
    "linear": bfemp.LinearElastic(E=1e5, nu=0.35, density=500.0),
}


def _deformed(model, stepper, rng, strong):
    """Free-DOF positions of a random (and optionally strongly deformed) configuration, J > 0."""
    d = model.dim
    X = model.fem_X
    if strong:
        angle = 0.9
        R = np.eye(d)
        R[:2, :2] = [[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]]
        A = np.eye(d)
        A[0, 0], A[0, 1], A[1, 1] = 1.8, 0.7, 0.6
        X = X @ (R @ A).T
    for _ in range(50):
        y = X + (0.08 if strong else 0.03) * rng.standard_normal(X.shape)
        F = np.einsum("mai,maj->mij", y[model.fem_cells], model.fem_cell_grad)
        if np.linalg.det(F).min() > 0.05:
            return stepper.layout.restrict(y)
    raise AssertionError("could not draw a non-inverted configuration")


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("material", sorted(MATERIALS))
@pytest.mark.parametrize("strong", [False, True])
def test_elasticity_term_passes_fd_harness(dim, material, strong, rng):
    scene = block_scene(dim, MATERIALS[material], h=1.0 if dim == 3 else 0.5)
    model, begun, _ = started_stepper(scene)
    term = next(t for t in begun.potential.potentials if t.name.startswith("elasticity"))
    x = _deformed(model, begun, rng, strong)
    report = check_term(term, x, eps=1e-6, tol=1e-5)
    assert report.ok, report


@pytest.mark.parametrize("dim", [2, 3])
def test_inertia_gravity_load_and_total_pass_fd_harness(dim, rng):
    scene = block_scene(dim, MATERIALS["neo_hookean"], h=1.0)
    scene.add_load(0, np.ones(dim))
    model, begun, x0 = started_stepper(scene)
    names = [t.name for t in begun.potential.terms]
    assert names == ["inertia", "elasticity[neo_hookean]", "gravity", "external_force"]
    x = _deformed(model, begun, rng, strong=False)
    for term in [*begun.potential.terms, begun.potential]:
        report = check_term(term, x, eps=1e-6, tol=1e-5)
        assert report.ok, (getattr(term, "name", "potential"), report)


@pytest.mark.parametrize("dim", [2, 3])
def test_projected_hessian_is_psd_where_the_true_one_is_not(dim, rng):
    """Under strong compression the unprojected Neo-Hookean Hessian is indefinite."""
    scene = block_scene(
        dim, MATERIALS["neo_hookean"], prescribed_bottom=False, gravity=False, h=1.0
    )
    model, begun, _ = started_stepper(scene)
    term = begun.potential.potentials[0]
    x = begun.layout.restrict(model.fem_X * np.r_[0.35, np.ones(dim - 1)])
    raw = dense_hessian(term, x, psd=False)
    projected = dense_hessian(term, x, psd=True)
    assert np.linalg.eigvalsh(raw).min() < -1e-6 * np.abs(raw).max()
    assert np.allclose(projected, projected.T, atol=1e-12 * np.abs(projected).max())
    assert np.linalg.eigvalsh(projected).min() > -1e-9 * np.abs(projected).max()


def test_elasticity_step_bound_keeps_cells_uninverted(rng):
    scene = block_scene(2, MATERIALS["neo_hookean"], prescribed_bottom=False, gravity=False)
    model, begun, x = started_stepper(scene)
    term = begun.potential.potentials[0]
    term.solution_changed(x)
    p = -3.0 * x  # collapses every cell through the origin at alpha = 1
    alpha = term.max_step_size(x, p)
    assert 0.0 < alpha < 1.0
    y = begun.layout.positions(x + alpha * p, begun.context.fixed_positions)
    F = np.einsum("mai,maj->mij", y[model.fem_cells], model.fem_cell_grad)
    assert np.linalg.det(F).min() > 0.0
