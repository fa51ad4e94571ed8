"""The contract between ``Simulation`` and a coupling strategy.

Every strategy (``"barrier"``, ``"single_field"``, ``"augury"``, ``"lr"``, ``"two_stage"``) is a
class that implements :class:`Stepper`, registered by name in :mod:`bfemp.steppers`. The way every
energy implements one term contract, every stepper implements this one, so that ``Simulation``,
metrics, frames, checkpoints and the trade study never look inside a stepper:

- construction ``cls(model, integrator=, transfer=, dt=, options=)`` with ``options`` an instance
  of the class's ``Options`` (a frozen keyword-only dataclass, one documented field each, units);
- ``initialize(state) -> State`` once before the first step;
- ``step(state) -> (State, StepReport)``; a failed step raises :class:`StepError`;
- ``stable_dt(state)``: the explicit stable step in s (``inf`` for implicit strategies);
- ``contact() -> ContactView``: forces, closest distance, active pairs and contact energy of the
  last step (NaN where a strategy has none);
- ``terms``: the names of the active energy terms or stages;
- ``checkpoint_data()`` / ``restore_checkpoint_data(data)``: the strategy's own carried state
  (declared by every stepper; an empty dict when there is none).
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np

__all__ = [
    "ContactView",
    "StepError",
    "StepReport",
    "Stepper",
    "StepperOptions",
    "options_from_mapping",
    "options_to_dict",
]


@dataclass(frozen=True, kw_only=True)
class StepperOptions:
    """Base of every strategy's options: a frozen keyword-only dataclass.

    Subclasses declare one field per setting with a docstring line (``Attributes:``) giving its
    meaning and unit, and validate in ``__post_init__`` with messages that name the field.

    A field that trades accuracy against cost declares it in its metadata, ``sweep``: ``finer``
    (+1 when a larger value is more accurate and costlier, -1 when a smaller one is) and either
    ``factor`` (values a factor apart) or ``step`` (integers a step apart), optionally ``min``,
    ``max`` and ``first`` (the first value when the default is None, "off"). The trade study
    (``benchmarks.tradeoff``) sweeps exactly these fields of each strategy.
    """

    #: the strategy these options belong to (set by each subclass)
    strategy: ClassVar[str] = ""

    def _named(self, name: str) -> str:
        """How messages name field ``name``: ``Class.name``."""
        return f"{type(self).__name__}.{name}"

    def check_choices(self, **allowed: tuple) -> None:
        """``ValueError`` naming the field when a field's value is not one of its ``allowed``."""
        for name, choices in allowed.items():
            value = getattr(self, name)
            if value not in choices:
                raise ValueError(f"{self._named(name)} must be one of {choices}, got {value!r}")

    def check_numbers(
        self,
        *names: str,
        low: float = 0.0,
        strict: bool = True,
        high: float | None = None,
        none: bool = False,
        what: str = "a finite number",
    ) -> None:
        """``ValueError`` naming the field unless each of ``names`` is a finite real number above
        ``low`` (``strict``; else at least ``low``) and at most ``high`` (or None when ``none``);
        each is stored as a float. ``what`` says what the value is in the message."""
        for name in names:
            value = getattr(self, name)
            if value is None and none:
                continue
            ok = isinstance(value, int | float) and not isinstance(value, bool)
            if not (
                ok
                and math.isfinite(value)
                and (value > low if strict else value >= low)
                and (high is None or value <= high)
            ):
                bound = (
                    f"be {'>' if strict else '>='} {low:g}"
                    if high is None
                    else (f"lie in {'(' if strict else '['}{low:g}, {high:g}]")
                )
                raise ValueError(
                    f"{self._named(name)} must {bound}{' or None' if none else ''} "
                    f"({what}), got {value!r}"
                )
            object.__setattr__(self, name, float(value))

    def check_integers(self, *names: str, low: int) -> None:
        """``ValueError`` naming the field unless each of ``names`` is an integer >= ``low``."""
        for name in names:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < low:
                raise ValueError(f"{self._named(name)} must be an integer >= {low}, got {value!r}")

    def check_flags(self, *names: str) -> None:
        """``ValueError`` naming the field unless each of ``names`` is True or False."""
        for name in names:
            value = getattr(self, name)
            if not isinstance(value, bool | np.bool_):
                raise ValueError(f"{self._named(name)} must be true or false, got {value!r}")


def options_to_dict(options: StepperOptions) -> dict[str, Any]:
    """The options as plain JSON-able values (recorded in manifests and checkpoints).

    Objects that are not numbers, strings, booleans or None (an injected linear solver) are
    recorded by their class name.
    """
    out: dict[str, Any] = {}
    for f in dataclasses.fields(options):
        value = getattr(options, f.name)
        if value is None or isinstance(value, bool | int | float | str):
            out[f.name] = value
        elif isinstance(value, tuple | list):
            out[f.name] = list(value)
        else:
            out[f.name] = type(value).__name__
    return out


def _matches(value: object, hint: object) -> bool:
    """Whether ``value`` (from a scene file or keyword) fits the field's annotation ``hint``."""
    if hint is Any:
        return True
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        return any(_matches(value, h) for h in typing.get_args(hint))
    if hint is type(None):
        return value is None
    if hint is bool:
        return isinstance(value, bool)
    if hint is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if hint is float:
        return isinstance(value, int | float) and not isinstance(value, bool)
    if typing.get_origin(hint) is typing.Literal:
        return value in typing.get_args(hint)
    if isinstance(hint, type):
        return isinstance(value, hint)
    return True


def options_from_mapping(
    cls: type[StepperOptions], values: Mapping[str, Any], *, where: str = "options"
) -> StepperOptions:
    """Build ``cls`` from a mapping (``[simulation.options]``), refusing what does not fit.

    Raises ``ValueError`` naming the field: an unknown field (with the strategy's fields listed),
    or a value of the wrong type.
    """
    hints = typing.get_type_hints(cls)
    names = [f.name for f in dataclasses.fields(cls) if f.init]
    for key, value in values.items():
        if key not in names:
            raise ValueError(
                f"{where}: unknown option {key!r} for strategy {cls.strategy!r} "
                f"(its options: {', '.join(names)})"
            )
        hint = hints[key]
        if not _matches(value, hint):
            name = hint.__name__ if isinstance(hint, type) else str(hint).replace("typing.", "")
            raise ValueError(
                f"{where}.{key}: expected {name}, got {value!r} ({type(value).__name__})"
            )
    return cls(**dict(values))


@dataclass(frozen=True, kw_only=True)
class StepReport:
    """Outcome of one time step, common to every strategy.

    Attributes:
        step: index of the completed step (1 for the first).
        t: time at the end of the step in s.
        success: whether the step converged.
        status: status name (``"CONVERGED"``, ``"LINE_SEARCH_STALLED"``, ``"EXPLICIT"``, ...).
        message: human-readable outcome.
        iterations: iteration counts of the step by name (``{"newton": 7, "friction": 2}``,
            ``{"augury": 1}``); metrics get one ``iterations_<name>`` column each. Barrier:
            ``"friction"`` is the lagged-friction updates of the step; when the step is solved
            in sub-steps (scripted nodes moving), the most that any one sub-step's friction loop
            took, so it never exceeds the cap (``ContactParameters.friction_iterations``).
        residual: the strategy's convergence measure in m/s (barrier: ``||p||_inf / dt`` of the
            last Newton increment); NaN for explicit strategies.
        timings: seconds per phase (``"assemble"``, ``"factorize"``, ``"p2g"``, ...); barrier:
            summed over every minimisation of the step (the friction loop's, and the sub-steps'
            when scripted nodes move); ``"total"`` is the time inside those minimisations,
            ``"step"`` the whole step.
        min_distance: smallest active contact distance at the end of the step in m (NaN when no
            pair is within d-hat or the strategy has no distance).
        contact_pairs: number of active contact pairs (or contact nodes) at the end of the step.
        friction_converged: whether the friction loop met the tolerance within its cap (False
            when it reached the cap or stalled before it).
        boundary_forces: per level-set boundary, the reaction force (d,) in N its slip nodes
            exert on the body (empty without slip constraints).
        notes: named observations of the step (``"SCRIPTED_FOREGROUND: ..."``), never silent.
        extra: strategy-specific scalars of the step (lr: ``"lr_unconverged"``,
            ``"lump_momentum_drift"`` in kg m/s, ...).
    """

    step: int
    t: float
    success: bool
    status: str
    message: str
    iterations: Mapping[str, int] = field(default_factory=dict)
    residual: float = float("nan")
    timings: dict[str, float] = field(default_factory=dict)
    min_distance: float = float("nan")
    contact_pairs: int = 0
    friction_converged: bool = True
    boundary_forces: tuple = ()
    notes: tuple[str, ...] = ()
    extra: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "iterations", MappingProxyType(dict(self.iterations)))

    @property
    def newton_iterations(self) -> int:
        """Newton iterations of the step (0 for strategies without Newton)."""
        return int(self.iterations.get("newton", 0))

    @property
    def friction_iterations(self) -> int:
        """Lagged-friction updates of the step (0 without friction)."""
        return int(self.iterations.get("friction", 0))


class StepError(RuntimeError):
    """A step failed; ``report`` says why (the state is left at the start of the step)."""

    def __init__(self, report: StepReport) -> None:
        super().__init__(
            f"step {report.step} (t = {report.t:.6g} s) failed: {report.status}: {report.message}"
        )
        self.report = report

    @classmethod
    def failed(cls, step: int, t: float, status: str, message: str, **fields: object) -> StepError:
        """The error of step ``step`` ending at ``t`` s that failed with ``status`` and
        ``message`` (``fields``: the report's other fields, e.g. ``iterations``, ``timings``)."""
        report = StepReport(step=step, t=t, success=False, status=status, message=message)
        return cls(dataclasses.replace(report, **fields) if fields else report)


@dataclass(frozen=True)
class ContactView:
    """What a strategy knows of contact at the end of its last step.

    Attributes:
        fem_forces: contact force on every FEM node ``(N, d)`` in N (N/m in 2D); zero off the
            boundary.
        particle_forces: contact force on every particle ``(P, d)`` in N (N/m in 2D).
        min_distance: closest active distance in m (NaN when the strategy measures none).
        pairs: number of active pairs (or contact nodes).
        energy: contact (barrier) energy in J (J/m in 2D); NaN when the strategy has no
            contact energy.
        parameters: strategy-specific scalars worth recording per step (barrier: ``kappa``).
        body_forces: total contact force ``(B, B, d)`` in N (N/m in 2D), ``[a, b]`` on body a
            from body b (FEM bodies first, then MPM bodies); None when not known.
    """

    fem_forces: np.ndarray
    particle_forces: np.ndarray
    min_distance: float = float("nan")
    pairs: int = 0
    energy: float = float("nan")
    parameters: Mapping[str, float] = field(default_factory=dict)
    body_forces: np.ndarray | None = None

    @classmethod
    def empty(cls, n_fem_nodes: int, n_particles: int, dim: int, **kwargs: Any) -> ContactView:
        """No contact force anywhere (before the first step, or a strategy without contact)."""
        return cls(np.zeros((n_fem_nodes, dim)), np.zeros((n_particles, dim)), **kwargs)


@runtime_checkable
class Stepper(Protocol):
    """What every coupling strategy implements (see the module docstring)."""

    #: registry name of the strategy
    name: ClassVar[str]
    #: the strategy's options class (a ``StepperOptions`` subclass)
    Options: ClassVar[type[StepperOptions]]
    #: implicit strategies solve for positions (``stable_dt`` is inf); explicit ones do not
    explicit: ClassVar[bool]

    def initialize(self, state: Any) -> Any:
        """The state with the strategy's start-up quantities (a^0, augury's B, ...)."""

    def step(self, state: Any) -> tuple[Any, StepReport]:
        """Advance ``state`` by dt; raises ``StepError`` when the step cannot be taken."""

    def stable_dt(self, state: Any) -> float:
        """The largest stable time step in s for ``state`` (inf for implicit strategies)."""

    def contact(self) -> ContactView:
        """Contact forces, distances, pairs and energy at the end of the last step."""

    @property
    def terms(self) -> list[str]:
        """Names of the active energy terms or stages."""

    def checkpoint_data(self) -> dict[str, np.ndarray]:
        """The strategy's carried state as arrays (empty when none)."""

    def restore_checkpoint_data(self, data: Mapping[str, np.ndarray]) -> None:
        """Take back what ``checkpoint_data`` returned."""


def finite_or_nan(value: float) -> float:
    """``value`` as a float, NaN when not finite (an 'inf' distance means none measured)."""
    value = float(value)
    return value if math.isfinite(value) else float("nan")
