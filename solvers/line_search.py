"""Backtracking (Armijo) line search with a feasible initial step.

BFEMP Algorithm 2, lines 7-11: start from the largest step that keeps every contact distance and
every deformation-gradient determinant positive (the objective's ``max_step_size``, so that all
trials stay feasible) and halve it until the energy decreases sufficiently,

    E(x + a p) <= E(x) + c a g.p                                  (Armijo, c in [0, 1)),

where ``g.p < 0`` is the directional derivative. ``c = 0`` is the paper's plain decrease test.
A trial with a non-finite energy (a barrier evaluated beyond its domain) counts as a rejection.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

__all__ = ["LineSearchResult", "SupportsValue", "backtracking_line_search"]

logger = logging.getLogger(__name__)


class SupportsValue(Protocol):
    """The part of the objective a line search needs."""

    def solution_changed(self, x: np.ndarray) -> None:
        """Refresh caches for the new iterate x (n,)."""
        ...

    def value(self, x: np.ndarray) -> float:
        """Energy at x (n,)."""
        ...


@dataclass(frozen=True)
class LineSearchResult:
    """Outcome of :func:`backtracking_line_search`.

    Attributes:
        success: whether a step with sufficient decrease was found.
        alpha: the accepted step (on failure: the last step tried, or alpha0 if none was).
        x: the accepted point ``x + alpha p`` (n,), or None on failure.
        fun: energy at the accepted point (on failure: the last finite trial energy or nan).
        nfev: number of ``value`` calls made.
        n_nonfinite: number of trials whose energy was not finite.
    """

    success: bool
    alpha: float
    x: np.ndarray | None
    fun: float
    nfev: int
    n_nonfinite: int


def backtracking_line_search(
    objective: SupportsValue,
    x: np.ndarray,
    p: np.ndarray,
    fun0: float,
    slope: float,
    alpha0: float,
    *,
    armijo_c: float,
    backtrack_factor: float,
    min_step: float,
) -> LineSearchResult:
    """Find ``alpha <= alpha0`` with ``E(x + alpha p) <= fun0 + armijo_c * alpha * slope``.

    Args:
        objective: provides ``solution_changed`` (called before every trial's ``value``) and
            ``value``.
        x: current iterate (n,).
        p: descent direction (n,), same units as x.
        fun0: energy at x (finite).
        slope: directional derivative ``g.p`` at x (< 0 for a descent direction).
        alpha0: initial (feasible) step size, > 0.
        armijo_c: sufficient-decrease constant in [0, 1).
        backtrack_factor: step reduction per rejection, in (0, 1).
        min_step: give up once the step falls below this.

    Returns:
        A :class:`LineSearchResult`; on failure the objective's last ``solution_changed`` was at
        a rejected trial point, the caller restores it if needed.
    """
    if not (math.isfinite(alpha0) and alpha0 > 0.0):
        raise ValueError(f"alpha0 must be finite and > 0, got {alpha0!r}")
    alpha = float(alpha0)
    nfev = 0
    n_nonfinite = 0
    last_fun = float("nan")
    last_alpha = alpha
    while alpha >= min_step:
        last_alpha = alpha
        trial = x + alpha * p
        objective.solution_changed(trial)
        fun = float(objective.value(trial))
        nfev += 1
        if not math.isfinite(fun):
            n_nonfinite += 1
        else:
            last_fun = fun
            if fun <= fun0 + armijo_c * alpha * slope:
                return LineSearchResult(True, alpha, trial, fun, nfev, n_nonfinite)
        logger.debug("line search: reject alpha=%.3e, E=%.10e (E0=%.10e)", alpha, fun, fun0)
        alpha *= backtrack_factor
    return LineSearchResult(False, last_alpha, None, last_fun, nfev, n_nonfinite)
