"""Coupling strategies: a ``Stepper`` advances ``(Model, State)`` by one step and reports.

Strategies are looked up by name in one registry (``STRATEGIES``) so that the same scene can be
run with each; every class implements the ``Stepper`` protocol of :mod:`bfemp.steppers.base`
and names its options class (``cls.Options``).

Layering inside the strategies (made precise here and enforced by
``tests/test_layering.py``): the explicit grid strategies (``single_field``, ``augury``, ``lr``
and the explicit engine) never import ``solvers.newton``; ``two_stage``, whose second stage is a
minimisation, may call the physics-free ``solvers.newton.minimize`` on the same contact terms
(``bfemp.contact``) as ``barrier``. No strategy imports another strategy's module except the
explicit engine (``bfemp.steppers.explicit``) it builds on.
"""

from __future__ import annotations

from bfemp.steppers.augury import AuguryOptions, AuguryStepper
from bfemp.steppers.barrier import BarrierOptions, BarrierStepper
from bfemp.steppers.base import (
    ContactView,
    StepError,
    Stepper,
    StepperOptions,
    StepReport,
    options_from_mapping,
    options_to_dict,
)
from bfemp.steppers.capabilities import Capabilities
from bfemp.steppers.capabilities import strategy_table as _strategy_table
from bfemp.steppers.lr import LROptions, LRStepper
from bfemp.steppers.single_field import SingleFieldOptions, SingleFieldStepper
from bfemp.steppers.two_stage import TwoStageOptions, TwoStageStepper

__all__ = [
    "STRATEGIES",
    "AuguryOptions",
    "AuguryStepper",
    "BarrierOptions",
    "SingleFieldOptions",
    "SingleFieldStepper",
    "BarrierStepper",
    "Capabilities",
    "ContactView",
    "ImplicitStepper",
    "LROptions",
    "LRStepper",
    "StepError",
    "StepReport",
    "Stepper",
    "StepperOptions",
    "options_for",
    "options_from_mapping",
    "options_to_dict",
    "stepper_class",
    "strategy_table",
    "TwoStageOptions",
    "TwoStageStepper",
]

#: the old name of the barrier stepper
ImplicitStepper = BarrierStepper

#: strategy name -> stepper class. "barrier" is BFEMP (implicit incremental potential);
#: "single_field" the explicit MPM baseline without a contact algorithm.
STRATEGIES: dict[str, type] = {"barrier": BarrierStepper, "single_field": SingleFieldStepper}
STRATEGIES["augury"] = AuguryStepper  # APIC augury contact (AUG), explicit
STRATEGIES["two_stage"] = TwoStageStepper  # explicit free motion, implicit contact (TS)
STRATEGIES["lr"] = LRStepper  # multimaterial MPM, logistic-regression contact (LR), explicit


def stepper_class(strategy: str) -> type:
    """The stepper class registered under ``strategy``."""
    try:
        return STRATEGIES[strategy]
    except KeyError:
        raise ValueError(
            f"strategy must be one of {sorted(STRATEGIES)}, got {strategy!r}"
        ) from None


def options_for(strategy: str, options: StepperOptions | None) -> StepperOptions:
    """``options`` checked against ``strategy`` (its defaults when None).

    Raises ``ValueError`` when the options belong to another strategy.
    """
    cls = stepper_class(strategy).Options
    if options is None:
        return cls()
    if not isinstance(options, cls):
        raise ValueError(
            f"options: strategy {strategy!r} takes {cls.__name__}, got "
            f"{type(options).__name__} (the options of strategy {options.strategy!r})"
        )
    return options


def strategy_table() -> str:
    """The registered strategies as a text table: which body pairs each couples (and how),
    friction, and the penetration each guarantees (``bfemp strategies`` prints it; see
    :mod:`bfemp.steppers.capabilities`)."""
    return _strategy_table(STRATEGIES)
