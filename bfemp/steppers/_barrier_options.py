"""The options of the ``"barrier"`` strategy (``Simulation(options=BarrierOptions(...))``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

from bfemp.steppers.base import StepperOptions
from solvers.choice import LINEAR_SOLVER_NAMES, make_linear_solver
from solvers.linear import LinearSolver

__all__ = ["LINEAR_SOLVERS", "VELOCITY_UPDATES", "BarrierOptions"]

#: the names ``BarrierOptions.linear_solver`` accepts
LINEAR_SOLVERS = LINEAR_SOLVER_NAMES

#: the names ``BarrierOptions.velocity_update`` accepts
VELOCITY_UPDATES = ("positions", "forces")


@dataclass(frozen=True, kw_only=True)
class BarrierOptions(StepperOptions):
    """Numerical settings of the ``barrier`` strategy (``Simulation(options=...)``).

    Attributes:
        tol: Newton tolerance in m/s: a step has converged when its increment moves no FEM
            node, particle position or (times dx) particle deformation gradient by more than
            ``tol * dt`` (section 5).
        max_newton_iterations: Newton iteration cap per minimisation.
        warm_start: start Newton from the predicted x^{n+1} where no contact is active instead
            of from x^n (measured: no gain on the rings and cantilever demos, hence off).
        linear_solver: ``"default"`` (CHOLMOD, scipy's SuperLU when scikit-sparse is missing),
            ``"cholmod"``, ``"scipy"``, ``"pardiso"`` (MKL PARDISO, needs the ``pardiso``
            extra), ``"cg_amg"`` (CG + AMG, pyamg), ``"auto"`` (the fastest of these measured
            for the matrix: ``solvers.choice.AutoSolver``), or a ``solvers.linear.LinearSolver``
            object.
        velocity_update: where a^{n+1} (and so v^{n+1}, BFEMP eq. 21) comes from. ``"positions"``
            (default): from the solved x^{n+1}, so that x^{n+1} - x^n = dt v^{n+1} holds
            exactly under backward Euler (``Integrator.acceleration``); ``"forces"``: the
            paper's Algorithm 2 line 14, a^{n+1} = -M^-1 dPsi/dx(x^{n+1}), which adds M^-1 times
            the Newton residual. The residual is large where the Hessian is stiff (at static
            friction), which ``"positions"`` removes. Internal forces cancel in the sum, so
            ``"forces"`` keeps a very stiff body's centre-of-mass motion free of the Newton
            tolerance; the slope benchmark uses it (design note ``measurements``, barrier).
        friction_back_solve: the friction loop's stopping test (Algorithm 1: the Newton
            increment under refreshed friction data below ``tol``) by a back-solve with the last
            factorisation (default) instead of a Newton iteration (assembly and factorisation):
            fewer factorisations, same answer (``benchmarks.speed_knobs``; design note
            ``measurements``, barrier).
    """

    strategy: ClassVar[str] = "barrier"

    tol: float = field(
        default=1e-6, metadata={"unit": "velocity", "sweep": {"finer": -1, "factor": 10.0}}
    )
    max_newton_iterations: int = 200
    warm_start: bool = False
    linear_solver: str | LinearSolver = "default"
    velocity_update: str = "positions"
    friction_back_solve: bool = True

    def _named(self, name: str) -> str:
        """The field alone: ``Simulation``'s flat keywords report these messages as its own."""
        return name

    def __post_init__(self) -> None:
        self.check_numbers("tol", what="a Newton tolerance in m/s")
        self.check_integers("max_newton_iterations", low=1)
        self.check_flags("warm_start", "friction_back_solve")
        self.check_choices(velocity_update=VELOCITY_UPDATES)
        solver = self.linear_solver
        if isinstance(solver, str) and solver not in LINEAR_SOLVERS:
            raise ValueError(f"linear_solver must be one of {LINEAR_SOLVERS}, got {solver!r}")
        if not isinstance(solver, str) and not callable(getattr(solver, "solve", None)):
            raise ValueError(
                f"linear_solver must be a name {LINEAR_SOLVERS} or a LinearSolver, got {solver!r}"
            )

    def make_linear_solver(self, dim: int = 1) -> LinearSolver:
        """The linear solver these options name; ``dim``: unknowns per node (for ``cg_amg``).

        Raises:
            RuntimeError: the named solver's package is not installed (says how to install).
        """
        if not isinstance(self.linear_solver, str):
            return self.linear_solver
        return make_linear_solver(self.linear_solver, block_size=dim)
