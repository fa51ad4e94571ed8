"""Options of the projected Newton solver (:func:`solvers.newton.minimize`).

The stopping rule is the one of the BFEMP paper (Sec. 5, Algorithm 2, line 13): the Newton
increment ``p`` (in metres, an update of node positions) divided by the time step ``dt`` is a
velocity, and the solve stops when ``||p||_inf / dt < eps_d`` with ``eps_d`` in m/s.  Here
``step_scale`` plays the role of ``dt`` and ``tol`` the role of ``eps_d``; with the defaults
(``step_scale = 1``) the test is on ``||p||_inf`` itself, in the units of ``x``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["NewtonOptions"]


#: the real-valued options: (lower, upper, lower bound included, upper bound included)
_RANGES = {
    "tol": (0.0, math.inf, False, False),
    "step_scale": (0.0, math.inf, False, False),
    "armijo_c": (0.0, 1.0, True, False),
    "backtrack_factor": (0.0, 1.0, False, False),
    "linear_rtol_max": (0.0, 1.0, False, False),
    "chord_stop_factor": (0.0, 1.0, True, True),
    "min_step": (0.0, 1.0, False, True),
    "near_solution_factor": (0.0, math.inf, True, False),
}


@dataclass(frozen=True, kw_only=True)
class NewtonOptions:
    """Projected Newton options; all fields are validated on construction.

    Attributes:
        tol: stop when ``||p||_inf / step_scale < tol`` (> 0). With ``step_scale = dt`` in s
            this is the paper's ``eps_d`` in m/s.
        step_scale: divisor of the increment in the stopping rule (> 0), the time step ``dt``
            in s for the paper's criterion; 1 makes ``tol`` an increment in the units of ``x``.
        max_iter: maximal number of accepted Newton iterations (>= 1).
        armijo_c: sufficient-decrease constant ``c`` in ``E(x + a p) <= E(x) + c a g.p``,
            in [0, 1). 0 gives the paper's plain ``E(x + a p) <= E(x)``.
        backtrack_factor: step-size reduction per rejected trial, in (0, 1) (paper: 1/2).
        min_step: the line search gives up (status ``LINE_SEARCH_STALLED``) once the step
            size falls below this value, in (0, 1].
        project_psd: ask the objective for PSD-projected Hessians (projected Newton). With
            ``False`` the exact Hessian is used and must be positive definite for CHOLMOD.
        exact_near_solution: with ``project_psd``, after a full step (alpha = 1) try the exact
            Hessian next: per-stencil projection alters the Hessian even where the global one
            is positive definite and turns Newton's quadratic convergence into a linear one.
            If the exact Hessian is not positive definite (or gives no descent) the projected
            one is used for the rest of the solve.
        linear_rtol_max: the loosest relative residual an inexact linear solver (one with
            ``accepts_rtol``, such as CG + AMG) may stop at, in (0, 1). Its tolerance per
            iteration is the Eisenstat-Walker forcing term (:func:`solvers.newton.forcing_term`)
            capped here and floored at the solver's own ``rtol``; the increment that passes the
            stopping test is re-solved at that floor. Direct solvers ignore it.
        chord_stop_factor: after a full step (alpha = 1), first test convergence with the last
            factorisation (a back-solve ``p = -H_old^{-1} g``, no new factorisation, with solvers
            that have ``solve_again``): stop when ``||p||_inf / step_scale < chord_stop_factor *
            tol``, in [0, 1]; 0 turns the test off. The stale Hessian misjudges p by a relative
            O(||H_new - H_old|| ||H^{-1}||); the factor below 1 leaves room for it, and where the
            chord says no, the exact test runs as before.
        chord_steps: where the chord test fails but predicts that one more chord iteration
            would pass it (``4 ||p_chord||^2 / ||p_last|| < chord_stop_factor tol step_scale``,
            ``p_last`` the step just taken;
            ``solvers._newton_direction._chord_step_predicted_to_converge``), step along the
            chord increment (line search and step bound as for a Newton step) instead of
            factorising again; at most one chord step per factorisation. False: always
            factorise.
        near_solution_factor: within this factor of the tolerance (``||p||_inf <= factor tol
            step_scale``) a step the energy cannot judge is taken when the gradient norm falls
            (``newton._Run.near_solution_step``), >= 0; 0 leaves only the round-off test. Where
            the energy is not smooth at that scale this can cycle (design note
            ``measurements``, newton).
    """

    tol: float = 1e-6
    step_scale: float = 1.0
    max_iter: int = 200
    armijo_c: float = 1e-4
    backtrack_factor: float = 0.5
    min_step: float = 1e-12
    project_psd: bool = True
    exact_near_solution: bool = True
    linear_rtol_max: float = 1e-2
    chord_stop_factor: float = 0.5
    chord_steps: bool = True
    near_solution_factor: float = 1e3

    def __post_init__(self) -> None:
        for name, (low, high, low_in, high_in) in _RANGES.items():
            value = getattr(self, name)
            ok = not isinstance(value, bool) and isinstance(value, int | float)
            ok = ok and math.isfinite(value) and (low <= value if low_in else low < value)
            if not (ok and (value <= high if high_in else value < high)):
                interval = f"{'[' if low_in else '('}{low:g}, {high:g}{']' if high_in else ')'}"
                raise ValueError(
                    f"NewtonOptions.{name} must be a finite number in {interval}, got {value!r}"
                )
        if isinstance(self.max_iter, bool) or not isinstance(self.max_iter, int):
            raise ValueError(f"NewtonOptions.max_iter must be an int, got {self.max_iter!r}")
        if self.max_iter < 1:
            raise ValueError(f"NewtonOptions.max_iter must be >= 1, got {self.max_iter}")
        for name in ("project_psd", "exact_near_solution", "chord_steps"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(
                    f"NewtonOptions.{name} must be a bool, got {getattr(self, name)!r}"
                )
