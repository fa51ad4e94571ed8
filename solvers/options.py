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


def _check_positive_finite(name: str, value: float) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"NewtonOptions.{name} must be a real number, got {value!r}")
    if not math.isfinite(value) or value <= 0.0:
        raise ValueError(f"NewtonOptions.{name} must be finite and > 0, got {value!r}")


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
            (``newton._accept_near_solution``), >= 0; 0 leaves only the round-off test. Where
            the energy is not smooth at that scale this can cycle: the ``two_stage`` slope at
            static friction (sliding eps_v dt = 5e-10 m, increments of 4.5e-9 m) alternated
            between a step accepted on the gradient norm (the energy rising by 3.7e-22 J/m)
            and an Armijo step back, until MAX_ITERATIONS.
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
        _check_positive_finite("tol", self.tol)
        _check_positive_finite("step_scale", self.step_scale)
        if isinstance(self.max_iter, bool) or not isinstance(self.max_iter, int):
            raise ValueError(f"NewtonOptions.max_iter must be an int, got {self.max_iter!r}")
        if self.max_iter < 1:
            raise ValueError(f"NewtonOptions.max_iter must be >= 1, got {self.max_iter}")
        if isinstance(self.armijo_c, bool) or not isinstance(self.armijo_c, (int, float)):
            raise ValueError(f"NewtonOptions.armijo_c must be a real number, got {self.armijo_c!r}")
        if not 0.0 <= self.armijo_c < 1.0:
            raise ValueError(f"NewtonOptions.armijo_c must be in [0, 1), got {self.armijo_c!r}")
        _check_positive_finite("backtrack_factor", self.backtrack_factor)
        if self.backtrack_factor >= 1.0:
            raise ValueError(
                f"NewtonOptions.backtrack_factor must be in (0, 1), got {self.backtrack_factor!r}"
            )
        _check_positive_finite("linear_rtol_max", self.linear_rtol_max)
        if self.linear_rtol_max >= 1.0:
            raise ValueError(
                f"NewtonOptions.linear_rtol_max must be in (0, 1), got {self.linear_rtol_max!r}"
            )
        c = self.chord_stop_factor
        if isinstance(c, bool) or not isinstance(c, (int, float)) or not 0.0 <= c <= 1.0:
            raise ValueError(f"NewtonOptions.chord_stop_factor must be in [0, 1], got {c!r}")
        _check_positive_finite("min_step", self.min_step)
        if self.min_step > 1.0:
            raise ValueError(f"NewtonOptions.min_step must be in (0, 1], got {self.min_step!r}")
        f = self.near_solution_factor
        if (
            isinstance(f, bool)
            or not isinstance(f, (int, float))
            or not (math.isfinite(f) and f >= 0)
        ):
            raise ValueError(
                f"NewtonOptions.near_solution_factor must be finite and >= 0, got {f!r}"
            )
        for name in ("project_psd", "exact_near_solution", "chord_steps"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(
                    f"NewtonOptions.{name} must be a bool, got {getattr(self, name)!r}"
                )
