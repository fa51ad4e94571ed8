"""The knobs of each strategy in the trade study (``benchmarks.tradeoff``), read from its options.

A strategy's own knobs are the fields of its options dataclass (``bfemp.steppers``) that declare
``sweep`` metadata (``StepperOptions``' docstring): ``finer`` (+1 / -1), ``factor`` or ``step``,
optionally ``min``, ``max`` and ``first``. The common knob ``dt`` (s) follows the same rule with
``DT_SWEEP``; an explicit strategy run at ``dt="auto"`` sweeps its CFL fractions
(``cfl_safety_*``) instead of dt, one run at a fixed dt sweeps dt and not the fractions (they
then change nothing).

A knob whose base is None ("off", e.g. LR's ``xpic_order``) goes from None to ``first``
(quick) and one step beyond (full); one without ``first`` is not swept from None (augury's
``tau = None``, which is dt: the scene sets a number to sweep it).
"""

from __future__ import annotations

import dataclasses
import math

from bfemp.steppers import stepper_class

#: the time step as a knob: finer when smaller, a factor 2 apart
DT_SWEEP = {"finer": -1, "factor": 2.0}
#: option fields that set the explicit step only through ``dt="auto"``
CFL_FIELDS = ("cfl_safety_fem", "cfl_safety_mpm")


def option_knobs(strategy: str) -> dict[str, dict]:
    """``{field: sweep spec}`` of the strategy's options fields that declare ``sweep``."""
    fields = dataclasses.fields(stepper_class(strategy).Options)
    return {f.name: dict(f.metadata["sweep"]) for f in fields if "sweep" in f.metadata}


def option_defaults(strategy: str) -> dict[str, object]:
    """The defaults of the strategy's options fields (those with a default)."""
    fields = dataclasses.fields(stepper_class(strategy).Options)
    return {f.name: f.default for f in fields if f.default is not dataclasses.MISSING}


def strategy_knobs(strategy: str, dt: float | str) -> dict[str, dict]:
    """Knob -> sweep spec of one strategy at a scene's base ``dt`` (a number or ``"auto"``:
    the CFL fractions are knobs, not dt)."""
    knobs = option_knobs(strategy)
    if dt == "auto":
        return knobs
    return {"dt": dict(DT_SWEEP), **{k: v for k, v in knobs.items() if k not in CFL_FIELDS}}


def _clip(spec: dict, value: float) -> float | None:
    lo, hi = spec.get("min", -math.inf), spec.get("max", math.inf)
    return value if lo <= value <= hi else None


def ladder(spec: dict, base: object, mode: str) -> tuple:
    """The values a knob takes in ``mode`` (``"quick"`` or ``"full"``) around ``base``.

    Args:
        spec: the knob's sweep declaration (``finer``, ``factor`` or ``step``, ...).
        base: the base value (a number, or None for "off": module docstring).
        mode: ``"quick"``: the base and one step finer (coarser where finer is out of range);
            ``"full"``: one coarser, base, one finer.

    Returns:
        the values, coarse to fine, without duplicates or values outside ``min`` / ``max``;
        ``()`` when the knob cannot be swept from this base (None without ``first``).
    """
    if mode not in ("quick", "full"):
        raise ValueError(f"mode must be 'quick' or 'full', got {mode!r}")
    if base is None:
        if "first" not in spec:
            return ()
        first = spec["first"]
        nxt = first + spec["step"] if "step" in spec else first * spec["factor"] ** spec["finer"]
        return (None, first) if mode == "quick" else (None, first, nxt)
    if isinstance(base, bool) or not isinstance(base, int | float):
        raise ValueError(f"a swept knob's base must be a number or None, got {base!r}")

    def move(k: int) -> float | None:  # k steps finer (negative: coarser)
        if "step" in spec:
            return _clip(spec, base + k * spec["finer"] * spec["step"])
        return _clip(spec, base * spec["factor"] ** (k * spec["finer"]))

    if mode == "quick":  # one step finer, or coarser where the finer end is out of range
        steps = (0, 1) if move(1) is not None else (-1, 0)
    else:
        steps = (-1, 0, 1)
    values = [v for v in (move(k) for k in steps) if v is not None]
    return tuple(dict.fromkeys(values))


def finer_key(spec: dict, value: object) -> float:
    """A sort key that grows toward the finer end (None, "off", is the coarsest)."""
    if value is None:
        return -math.inf
    return spec["finer"] * float(value)
