"""Physical quantities in scene files: a plain number in SI units, or a string with a unit.

``dt = 0.01`` and ``dt = "10 ms"`` are the same; ``E = "50 MPa"`` is ``5e7`` Pa. A unit of the
wrong kind (``dt = "1 m"``) or an unknown one is an error that lists the units of the expected
kind. Vectors (gravity, velocities, corners) are plain SI numbers.
"""

from __future__ import annotations

import re

__all__ = ["UNITS", "parse_quantity"]

#: kind -> unit symbol -> factor to SI.
UNITS: dict[str, dict[str, float]] = {
    "length": {"m": 1.0, "km": 1e3, "cm": 1e-2, "mm": 1e-3, "um": 1e-6},
    "time": {"s": 1.0, "ms": 1e-3, "us": 1e-6, "min": 60.0},
    "pressure": {"Pa": 1.0, "kPa": 1e3, "MPa": 1e6, "GPa": 1e9},
    "density": {"kg/m^3": 1.0, "kg/m3": 1.0, "g/cm^3": 1e3, "g/cm3": 1e3},
    "velocity": {"m/s": 1.0, "cm/s": 1e-2, "mm/s": 1e-3},
    "acceleration": {"m/s^2": 1.0, "m/s2": 1.0},
}

#: kind -> the SI unit shown in messages.
SI = {kind: next(iter(units)) for kind, units in UNITS.items()}

_QUANTITY = re.compile(
    r"\s*([-+]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|inf|nan))\s*([A-Za-z/^0-9]+)?\s*"
)


def parse_quantity(value: object, kind: str | None) -> float:
    """The SI value of a number or of a ``"<number> <unit>"`` string.

    Args:
        value: what the scene file holds.
        kind: the expected kind (a key of :data:`UNITS`), or None for a dimensionless number.

    Returns:
        the value in SI units (float; NaN and inf pass through for the caller to judge).

    Raises:
        ValueError: with a message saying what was expected (the caller adds the location).
    """
    expected = "a number" if kind is None else f"a {kind} in {SI[kind]}"
    if isinstance(value, bool):
        raise ValueError(f"must be {expected}, got the boolean {str(value).lower()}")
    if isinstance(value, int | float):
        return float(value)
    if not isinstance(value, str):
        raise ValueError(f"must be {expected}, got {type(value).__name__} {value!r}")
    match = _QUANTITY.fullmatch(value)
    if match is None:
        raise ValueError(f"must be {expected}, got the text {value!r}")
    number, unit = float(match.group(1)), match.group(2)
    if unit is None:
        raise ValueError(f"must be {expected}: write {match.group(1)} without quotes")
    if kind is None:
        raise ValueError(f"is dimensionless: write a plain number, got {value!r}")
    if unit in UNITS[kind]:
        return number * UNITS[kind][unit]
    allowed = ", ".join(UNITS[kind])
    other = next((other for other, units in UNITS.items() if unit in units), None)
    if other is not None:
        raise ValueError(f"unit {unit!r} is a {other}, but this is a {kind} ({allowed})")
    raise ValueError(f"unknown unit {unit!r} for a {kind}; use one of {allowed}")
