"""A projected Newton matrix indefinite only by rounding: an MPM-FEM barrier pair at 1e-9 d-hat.

Issue 44, defect 5: a Newton iterate brought an MPM particle to 2.6e-14 m of a FEM edge (d-hat
1.5e-5 m); the pair's PSD-projected block (curvature ~ kappa / d^2, BFEMP eq. 27) reached 1.2e17
N/m, whose rounding (eps x 1.2e17 ~ 27) exceeds the masses of the grid nodes it touches, and the
factorisation reported LINEAR_SOLVE_FAILED although no term is indefinite. The system here is
built by the library's own barrier kernel, chain rule and assembly; Newton must solve it with the
rounding-level shift (solvers.linear.rounding_shift), and must still fail on a truly indefinite
block.
"""

import numpy as np
import pytest

import bfemp
from bfemp.contact._assembly_kernels import _chain_hessian
from bfemp.contact._barrier_kernels import _barrier_hessians
from bfemp.contact.barrier import barrier_derivative, barrier_second_derivative
from bfemp.errors import StepNoteWarning
from geometry._distance_kernels import KIND_PE
from solvers import linear
from solvers.assembly import TripletAssembler, Triplets
from solvers.linear import CholmodSolver, LinearSolveError, ScipySolver
from solvers.newton import minimize
from solvers.options import NewtonOptions
from solvers.result import NewtonStatus
from tests.bfemp.conftest import block_on_fem_floor

DHAT = 1.5e-5  # m, as in the scene
N_NODES = 12  # 9 grid nodes of the particle's stencil, 2 edge nodes, 1 node apart


def _quadratic_bspline(f: float) -> np.ndarray:
    """Weights (3,) of the quadratic B-spline at the fractional offset f of the base node."""
    return np.array([0.5 * (1.0 - f) ** 2, 0.75 - (f - 0.5) ** 2, 0.5 * f * f])


def _barrier_system(psd: bool = True, sign: float = 1.0) -> tuple[Triplets, np.ndarray]:
    """Triplets ``(24 DOFs)`` of lumped masses plus one particle-edge barrier block at
    d = 2.6e-14 m, and the masses (24,) in kg.

    The particle sits on 9 grid nodes (quadratic B-spline weights 5.6e-5 to 0.67), the edge
    (0.1 m, tilted 1e-3) on 2 FEM nodes; omega c kappa = 8e-11 makes the block 1.2e17 N/m, as
    measured in the issue. Grid masses 0.5 kg, the stencil's lightest node 2.3e-5 kg, FEM
    nodes 10 kg, node 11 (no contact) 0.5 kg. ``psd``: projected per pair (projected Newton) or
    the exact block; ``sign``: -1 negates the block (a sign bug).
    """
    d = 2.6e-14
    e0, e1 = np.array([-0.05, 0.0]), np.array([0.05, 5e-5])
    normal = np.array([-(e1 - e0)[1], (e1 - e0)[0]]) / np.linalg.norm(e1 - e0)
    pos = np.array([e0 + 0.3 * (e1 - e0) + d * normal, e0, e1])
    pts = np.array([[0, 1, 2]])
    dist = np.array([np.dot(pos[0] - e0, normal)])
    scale = 8e-11
    c1 = scale * barrier_derivative(dist, DHAT, 1.0)
    c2 = scale * barrier_second_derivative(dist, DHAT, 1.0)
    hess = sign * _barrier_hessians(pos, pts, KIND_PE, c1, c2, psd)
    weights = np.zeros((3, 9))
    nodes = np.zeros((3, 9), dtype=np.int64)
    weights[0] = np.outer(_quadratic_bspline(0.97), _quadratic_bspline(0.5)).ravel()
    nodes[0] = np.arange(9)
    nodes[1, 0], nodes[2, 0] = 9, 10
    weights[1, 0] = weights[2, 0] = 1.0
    rows, cols, vals = _chain_hessian(hess, pts, nodes, weights, np.arange(N_NODES))
    mass = np.full(N_NODES, 0.5)
    mass[9:11] = 10.0
    mass[np.argmin(weights[0])] = 2.3e-5
    dof_mass = np.repeat(mass, 2)
    n = dof_mass.size
    diag = Triplets(np.arange(n), np.arange(n), dof_mass)
    return Triplets.concatenate([diag, Triplets(rows, cols, vals)]), dof_mass


class _Inertia:
    """E = 1/2 |x - c|^2_M with the barrier system as Newton's proxy (M plus PSD blocks)."""

    def __init__(self, triplets: Triplets, mass: np.ndarray) -> None:
        self.triplets, self.mass = triplets, mass
        self.c = np.linspace(-1e-3, 1e-3, mass.size)

    def solution_changed(self, x):
        pass

    def value(self, x):
        return 0.5 * float(self.mass @ (x - self.c) ** 2)

    def gradient(self, x):
        return self.mass * (x - self.c)

    def hessian(self, x, psd):
        return self.triplets

    def max_step_size(self, x, p):
        return 1.0


def _solvers():
    return [ScipySolver, CholmodSolver] if linear.cholmod_available() else [ScipySolver]


@pytest.mark.parametrize("solver_cls", _solvers())
def test_barrier_block_at_1e_9_dhat_is_solved_with_the_rounding_shift(solver_cls):
    triplets, mass = _barrier_system()
    A = TripletAssembler(mass.size).assemble(triplets)
    # the pair's 1.2e17 N/m block times the largest w_a w_b: entries up to 5.8e16 N/m
    assert 5e16 < abs(A).max() < 2e17 and mass.min() == 2.3e-5
    with pytest.raises(LinearSolveError):  # the premise: the rounded sum does not factorise
        solver_cls().solve(A, np.ones(mass.size))
    obj = _Inertia(triplets, mass)
    x0 = np.zeros(mass.size)
    opts = NewtonOptions(tol=1e-14, max_iter=1)  # one step, then the MAX_ITERATIONS stop
    res = minimize(obj, x0, options=opts, linear_solver=solver_cls())
    # before the shift: LINEAR_SOLVE_FAILED at iteration 0 (issue 44 defect 5)
    assert res.status == NewtonStatus.MAX_ITERATIONS, res.message
    assert res.shifted_solves >= 1
    assert res.fun < obj.value(x0)
    # rounding-level: at most ROUNDING_SHIFT_ULPS eps of the largest row's absolute sum
    row_abs = np.abs(A).sum(axis=1).max()
    assert res.max_shift <= linear.ROUNDING_SHIFT_ULPS * np.finfo(float).eps * row_abs


@pytest.mark.parametrize("psd, sign", [(False, 1.0), (True, -1.0)])
def test_truly_indefinite_barrier_block_still_fails(psd, sign):
    # the exact block (its negative curvature c1 hess d ~ 1e-12 of the block, far above
    # rounding) and a negated projected block (a sign bug) are not hidden by the shift
    triplets, mass = _barrier_system(psd=psd, sign=sign)
    res = minimize(_Inertia(triplets, mass), np.zeros(mass.size), linear_solver=ScipySolver())
    assert res.status == NewtonStatus.LINEAR_SOLVE_FAILED
    assert "again with the rounding shift" in res.message and res.shifted_solves == 0


class _FailsFirst:
    """A linear solver that raises on its first factorisation (a stand-in for the rounded
    indefinite sum, which no quick scene produces) and delegates afterwards."""

    def __init__(self, inner) -> None:
        self.inner, self.calls = inner, 0

    @property
    def last_timings(self):
        return self.inner.last_timings

    def solve(self, A, b, *, pattern_version=None):
        self.calls += 1
        if self.calls == 1:
            raise LinearSolveError("matrix is not positive definite: simulated rounding")
        return self.inner.solve(A, b, pattern_version=pattern_version)

    def solve_again(self, b):
        return self.inner.solve_again(b)


@pytest.mark.parametrize("strategy", ["barrier", "two_stage"])
def test_a_shifted_solve_is_a_named_note_of_the_step(strategy):
    sim = bfemp.Simulation(block_on_fem_floor(mu=0.0), strategy=strategy, dt=5e-4)
    solve = sim.stepper._solver
    solve.linear_solver = _FailsFirst(solve.linear_solver)
    with pytest.warns(StepNoteWarning, match="PSD_ROUNDING_SHIFT"):
        report = sim.step()
    assert report.success and solve.linear_solver.calls >= 2
    notes = [n for n in report.notes if n.startswith("PSD_ROUNDING_SHIFT")]
    assert len(notes) == 1 and "1 projected Newton system" in notes[0]
    assert sim.note_counts["PSD_ROUNDING_SHIFT"] == 1
    report = sim.step()  # the next step solves without the shift: no note
    assert not any(n.startswith("PSD_ROUNDING_SHIFT") for n in report.notes)
