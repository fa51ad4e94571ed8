"""Checks of the arguments of ``Simulation`` and ``Simulation.run`` that need more than a type
test; each message names the argument as the user passed it (not an internal class)."""

from __future__ import annotations

import logging
import math
import numbers

from bfemp.model import Model
from bfemp.state import State
from bfemp.steppers import BarrierOptions, StepperOptions, options_for, stepper_class

__all__ = [
    "check_run_args",
    "check_t_end",
    "merge_flat_options",
    "n_steps",
    "resolve_dt",
]

log = logging.getLogger("bfemp.simulation")


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


def check_run_args(
    t_end: object, every: object, checkpoint_every: object, resume: bool, out: object
) -> None:
    """Validate the arguments of ``Simulation.run`` (errors name the argument)."""
    for name, value, least in (("every", every, 1), ("checkpoint_every", checkpoint_every, 0)):
        if value is not None and (
            isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < least
        ):
            raise ValueError(f"Simulation.run: {name} must be an integer >= {least}, got {value!r}")
    if not (isinstance(t_end, numbers.Real) and math.isfinite(t_end)):
        raise ValueError(f"Simulation.run: t_end must be a finite time in s, got {t_end!r}")
    if resume and out is None:
        raise ValueError("Simulation.run: resume=True needs out, the folder of the run")


def merge_flat_options(
    strategy: str, options: StepperOptions | None, flat: dict[str, object]
) -> StepperOptions:
    """The strategy's options, from ``options`` or from the flat barrier keywords."""
    given = {k: v for k, v in flat.items() if v is not None}
    if given and strategy != "barrier":
        raise ValueError(
            f"Simulation: {', '.join(sorted(given))} belong to strategy 'barrier'; strategy "
            f"{strategy!r} takes its settings as options={stepper_class(strategy).Options.__name__}"
            "(...)"
        )
    if given and options is not None:
        raise ValueError(
            f"Simulation: give either options=BarrierOptions(...) or the flat keywords "
            f"{', '.join(sorted(given))}, not both"
        )
    if given:
        try:
            return BarrierOptions(**given)
        except ValueError as err:
            raise ValueError(f"Simulation.{err}") from None
    return options_for(strategy, options)


def resolve_dt(
    dt: object, stepper_cls: type, model: Model, state: State, options: StepperOptions
) -> float:
    """dt in s: a positive number, or ``"auto"``: an explicit strategy's stable step."""
    if isinstance(dt, str):
        auto = getattr(stepper_cls, "auto_dt", None)
        if dt != "auto":
            raise ValueError(f"Simulation.dt must be a time in s or 'auto', got {dt!r}")
        if auto is None:
            raise ValueError(
                f"Simulation.dt='auto' needs an explicit strategy with a stable step; strategy "
                f"{stepper_cls.name!r} is implicit: give dt in s"
            )
        return float(auto(model, state, options))
    if isinstance(dt, bool) or not (isinstance(dt, int | float) and math.isfinite(dt) and dt > 0):
        raise ValueError(f"Simulation.dt must be a positive number of seconds, got {dt!r}")
    return float(dt)


def n_steps(t: float, t_end: float, dt: float) -> int:
    """Whole steps of ``dt`` (s) from ``t`` to reach ``t_end`` (the end time past it is logged)."""
    n = max(0, math.ceil((t_end - t) / dt - 1e-9))
    end = t + n * dt
    if end > t_end + 1e-9 * dt:
        log.info(
            "the run ends at t = %.9g s, %.3g s after t_end = %.9g s: %d whole steps of "
            "dt = %.9g s (the last step is not shortened; Simulation.run says why)",
            end,
            end - t_end,
            t_end,
            n,
            dt,
        )
    return n
