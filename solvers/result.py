"""Status codes, result and per-iteration report of the projected Newton solver.

Field names follow ``scipy.optimize.OptimizeResult`` (``x``, ``success``, ``status``,
``message``, ``nit``, ``fun``, ``jac``, ``nfev``, ``njev``, ``nhev``) so that users of scipy
find their way; the solver adds the last increment norm, the accepted step sizes and per-phase
wall-clock timings.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import IntEnum

import numpy as np

__all__ = ["TIMING_KEYS", "NewtonIteration", "NewtonResult", "NewtonStatus", "add_timings"]

#: Phases timed by :func:`solvers.newton.minimize`, in s. ``analyze`` is the symbolic
#: factorisation (just a pattern check while the pattern is reused), ``line_search`` includes every
#: energy evaluation (the one at ``x0`` too), ``pattern`` the sparsity-pattern builds of the
#: assembler (apart from ``assemble``, the sums into the pattern) and ``total`` the whole call.
TIMING_KEYS: tuple[str, ...] = (
    "gradient",
    "hessian",
    "pattern",
    "assemble",
    "analyze",
    "factorize",
    "solve",
    "line_search",
    "step_bound",
    "total",
)


def add_timings(total: dict[str, float], timings: dict[str, float]) -> dict[str, float]:
    """Add the seconds of ``timings`` to ``total`` phase by phase (in place; returns ``total``):
    the phases of a time step solved by several minimisations (friction loop, sub-steps)."""
    for key, seconds in timings.items():
        total[key] = total.get(key, 0.0) + seconds
    return total


class NewtonStatus(IntEnum):
    """Why :func:`solvers.newton.minimize` stopped; only ``CONVERGED`` is a success."""

    CONVERGED = 0
    MAX_ITERATIONS = 1
    LINE_SEARCH_STALLED = 2
    NON_FINITE = 3
    CALLBACK_STOP = 4
    LINEAR_SOLVE_FAILED = 5

    @property
    def description(self) -> str:
        """A one-line human explanation of the status."""
        return _DESCRIPTIONS[self]


_DESCRIPTIONS: dict[NewtonStatus, str] = {
    NewtonStatus.CONVERGED: "converged: the Newton increment is below tolerance",
    NewtonStatus.MAX_ITERATIONS: "stopped: maximal number of Newton iterations reached",
    NewtonStatus.LINE_SEARCH_STALLED: (
        "failed: the line search found no step giving sufficient decrease of the energy"
    ),
    NewtonStatus.NON_FINITE: "failed: non-finite energy, gradient or Hessian",
    NewtonStatus.CALLBACK_STOP: "stopped by the callback",
    NewtonStatus.LINEAR_SOLVE_FAILED: (
        "failed: the linear solve of the Newton system failed (matrix not positive definite?)"
    ),
}


@dataclass
class NewtonResult:
    """Outcome of a projected Newton minimisation.

    Attributes:
        x: the returned iterate (n,), in the units of ``x0``; the last accepted iterate on failure.
        success: True iff ``status`` is ``CONVERGED``.
        status: why the solver stopped.
        message: human-readable reason, with the numbers that matter.
        nit: number of accepted Newton iterations.
        fun: energy at ``x`` (J for an incremental potential); nan if never finite.
        jac: gradient at ``x`` (n,), or None when it was not evaluated there.
        nfev: number of ``value`` calls; njev: ``gradient`` calls; nhev: ``hessian`` calls.
        step_inf_norm: ``||p||_inf`` of the last computed Newton increment (units of ``x``;
            the objective's ``increment_norm`` where it has one), nan if none was computed.
        alphas: accepted line-search step sizes, one per iteration.
        chord_steps: iterations that stepped along a back-solve with the last factorisation
            instead of a new one (``NewtonOptions.chord_steps``).
        linear_iterations: iterations of an iterative linear solver, summed over the solves
            (0 for direct solvers).
        shifted_solves: linear solves of the projected Hessian that failed and succeeded with
            the rounding-level diagonal shift (:func:`solvers.linear.rounding_shift`).
        max_shift: the largest diagonal shift those solves added, in the units of the Hessian
            (0 when none).
        timings: wall-clock seconds per phase, keys :data:`TIMING_KEYS`.
    """

    x: np.ndarray
    success: bool
    status: NewtonStatus
    message: str
    nit: int = 0
    fun: float = float("nan")
    jac: np.ndarray | None = None
    nfev: int = 0
    njev: int = 0
    nhev: int = 0
    step_inf_norm: float = float("nan")
    alphas: list[float] = field(default_factory=list)
    linear_iterations: int = 0
    chord_steps: int = 0
    shifted_solves: int = 0
    max_shift: float = 0.0
    timings: dict[str, float] = field(default_factory=lambda: dict.fromkeys(TIMING_KEYS, 0.0))


@dataclass(frozen=True)
class NewtonIteration:
    """What the callback of :func:`solvers.newton.minimize` receives after each accepted step.

    Attributes:
        x: the new iterate (n,) (a copy; the callback may keep it).
        fun: energy at ``x``.
        nit: number of accepted iterations so far (1 after the first).
        step_inf_norm: ``||p||_inf`` of the increment just taken (before scaling by ``alpha``).
        alpha: the accepted step size.
    """

    x: np.ndarray
    fun: float
    nit: int
    step_inf_norm: float
    alpha: float
