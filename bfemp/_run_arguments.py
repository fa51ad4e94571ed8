"""Checks of the arguments of ``Simulation`` and ``Simulation.run`` that need more than a type
test; each message names the argument as the user passed it (not an internal class)."""

from __future__ import annotations

import math
import numbers

from solvers.options import NewtonOptions

__all__ = ["check_t_end", "newton_options"]


def newton_options(tol: object, max_newton_iterations: object) -> NewtonOptions:
    """The Newton options of ``Simulation(tol=, max_newton_iterations=)``.

    Args:
        tol: Newton tolerance on ``||p||_inf / dt`` in m/s, finite and > 0.
        max_newton_iterations: Newton iteration cap per step, an integer >= 1.
    """
    if isinstance(tol, bool) or not isinstance(tol, numbers.Real) or not math.isfinite(tol):
        raise ValueError(f"Simulation.tol must be a finite number of m/s, got {tol!r}")
    if not tol > 0.0:
        raise ValueError(f"Simulation.tol must be > 0 (a Newton tolerance in m/s), got {tol!r}")
    n = max_newton_iterations
    if isinstance(n, bool) or not isinstance(n, numbers.Integral) or n < 1:
        raise ValueError(f"Simulation.max_newton_iterations must be an integer >= 1, got {n!r}")
    return NewtonOptions(tol=float(tol), max_iter=int(n))


def check_t_end(t_end: float, t: float, dt: float, where: str | None = None) -> None:
    """Refuse a ``t_end`` (s) before the time ``t`` (s) a run starts from.

    A run to ``t_end == t`` (within ``1e-9 dt``) takes no step and is allowed.

    Args:
        t_end: the requested end time in s.
        t: the current time in s (after a resume: the checkpoint's).
        dt: the time step in s (scale of the tolerance).
        where: what ``t`` is, e.g. ``"the checkpoint in out/beam"``; default the current time.
    """
    if t_end < t - 1e-9 * dt:
        of = f"the time t = {t:.9g} s of {where}" if where else f"the current time t = {t:.9g} s"
        raise ValueError(
            f"Simulation.run: t_end = {t_end:.9g} s is earlier than {of}; give a t_end >= {t:.9g} s"
        )
