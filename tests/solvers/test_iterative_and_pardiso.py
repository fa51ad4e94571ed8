"""The extra linear solvers: PARDISO (optional) and CG + AMG behind the LinearSolver interface,
the ``auto`` choice, and the same Newton solution as CHOLMOD on 2D and 3D steps."""

import numpy as np
import pytest
import scipy.sparse as sp

from solvers import choice, iterative, linear, pardiso
from solvers.linear import LinearSolveError, LinearSolver


def _laplacian_3d(k):
    """7-point Laplacian of a k^3 grid plus a mass term: SPD, like a stiffness + inertia."""
    one = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(k, k))
    eye = sp.eye(k)
    lap = (
        sp.kron(sp.kron(one, eye), eye)
        + sp.kron(sp.kron(eye, one), eye)
        + sp.kron(sp.kron(eye, eye), one)
    )
    return (lap + 1e-2 * sp.eye(k**3)).tocsc()


def test_cg_amg_solves_an_spd_system_and_reuses_its_hierarchy():
    A = _laplacian_3d(14)
    rng = np.random.default_rng(0)
    solver = iterative.CgAmgSolver(rtol=1e-10)
    assert isinstance(solver, LinearSolver)
    for k in range(3):
        b = rng.standard_normal(A.shape[0])
        Ak = (A * (1.0 + 0.05 * k)).tocsc()
        x = solver.solve(Ak, b, pattern_version=7)
        assert np.linalg.norm(Ak @ x - b) <= 1e-9 * np.linalg.norm(b)
    assert solver.n_symbolic == 1 and solver.n_numeric == 3
    assert solver.last_iterations > 0
    x = solver.solve_again(b)
    assert np.linalg.norm(Ak @ x - b) <= 1e-9 * np.linalg.norm(b)


def test_cg_amg_rejects_an_indefinite_matrix():
    A = (_laplacian_3d(6) - 3.0 * sp.eye(216)).tocsc()
    with pytest.raises(LinearSolveError, match="positive definite"):
        iterative.CgAmgSolver(maxiter=200).solve(A, np.ones(216))


def test_cg_amg_validates_its_options():
    with pytest.raises(ValueError, match="rtol"):
        iterative.CgAmgSolver(rtol=0.0)
    with pytest.raises(ValueError, match="block_size"):
        iterative.CgAmgSolver(block_size=4)


def test_pardiso_solves_or_says_how_to_install(monkeypatch):
    A = _laplacian_3d(10)
    b = np.arange(A.shape[0], dtype=float)
    if pardiso.pardiso_available():
        solver = pardiso.PardisoSolver()
        for k in range(2):
            Ak = (A * (1.0 + k)).tocsc()
            x = solver.solve(Ak, b)
            np.testing.assert_allclose(Ak @ x, b, atol=1e-9 * np.abs(b).max())
        assert solver.n_symbolic == 1 and solver.n_numeric == 2
        np.testing.assert_allclose(Ak @ solver.solve_again(b), b, atol=1e-9 * np.abs(b).max())
        with pytest.raises(LinearSolveError, match="positive definite"):
            solver.solve((A - 3.0 * sp.eye(A.shape[0])).tocsc(), b)
    # Without pypardiso: a clear error naming the extra, and "auto" falls back to CHOLMOD.
    monkeypatch.setattr(pardiso, "_import_pypardiso", lambda: None)
    with pytest.raises(RuntimeError, match=r"bfemp\[pardiso\]"):
        choice.make_linear_solver("pardiso")
    auto = choice.AutoSolver()
    x = auto.solve(A, b)
    np.testing.assert_allclose(A @ x, b, atol=1e-9 * np.abs(b).max())
    assert auto.chosen == ("cholmod" if linear.cholmod_available() else "default")


def test_auto_sends_dense_3d_grids_to_cg_above_the_size_threshold():
    # 27-point-like coupling: more than DENSE_ROW_NNZ nonzeros per row
    n = 400
    rng = np.random.default_rng(1)
    m = sp.random(n, n, density=0.5, random_state=rng)
    A = (m @ m.T + n * sp.eye(n)).tocsc()
    assert A.nnz > choice.DENSE_ROW_NNZ * n
    assert choice.AutoSolver(cg_min_dofs=100).choose(A) == "cg_amg"
    assert choice.AutoSolver(cg_min_dofs=10_000).choose(A) != "cg_amg"
    with pytest.raises(ValueError, match="linear solver must be one of"):
        choice.make_linear_solver("superlu")


def _one_step(scene, dt, solver):
    import bfemp
    from bfemp.integrators import BACKWARD_EULER
    from bfemp.steppers.barrier import BarrierOptions, BarrierStepper

    model = scene.build()
    stepper = BarrierStepper(
        model,
        integrator=BACKWARD_EULER,
        dt=dt,
        options=BarrierOptions(tol=1e-6, linear_solver=solver),
    )
    state, report = stepper.step(stepper.initialize(model.initial_state()))
    assert isinstance(state, bfemp.State) or state is not None
    return state, report


@pytest.mark.parametrize("case", ["mpm2d", "fem3d", "mpm3d"])
def test_cg_amg_reaches_the_cholmod_newton_solution(case):
    from benchmarks import catalogue

    if case == "mpm2d":
        scene, dt = catalogue.mpm_block_scene(2, (12, 12), 4), 0.01
    elif case == "mpm3d":
        scene, dt = catalogue.mpm_block_scene(3, (5, 5, 3), 8), 0.01
    else:
        scene, dt = catalogue.fem_block_scene(3, (6, 3, 3)), 0.05
    direct, rep_d = _one_step(scene, dt, "default")
    cg, rep_cg = _one_step(scene, dt, "cg_amg")
    assert rep_d.newton_iterations > 1  # a real nonlinear solve, not one step
    x_d = np.concatenate([direct.fem_x.ravel(), direct.mpm_x.ravel()])
    x_cg = np.concatenate([cg.fem_x.ravel(), cg.mpm_x.ravel()])
    moved = np.abs(
        x_d
        - np.concatenate(
            [
                scene.build().initial_state().fem_x.ravel(),
                scene.build().initial_state().mpm_x.ravel(),
            ]
        )
    ).max()
    assert moved > 100 * 1e-6 * dt  # the step moves far more than the tolerance
    # both are Newton solutions to tol = 1e-6 m/s: they agree to a few tol * dt
    assert np.abs(x_cg - x_d).max() <= 10 * 1e-6 * dt
