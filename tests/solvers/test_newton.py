"""Projected Newton: convergence rates, feasibility, fixed DOFs, every failure status."""

import logging

import numpy as np
import pytest
import scipy.sparse as sp

from solvers import linear
from solvers.assembly import TripletAssembler, Triplets
from solvers.linear import CholmodSolver, LinearSolveError, ScipySolver
from solvers.newton import minimize
from solvers.options import NewtonOptions
from solvers.psd import project_psd
from solvers.result import TIMING_KEYS, NewtonStatus


class Quadratic:
    """E = 1/2 x^T A x - b^T x with a sparse SPD A."""

    def __init__(self, A, b, fixed_dofs=None):
        self.A = sp.csr_matrix(A)
        coo = sp.coo_matrix(A)
        self.rows, self.cols, self.vals = coo.row, coo.col, coo.data
        self.b = b
        self.fixed_dofs = fixed_dofs
        self.visited = []

    def solution_changed(self, x):
        self.visited.append(x.copy())

    def value(self, x):
        return 0.5 * x @ (self.A @ x) - self.b @ x

    def gradient(self, x):
        return self.A @ x - self.b

    def hessian(self, x, psd):
        return Triplets(self.rows, self.cols, self.vals)

    def max_step_size(self, x, p):
        return 1.0


class LogCoshChain:
    """Smooth strictly convex, non-quadratic, tridiagonal Hessian:
    E = sum_i logcosh(x_i - c_i) + sum_i softplus(x_{i+1} - x_i) + mu/2 |x|^2."""

    def __init__(self, c, mu=0.1):
        self.c, self.mu = c, mu
        n = c.size
        self.edges = np.stack([np.arange(n - 1), np.arange(1, n)], axis=1)
        self.last_x = None
        self.calls = {"solution_changed": 0, "value": 0, "gradient": 0, "hessian": 0}
        self.psd_flags = []

    def _check(self, x, name):
        # The contract: solution_changed(x) precedes every evaluation at x.
        assert self.last_x is not None and np.array_equal(x, self.last_x), name
        self.calls[name] += 1

    def solution_changed(self, x):
        self.last_x = x.copy()
        self.calls["solution_changed"] += 1

    def value(self, x):
        self._check(x, "value")
        y = x - self.c
        logcosh = np.abs(y) + np.log1p(np.exp(-2.0 * np.abs(y))) - np.log(2.0)
        d = x[1:] - x[:-1]
        return logcosh.sum() + np.logaddexp(0.0, d).sum() + 0.5 * self.mu * x @ x

    def gradient(self, x):
        self._check(x, "gradient")
        g = np.tanh(x - self.c) + self.mu * x
        s = 0.5 * (1.0 + np.tanh(0.5 * (x[1:] - x[:-1])))  # sigmoid
        g[1:] += s
        g[:-1] -= s
        return g

    def hessian(self, x, psd):
        self._check(x, "hessian")
        self.psd_flags.append(psd)
        n = x.size
        diag = 1.0 / np.cosh(x - self.c) ** 2 + self.mu
        s = 0.5 * (1.0 + np.tanh(0.5 * (x[1:] - x[:-1])))
        w = s * (1.0 - s)
        blocks = w[:, None, None] * np.array([[1.0, -1.0], [-1.0, 1.0]])
        idx = np.arange(n)
        return Triplets.concatenate(
            [Triplets(idx, idx, diag), Triplets.from_blocks(self.edges, blocks)]
        )

    def max_step_size(self, x, p):
        return 1.0


class Barrier:
    """E = -sum log(1 - x_i) + k/2 |x - t|^2, +inf for any x_i >= 1; max step stays feasible."""

    def __init__(self, t, k=1.0):
        self.t, self.k = t, k
        self.bounds = []  # (x, p, alpha bound) per max_step_size call
        self.trial_alphas = []
        self.trial_limits = []
        self.evaluated = []

    def solution_changed(self, x):
        pass

    def value(self, x):
        self.evaluated.append(x.copy())
        if self.bounds:
            # Every value call after x0 is a line-search trial x_prev + alpha p of the last step.
            x_prev, p, bound = self.bounds[-1]
            j = np.argmax(np.abs(p))  # least cancellation in (x - x_prev) / p
            self.trial_alphas.append((x[j] - x_prev[j]) / p[j])
            self.trial_limits.append(min(1.0, bound))
        if np.any(x >= 1.0):
            return np.inf
        return -np.log(1.0 - x).sum() + 0.5 * self.k * ((x - self.t) ** 2).sum()

    def gradient(self, x):
        return 1.0 / (1.0 - x) + self.k * (x - self.t)

    def hessian(self, x, psd):
        idx = np.arange(x.size)
        return Triplets(idx, idx, 1.0 / (1.0 - x) ** 2 + self.k)

    def max_step_size(self, x, p):
        ahead = p > 0.0
        bound = np.inf
        if ahead.any():
            bound = 0.9 * ((1.0 - x[ahead]) / p[ahead]).min()
        self.bounds.append((x.copy(), p.copy(), bound))
        return bound


def _random_spd(rng, n):
    m = sp.random(n, n, density=0.1, random_state=rng)
    return (m @ m.T + sp.eye(n)).tocsc()


def test_quadratic_converges_in_one_iteration():
    rng = np.random.default_rng(0)
    n = 40
    A = _random_spd(rng, n)
    b = rng.standard_normal(n)
    obj = Quadratic(A, b)
    res = minimize(obj, np.zeros(n), options=NewtonOptions(tol=1e-9))
    assert res.success and res.status == NewtonStatus.CONVERGED
    assert res.nit == 1 and res.alphas == [1.0]
    np.testing.assert_allclose(res.x, np.linalg.solve(A.toarray(), b), rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(res.jac, 0.0, atol=1e-9)
    assert res.fun == pytest.approx(obj.value(res.x))
    # one Hessian: the convergence test after the full step is the chord back-solve
    assert res.nfev == 2 and res.njev == 2 and res.nhev == 1
    assert "chord test" in res.message
    off = minimize(obj, np.zeros(n), options=NewtonOptions(tol=1e-9, chord_stop_factor=0.0))
    assert off.success and off.nhev == 2  # without it: a second Hessian for the test
    assert set(res.timings) == set(TIMING_KEYS)
    assert all(v >= 0.0 for v in res.timings.values())
    parts = sum(v for k, v in res.timings.items() if k != "total")
    assert res.timings["total"] >= parts - 1e-9


def test_converged_at_x0_takes_no_step():
    rng = np.random.default_rng(1)
    A = _random_spd(rng, 10)
    x_star = rng.standard_normal(10)
    res = minimize(Quadratic(A, A @ x_star), x_star, options=NewtonOptions(tol=1e-8))
    assert res.success and res.nit == 0 and res.alphas == []
    np.testing.assert_array_equal(res.x, x_star)


def test_quadratic_convergence_rate_and_contract():
    rng = np.random.default_rng(2)
    n = 50
    obj = LogCoshChain(rng.standard_normal(n))
    x0 = 4.0 * rng.standard_normal(n)
    steps, energies = [], []

    def record(it):
        steps.append(it.step_inf_norm)
        energies.append(it.fun)

    res = minimize(
        obj, x0, options=NewtonOptions(tol=1e-11), linear_solver=ScipySolver(), callback=record
    )
    assert res.success, res.message
    assert res.nit >= 4  # genuinely non-quadratic from this start
    np.testing.assert_allclose(res.jac, 0.0, atol=1e-10)
    steps.append(res.step_inf_norm)
    # Error recursion e_{k+1} <= C e_k^2 once in the quadratic regime (above round-off).
    pairs = [(a, b) for a, b in zip(steps[:-1], steps[1:], strict=True) if a < 0.3 and b > 1e-14]
    assert len(pairs) >= 2, steps
    for a, b in pairs:
        assert b <= 2.0 * a**2, steps
    assert res.alphas[-2:] == [1.0, 1.0]
    # Energy decreases monotonically and the counters match the calls.
    assert np.all(np.diff(energies) < 0.0)
    assert res.nfev == obj.calls["value"]
    assert res.njev == obj.calls["gradient"] and res.nhev == obj.calls["hessian"]
    # projected Hessian first; the exact one only after full steps (exact_near_solution)
    assert obj.psd_flags[0] and not all(obj.psd_flags)
    obj.solution_changed(x0)
    assert res.fun < obj.value(x0)


def test_without_exact_near_solution_every_hessian_is_projected():
    rng = np.random.default_rng(2)
    obj = LogCoshChain(rng.standard_normal(50))
    res = minimize(
        obj,
        4.0 * rng.standard_normal(50),
        options=NewtonOptions(tol=1e-11, exact_near_solution=False),
        linear_solver=ScipySolver(),
    )
    assert res.success, res.message
    assert obj.psd_flags and all(obj.psd_flags)


class _IndefiniteNearSolution:
    """E = sum_i (x_i^2/2 - a cos x_i): the exact Hessian 1 + a cos x is indefinite for a > 1
    at x = pi, where the projected Hessian max(., 0) + ... stays PD; minimiser x = 0."""

    def __init__(self, n, a):
        self.n, self.a = n, a
        self.fixed_dofs = None
        self.flags = []

    def solution_changed(self, x):
        pass

    def value(self, x):
        return float(np.sum(0.5 * x**2 - self.a * np.cos(x)))

    def gradient(self, x):
        return x + self.a * np.sin(x)

    def hessian(self, x, psd):
        self.flags.append(psd)
        d = 1.0 + self.a * np.cos(x)
        if psd:
            d = np.maximum(d, 1e-3)
        idx = np.arange(self.n)
        return Triplets(idx, idx, d)

    def max_step_size(self, x, p):
        return 1.0


def test_indefinite_exact_hessian_falls_back_to_projection():
    obj = _IndefiniteNearSolution(4, a=3.0)
    res = minimize(
        obj, np.full(4, 2.5), options=NewtonOptions(tol=1e-10), linear_solver=ScipySolver()
    )
    assert res.success, res.message
    np.testing.assert_allclose(res.x, 0.0, atol=1e-9)


@pytest.mark.skipif(not linear.cholmod_available(), reason="needs scikit-sparse")
def test_cholmod_symbolic_analysis_is_reused_across_iterations():
    rng = np.random.default_rng(3)
    obj = LogCoshChain(rng.standard_normal(30))
    solver = CholmodSolver()
    res = minimize(obj, 3.0 * rng.standard_normal(30), linear_solver=solver)
    assert res.success and res.nit >= 3
    assert solver.n_symbolic == 1 and solver.n_numeric == res.nhev
    # A second solve of the same problem with the same solver reuses it too.
    minimize(obj, np.zeros(30), linear_solver=solver)
    assert solver.n_symbolic == 1


def test_max_step_size_bound_is_respected():
    t = np.array([3.0, 10.0, 1.5, -2.0, 50.0])
    obj = Barrier(t)
    res = minimize(obj, np.zeros(t.size), options=NewtonOptions(tol=1e-10))
    assert res.success, res.message
    # Smaller root of (1 - x)(t - x) k = 1: the barrier minimiser, inside x < 1.
    k = obj.k
    expected = ((1 + t) - np.sqrt((1 + t) ** 2 - 4 * (t - 1 / k))) / 2
    np.testing.assert_allclose(res.x, expected, rtol=1e-9)
    assert all(np.all(x < 1.0) for x in obj.evaluated)
    # The unconstrained first Newton step would leave the domain; the bound cut it.
    assert obj.bounds[0][2] < 1.0
    assert len(obj.trial_alphas) == res.nfev - 1
    alphas, limits = np.array(obj.trial_alphas), np.array(obj.trial_limits)
    assert np.all(alphas <= limits * (1.0 + 1e-6))
    # The first trial of every line search starts exactly at min(1, bound).
    assert alphas[0] == pytest.approx(limits[0], rel=1e-9)


def test_fixed_dofs_stay_fixed():
    rng = np.random.default_rng(4)
    n = 30
    A = _random_spd(rng, n)
    b = rng.standard_normal(n)
    fixed = np.zeros(n, bool)
    fixed[[0, 7, 8, 29]] = True
    obj = Quadratic(A, b, fixed_dofs=fixed)
    x0 = rng.standard_normal(n)
    res = minimize(obj, x0, options=NewtonOptions(tol=1e-10))
    assert res.success and res.nit == 1
    np.testing.assert_array_equal(res.x[fixed], x0[fixed])
    assert all(np.array_equal(x[fixed], x0[fixed]) for x in obj.visited)
    free = ~fixed
    Ad = A.toarray()
    x_free = np.linalg.solve(Ad[np.ix_(free, free)], b[free] - Ad[np.ix_(free, fixed)] @ x0[fixed])
    np.testing.assert_allclose(res.x[free], x_free, rtol=1e-10, atol=1e-12)
    # The gradient at fixed DOFs (reaction forces) is not zero and did not block convergence.
    assert np.abs(res.jac[fixed]).max() > 1e-3
    np.testing.assert_allclose(res.jac[free], 0.0, atol=1e-9)


def test_all_dofs_fixed_converges_immediately():
    obj = Quadratic(sp.eye(3), np.ones(3), fixed_dofs=np.ones(3, bool))
    res = minimize(obj, np.zeros(3))
    assert res.success and res.nit == 0


def test_max_iterations():
    rng = np.random.default_rng(5)
    obj = LogCoshChain(rng.standard_normal(20))
    res = minimize(obj, 5.0 * rng.standard_normal(20), options=NewtonOptions(max_iter=1))
    assert not res.success and res.status == NewtonStatus.MAX_ITERATIONS
    assert res.nit == 1 and "max_iter" in res.message
    assert np.isfinite(res.fun) and res.jac is not None


class _NaNValue(Quadratic):
    def value(self, x):
        return np.nan


class _NaNGradient(Quadratic):
    def gradient(self, x):
        g = super().gradient(x)
        g[2] = np.nan
        return g


@pytest.mark.parametrize("cls", [_NaNValue, _NaNGradient])
def test_non_finite(cls):
    obj = cls(sp.eye(4, format="csc"), np.ones(4))
    res = minimize(obj, np.zeros(4))
    assert not res.success and res.status == NewtonStatus.NON_FINITE
    assert "non-finite" in res.message or "nan" in res.message
    np.testing.assert_array_equal(res.x, np.zeros(4))


class _WrongGradient(Quadratic):
    """Gradient of the opposite sign: every 'descent' direction increases the energy."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.last_changed = None

    def solution_changed(self, x):
        self.last_changed = x.copy()

    def gradient(self, x):
        return -super().gradient(x)


def test_line_search_stalled():
    obj = _WrongGradient(sp.eye(3, format="csc"), np.ones(3))
    x0 = np.array([0.5, -0.2, 0.1])
    res = minimize(obj, x0, options=NewtonOptions(min_step=1e-6))
    assert not res.success and res.status == NewtonStatus.LINE_SEARCH_STALLED
    assert "alpha" in res.message and "||p||_inf" in res.message
    np.testing.assert_array_equal(res.x, x0)
    # The objective's caches were restored to the returned iterate.
    np.testing.assert_array_equal(obj.last_changed, x0)


def test_zero_max_step_size_stalls():
    class Blocked(Quadratic):
        def max_step_size(self, x, p):
            return 0.0

    res = minimize(Blocked(sp.eye(2, format="csc"), np.ones(2)), np.zeros(2))
    assert res.status == NewtonStatus.LINE_SEARCH_STALLED and "max_step_size" in res.message


@pytest.mark.parametrize("mode", ["return", "raise"])
def test_callback_stop(mode):
    rng = np.random.default_rng(6)
    obj = LogCoshChain(rng.standard_normal(10))
    seen = []

    def callback(it):
        seen.append((it.nit, it.fun, it.alpha))
        if it.nit == 2:
            if mode == "raise":
                raise StopIteration
            return True
        return None

    res = minimize(obj, 5.0 * rng.standard_normal(10), callback=callback)
    assert not res.success and res.status == NewtonStatus.CALLBACK_STOP
    assert res.nit == 2 and [s[0] for s in seen] == [1, 2]
    assert seen[-1][1] == res.fun and seen[0][1] > seen[1][1]


class _Concave(Quadratic):
    """Negative definite Hessian: no PD system to solve when projection is off."""

    def hessian(self, x, psd):
        self.psd_seen = psd
        return Triplets(self.rows, self.cols, -self.vals)


@pytest.mark.parametrize("solver_cls", [ScipySolver, CholmodSolver])
def test_linear_solve_failed(solver_cls):
    if solver_cls is CholmodSolver and not linear.cholmod_available():
        pytest.skip("needs scikit-sparse")
    obj = _Concave(sp.eye(5, format="csc"), np.ones(5))
    res = minimize(
        obj, np.zeros(5), options=NewtonOptions(project_psd=False), linear_solver=solver_cls()
    )
    assert obj.psd_seen is False
    assert not res.success and res.status == NewtonStatus.LINEAR_SOLVE_FAILED
    assert "positive definite" in res.message


class _AscentSolver:
    """Returns -A^{-1} b: the Newton 'step' points uphill, forcing the -g fallback."""

    def solve(self, A, b, *, pattern_version=None):
        return -np.linalg.solve(A.toarray(), b)


def test_non_descent_direction_falls_back_to_gradient(caplog):
    A = sp.diags([1.0, 2.0, 1.5]).tocsc()
    b = np.array([1.0, -1.0, 2.0])
    caplog.set_level(logging.DEBUG, logger="solvers.newton")
    res = minimize(
        Quadratic(A, b), np.zeros(3), options=NewtonOptions(tol=1e-8), linear_solver=_AscentSolver()
    )
    assert res.success, res.message
    np.testing.assert_allclose(res.x, b / A.diagonal(), atol=1e-7)
    assert res.nit > 1  # steepest descent, not one Newton step
    assert any("using -g" in r.getMessage() for r in caplog.records)
    assert res.timings["solve"] > 0.0


def test_custom_solver_error_is_reported():
    class Failing:
        def solve(self, A, b, *, pattern_version=None):
            raise LinearSolveError("boom")

    res = minimize(Quadratic(sp.eye(2), np.ones(2)), np.zeros(2), linear_solver=Failing())
    assert res.status == NewtonStatus.LINEAR_SOLVE_FAILED and "boom" in res.message


def test_bad_input_raises_value_error():
    obj = Quadratic(sp.eye(3), np.ones(3))
    with pytest.raises(ValueError, match="x0"):
        minimize(obj, np.array([0.0, np.nan, 0.0]))
    with pytest.raises(ValueError, match="x0"):
        minimize(obj, np.zeros((3, 1)))
    obj.fixed_dofs = np.array([0, 1])
    with pytest.raises(ValueError, match="fixed_dofs"):
        minimize(obj, np.zeros(3))
    with pytest.raises(ValueError, match="options"):
        minimize(Quadratic(sp.eye(3), np.ones(3)), np.zeros(3), options={"tol": 1.0})


class _InexactSpy:
    """A CG solver stand-in that records the relative residual Newton hands each solve and
    stops there: it returns x with ``A x = b - r``, ``||r|| = rtol ||b||``."""

    accepts_rtol = True
    rtol = 1e-12  # the floor

    def __init__(self, seed=0):
        self.rtols = []
        self.last_iterations = 0
        self.rng = np.random.default_rng(seed)

    def solve(self, A, b, *, pattern_version=None, rtol=None):
        tol = self.rtol if rtol is None else max(rtol, self.rtol)
        self.rtols.append(rtol)
        self.last_iterations = 1
        r = self.rng.standard_normal(b.size)
        r *= tol * np.linalg.norm(b) / np.linalg.norm(r)
        return sp.linalg.spsolve(sp.csc_matrix(A), b - r)


def test_forcing_term_follows_the_gradient_and_is_capped():
    from solvers.newton import forcing_term

    assert forcing_term(1.0, None, None, 1e-2) == 1e-2  # first iteration: the cap
    # quadratic in the gradient ratio (Eisenstat-Walker choice 2, gamma 0.9)
    assert forcing_term(1e-3, 1.0, 1e-2, 1e-2) == pytest.approx(0.9e-6)
    assert forcing_term(0.5, 1.0, 1e-2, 1e-2) == 1e-2  # capped
    # safeguard: a large previous eta keeps the next one from collapsing
    assert forcing_term(1e-3, 1.0, 0.5, 0.9) == pytest.approx(0.9 * 0.25)


def test_inexact_solves_follow_newton_and_the_deciding_increment_is_exact():
    rng = np.random.default_rng(2)
    n = 50
    x0 = 4.0 * rng.standard_normal(n)
    c = rng.standard_normal(n)
    spy = _InexactSpy()
    res = minimize(LogCoshChain(c), x0, options=NewtonOptions(tol=1e-11), linear_solver=spy)
    assert res.success, res.message
    np.testing.assert_allclose(res.jac, 0.0, atol=1e-10)
    handed = [r for r in spy.rtols if r is not None]
    assert handed[0] == NewtonOptions().linear_rtol_max
    assert min(handed) < 1e-4 * handed[0]  # tightened as the gradient fell
    assert spy.rtols[-1] is None  # the increment that stopped Newton: the solver's floor
    assert res.linear_iterations == len(spy.rtols)
    # the same minimiser as exact solves
    exact = minimize(
        LogCoshChain(c), x0, options=NewtonOptions(tol=1e-11), linear_solver=ScipySolver()
    )
    np.testing.assert_allclose(res.x, exact.x, atol=1e-9)


def test_a_direct_solver_gets_no_rtol():
    rng = np.random.default_rng(3)
    calls = []

    class Direct(ScipySolver):
        def solve(self, A, b, *, pattern_version=None, **kwargs):
            calls.append(kwargs)
            return super().solve(A, b, pattern_version=pattern_version)

    res = minimize(LogCoshChain(rng.standard_normal(20)), np.zeros(20), linear_solver=Direct())
    assert res.success and calls and all(k == {} for k in calls)


@pytest.mark.skipif(not linear.cholmod_available(), reason="needs scikit-sparse")
def test_chord_test_stops_only_below_the_tolerance_and_agrees_with_the_exact_one():
    rng = np.random.default_rng(2)
    n = 50
    c, x0 = rng.standard_normal(n), 4.0 * rng.standard_normal(n)
    for tol in (1e-6, 1e-9, 1e-11):
        on = minimize(
            LogCoshChain(c), x0, options=NewtonOptions(tol=tol), linear_solver=CholmodSolver()
        )
        off = minimize(
            LogCoshChain(c),
            x0,
            options=NewtonOptions(tol=tol, chord_stop_factor=0.0),
            linear_solver=CholmodSolver(),
        )
        assert on.success and off.success
        assert on.nhev < off.nhev  # a factorisation saved
        # the exact increment at the returned point is below the tolerance too
        obj = LogCoshChain(c)
        obj.solution_changed(on.x)
        H = obj.hessian(on.x, psd=False)
        Hm = sp.csc_matrix((H.vals, (H.rows, H.cols)), shape=(n, n))
        p = sp.linalg.spsolve(Hm, -obj.gradient(on.x))
        assert np.abs(p).max() < tol
        np.testing.assert_allclose(on.x, off.x, atol=10 * tol)
    with pytest.raises(ValueError, match="chord_stop_factor"):
        NewtonOptions(chord_stop_factor=1.5)


def test_near_solution_factor_is_validated_by_name():
    assert NewtonOptions().near_solution_factor == 1e3
    assert NewtonOptions(near_solution_factor=0.0).near_solution_factor == 0.0
    for bad in (-1.0, float("inf"), True, "1"):
        with pytest.raises(ValueError, match="near_solution_factor"):
            NewtonOptions(near_solution_factor=bad)


class TwoCycle:
    """A convex-enough 1D quintic with Newton steps A = 0 -> B = 1 -> A: E(A) = 0 < E(B) = 0.1,
    E'(A) = -2, E''(A) = 2 (Newton lands on B), E'(B) = 1, E''(B) = 1 (Newton lands on A),
    and |E'(B)| < |E'(A)|: the near-solution rule takes A -> B on the gradient norm although
    E rises, then Armijo takes B -> A."""

    def __init__(self):
        rows = []
        for x in (0.0, 1.0):
            rows.append([x**k for k in range(6)])
            rows.append([k * x ** (k - 1) if k else 0.0 for k in range(6)])
            rows.append([k * (k - 1) * x ** (k - 2) if k > 1 else 0.0 for k in range(6)])
        self.c = np.linalg.solve(np.array(rows), np.array([0.0, -2.0, 2.0, 0.1, 1.0, 1.0]))

    def _poly(self, x, order):
        c = np.polynomial.polynomial.polyder(self.c, order) if order else self.c
        return float(np.polynomial.polynomial.polyval(x[0], c))

    def solution_changed(self, x):
        pass

    def value(self, x):
        return self._poly(x, 0)

    def gradient(self, x):
        return np.array([self._poly(x, 1)])

    def hessian(self, x, psd):
        return Triplets(np.array([0]), np.array([0]), np.array([abs(self._poly(x, 2))]))

    def max_step_size(self, x, p):
        return 1.0


def test_near_solution_steps_cannot_take_turns_with_armijo_steps():
    # frictional buckling at dt = 2e-2 s cycled like this for 500 iterations (issue 18)
    objective = TwoCycle()
    assert objective.value(np.array([1.0])) > objective.value(np.array([0.0]))
    res = minimize(
        objective,
        np.array([0.0]),
        options=NewtonOptions(tol=1e-2, max_iter=50, exact_near_solution=False),
        linear_solver=ScipySolver(),
    )
    assert res.success, res.message
    assert res.nit < 20
    assert 0.3 < res.x[0] < 0.5  # the minimiser, x = 0.38 (E = -0.41 < E(A))


@pytest.mark.skipif(not linear.cholmod_available(), reason="needs scikit-sparse")
def test_chord_steps_save_factorisations_and_reach_the_same_tolerance():
    """Where the failed chord test predicts convergence after one more chord iteration, a step
    along it replaces a factorisation; the returned point passes the exact test all the same.
    The control (chord_steps=False) factorises at every iteration."""
    rng = np.random.default_rng(3)
    n = 50
    c, x0 = rng.standard_normal(n), 4.0 * rng.standard_normal(n)
    saved = 0
    for tol in (1e-6, 1e-9, 1e-11):
        runs = {}
        for steps in (True, False):
            solver = CholmodSolver()
            res = minimize(
                LogCoshChain(c),
                x0,
                options=NewtonOptions(tol=tol, chord_steps=steps),
                linear_solver=solver,
            )
            assert res.success
            runs[steps] = (res, solver.n_numeric)
        (on, n_on), (off, n_off) = runs[True], runs[False]
        assert off.chord_steps == 0 and n_off == off.nhev
        assert n_on == on.nhev <= n_off
        saved += n_off - n_on  # each chord step that ended the solve: one factorisation less
        obj = LogCoshChain(c)
        obj.solution_changed(on.x)
        H = obj.hessian(on.x, psd=False)
        Hm = sp.csc_matrix((H.vals, (H.rows, H.cols)), shape=(n, n))
        p = sp.linalg.spsolve(Hm, -obj.gradient(on.x))
        assert np.abs(p).max() < tol  # the exact increment at the returned point
        np.testing.assert_allclose(on.x, off.x, atol=10 * tol)
    assert saved >= 1
    with pytest.raises(ValueError, match="chord_steps"):
        NewtonOptions(chord_steps=1)


def _rounded_psd_sum(theta: float = 0.5) -> Triplets:
    """Masses of 1e-5 kg on 2 DOFs plus one block of curvature 1e17 N/m along
    ``(cos theta, sin theta)`` projected to PSD by :func:`solvers.psd.project_psd`: positive
    definite in exact arithmetic, indefinite as computed (the projected block's rounding, eps x
    1e17 ~ 22, swamps the masses; issue 44 defect 5 in two unknowns)."""
    v = np.array([np.cos(theta), np.sin(theta)])
    w = np.array([-v[1], v[0]])
    block = project_psd((1e17 * np.outer(v, v) - 1e3 * np.outer(w, w))[None])[0]
    rows, cols = np.repeat(np.arange(2), 2), np.tile(np.arange(2), 2)
    mass = Triplets(np.arange(2), np.arange(2), np.full(2, 1e-5))
    return Triplets.concatenate([mass, Triplets(rows, cols, block.ravel())])


class _MassWithProxy:
    """E = 1/2 |x - c|^2_M (M = 1e-5 kg I) whose Newton proxy is ``hessian_triplets`` (a
    projected Newton proxy: M plus PSD blocks, never below M)."""

    def __init__(self, hessian_triplets: Triplets) -> None:
        self.triplets = hessian_triplets
        self.c = np.array([1e-3, -2e-3])

    def solution_changed(self, x):
        pass

    def value(self, x):
        return 0.5e-5 * float((x - self.c) @ (x - self.c))

    def gradient(self, x):
        return 1e-5 * (x - self.c)

    def hessian(self, x, psd):
        return self.triplets

    def max_step_size(self, x, p):
        return 1.0


@pytest.mark.parametrize("solver_cls", [ScipySolver, CholmodSolver])
def test_projected_matrix_indefinite_by_rounding_is_solved_with_the_shift(solver_cls):
    if solver_cls is CholmodSolver and not linear.cholmod_available():
        pytest.skip("needs scikit-sparse")
    triplets = _rounded_psd_sum()
    A = TripletAssembler(2).assemble(triplets)
    # the premise: the rounded sum does not factorise (both solvers, at theta = 0.5)
    with pytest.raises(LinearSolveError, match="positive definite|factori"):
        solver_cls().solve(A, np.ones(2))
    obj = _MassWithProxy(triplets)
    e0 = obj.value(np.zeros(2))
    opts = NewtonOptions(tol=1e-14, max_iter=1)  # one step, then the MAX_ITERATIONS stop
    res = minimize(obj, np.zeros(2), options=opts, linear_solver=solver_cls())
    # before the rounding shift: LINEAR_SOLVE_FAILED at iteration 0
    assert res.status == NewtonStatus.MAX_ITERATIONS, res.message
    assert res.shifted_solves >= 1
    assert res.fun < e0  # the shifted proxy still gives a descent step
    # the shift is rounding-level: ROUNDING_SHIFT_ULPS eps of the row (|a_ij| <= 1e17)
    assert 0.0 < res.max_shift <= linear.ROUNDING_SHIFT_ULPS * np.finfo(float).eps * 2e17


def test_indefinite_projected_matrix_still_fails_after_the_shift():
    # a matrix indefinite beyond rounding (a bug producing a negative block) is not hidden
    A = sp.csc_matrix(np.array([[2.0, 0.0], [0.0, -1e-6]]))
    res = minimize(Quadratic(A, np.ones(2)), np.zeros(2), linear_solver=ScipySolver())
    assert res.status == NewtonStatus.LINEAR_SOLVE_FAILED
    assert "again with the rounding shift" in res.message
    assert res.shifted_solves == 0


def test_exact_hessian_is_not_shifted():
    # without projection the Hessian may be indefinite for real: no retry
    res = minimize(
        _MassWithProxy(_rounded_psd_sum()),
        np.zeros(2),
        options=NewtonOptions(project_psd=False),
        linear_solver=ScipySolver(),
    )
    assert res.status == NewtonStatus.LINEAR_SOLVE_FAILED
    assert "rounding shift" not in res.message and res.shifted_solves == 0
