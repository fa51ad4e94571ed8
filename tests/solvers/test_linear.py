"""Linear solvers: CHOLMOD vs SuperLU, symbolic reuse, not-PD detection, fallback warning."""

import warnings

import numpy as np
import pytest
import scipy.sparse as sp

from solvers import linear
from solvers.assembly import TripletAssembler, Triplets
from solvers.linear import (
    CholmodSolver,
    LinearSolveError,
    LinearSolver,
    ScipySolver,
    default_linear_solver,
)

needs_cholmod = pytest.mark.skipif(not linear.cholmod_available(), reason="needs scikit-sparse")


def _spd(rng, n, density=0.05, shift=0.5):
    m = sp.random(n, n, density=density, random_state=rng)
    return (m @ m.T + shift * sp.eye(n)).tocsc()


def _solvers():
    out = [ScipySolver()]
    if linear.cholmod_available():
        out.append(CholmodSolver())
    return out


def test_solvers_agree_on_random_spd_system():
    rng = np.random.default_rng(0)
    n = 300
    A = _spd(rng, n)
    b = rng.standard_normal(n)
    solutions = []
    for solver in _solvers():
        assert isinstance(solver, LinearSolver)
        x = solver.solve(A, b)
        np.testing.assert_allclose(A @ x, b, atol=1e-10 * np.abs(b).max())
        assert set(solver.last_timings) == {"analyze", "factorize", "solve"}
        assert all(v >= 0.0 for v in solver.last_timings.values())
        solutions.append(x)
    np.testing.assert_allclose(solutions[0], solutions[-1], rtol=1e-9, atol=1e-12)


def test_solve_again_back_solves_with_the_last_factorisation():
    rng = np.random.default_rng(1)
    n = 200
    A = _spd(rng, n)
    for solver in _solvers():
        assert solver.solve_again(np.ones(n)) is None  # nothing factorised yet
        solver.solve(A, rng.standard_normal(n))
        factorisations = solver.n_numeric
        b = rng.standard_normal(n)
        x = solver.solve_again(b)
        np.testing.assert_allclose(A @ x, b, atol=1e-10 * np.abs(b).max())
        assert solver.n_numeric == factorisations
        assert solver.solve_again(np.ones(n + 1)) is None  # another size: no answer


@needs_cholmod
def test_cholmod_reuses_symbolic_analysis_while_pattern_is_unchanged():
    rng = np.random.default_rng(1)
    n = 200
    A = _spd(rng, n)
    solver = CholmodSolver()
    for k in range(3):
        # Same pattern, new values (scaled diagonal and off-diagonals): numeric only.
        Ak = A.copy()
        Ak.data = Ak.data * (1.0 + 0.1 * k)
        Ak = Ak + (k * sp.eye(n)).tocsc()
        b = rng.standard_normal(n)
        x = solver.solve(Ak.tocsc(), b)
        np.testing.assert_allclose(Ak @ x, b, atol=1e-10)
    assert solver.n_symbolic == 1 and solver.n_numeric == 3
    # A new pattern forces a new analysis, and the result is still right.
    B = (_spd(rng, n, density=0.08) + A).tocsc()
    b = rng.standard_normal(n)
    x = solver.solve(B, b)
    np.testing.assert_allclose(B @ x, b, atol=1e-10)
    assert solver.n_symbolic == 2 and solver.n_numeric == 4


@needs_cholmod
def test_cholmod_pattern_version_from_assembler():
    rng = np.random.default_rng(2)
    n = 50
    A = _spd(rng, n).tocoo()
    t = Triplets(A.row, A.col, A.data)
    asm = TripletAssembler(n)
    solver = CholmodSolver()
    for scale in (1.0, 2.0, 3.0):
        H = asm.assemble(t.scaled(scale))
        b = np.ones(n)
        x = solver.solve(H, b, pattern_version=asm.pattern_version)
        np.testing.assert_allclose(scale * (A @ x), b, atol=1e-10)
    assert solver.n_symbolic == 1
    # Another assembler with another pattern, even of equal size, re-analyses.
    C = (_spd(rng, n, density=0.1) + sp.eye(n)).tocoo()
    other = TripletAssembler(n)
    H = other.assemble(Triplets(C.row, C.col, C.data))
    x = solver.solve(H, np.ones(n), pattern_version=other.pattern_version)
    np.testing.assert_allclose(C @ x, np.ones(n), atol=1e-10)
    assert solver.n_symbolic == 2


@pytest.mark.parametrize("mode", ["auto", "simplicial", "supernodal"])
def test_not_positive_definite_raises(mode):
    rng = np.random.default_rng(3)
    n = 120
    A = (_spd(rng, n) - 3.0 * sp.eye(n)).tocsc()  # indefinite
    assert np.linalg.eigvalsh(A.toarray()).min() < 0
    solvers = [ScipySolver()]
    if linear.cholmod_available():
        solvers.append(CholmodSolver(mode=mode))
    for solver in solvers:
        with pytest.raises(LinearSolveError, match="not positive definite"):
            solver.solve(A, np.ones(n))
    # The CHOLMOD solver recovers on the next SPD matrix with the same pattern.
    if linear.cholmod_available():
        good = (A + 10.0 * sp.eye(n)).tocsc()
        x = solvers[-1].solve(good, np.ones(n))
        np.testing.assert_allclose(good @ x, np.ones(n), atol=1e-10)


def test_bad_shapes_raise_value_error():
    A = sp.eye(3, format="csc")
    for solver in _solvers():
        with pytest.raises(ValueError, match="b must have shape"):
            solver.solve(A, np.ones(4))
        with pytest.raises(ValueError, match="square"):
            solver.solve(sp.csc_matrix(np.ones((2, 3))), np.ones(2))


@needs_cholmod
def test_default_solver_is_cholmod_when_available():
    assert isinstance(default_linear_solver(), CholmodSolver)


def test_default_solver_falls_back_with_exactly_one_warning(monkeypatch, caplog):
    monkeypatch.setattr(linear, "_import_cholmod", lambda: None)
    monkeypatch.setattr(linear, "_fallback_warned", False)
    assert not linear.cholmod_available()
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        first = default_linear_solver()
        second = default_linear_solver()
    assert isinstance(first, ScipySolver) and isinstance(second, ScipySolver)
    runtime = [w for w in record if issubclass(w.category, RuntimeWarning)]
    assert len(runtime) == 1
    assert "scikit-sparse" in str(runtime[0].message)
    assert "pip install" in str(runtime[0].message)
    # the warning alone: a log record beside it printed the hint twice
    assert not any("scikit-sparse" in r.getMessage() for r in caplog.records)
    with pytest.raises(RuntimeError, match="scikit-sparse"):
        CholmodSolver()


def test_rounding_shift_is_ulps_eps_times_the_row_absolute_sum():
    A = sp.csc_matrix(np.array([[4.0, -1.0, 0.0], [-1.0, 3.0, 2.0], [0.0, 2.0, 5.0]]))
    eps = np.finfo(float).eps
    np.testing.assert_allclose(linear.rounding_shift(A), 16.0 * eps * np.array([5.0, 6.0, 7.0]))
    np.testing.assert_allclose(linear.rounding_shift(A, ulps=2.0), 2.0 * eps * np.array([5, 6, 7]))
    with pytest.raises(ValueError, match="ulps"):
        linear.rounding_shift(A, ulps=-1.0)
    with pytest.raises(ValueError, match="square"):
        linear.rounding_shift(sp.csc_matrix(np.ones((2, 3))))


def test_shift_diagonal_keeps_the_pattern_where_the_diagonal_is_stored():
    A = sp.csc_matrix(np.array([[4.0, 1.0], [1.0, 3.0]]))
    shifted, same = linear.shift_diagonal(A, np.array([0.5, 0.25]))
    assert same
    np.testing.assert_array_equal(shifted.indices, A.indices)
    np.testing.assert_array_equal(shifted.toarray(), [[4.5, 1.0], [1.0, 3.25]])
    np.testing.assert_array_equal(A.toarray(), [[4.0, 1.0], [1.0, 3.0]])  # A untouched
    # a diagonal entry not stored: a new pattern
    B = sp.csc_matrix(np.array([[0.0, 1.0], [1.0, 3.0]]))
    shifted, same = linear.shift_diagonal(B, np.array([2.0, 1.0]))
    assert not same
    np.testing.assert_array_equal(shifted.toarray(), [[2.0, 1.0], [1.0, 4.0]])
    with pytest.raises(ValueError, match="shift"):
        linear.shift_diagonal(A, np.ones(3))
