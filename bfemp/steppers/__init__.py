"""Coupling strategies: a ``Stepper`` advances ``(Model, State)`` by one step and reports.

Strategies are looked up by name in one registry so that the same scene can be run with each.
"""

from __future__ import annotations

from bfemp.steppers.base import StepError, StepReport
from bfemp.steppers.implicit import ImplicitStepper
from bfemp.steppers.single_field import SingleFieldStepper

__all__ = ["STRATEGIES", "StepError", "StepReport", "ImplicitStepper", "stepper_class"]

#: strategy name -> stepper class. "barrier" is BFEMP (implicit incremental potential).
STRATEGIES = {"barrier": ImplicitStepper, "single_field": SingleFieldStepper}


def stepper_class(strategy: str) -> type:
    """The stepper class registered under ``strategy``."""
    try:
        return STRATEGIES[strategy]
    except KeyError:
        raise ValueError(
            f"strategy must be one of {sorted(STRATEGIES)}, got {strategy!r}"
        ) from None
