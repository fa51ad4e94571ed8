"""Argument checks shared by the geometry builders: each returns the value as floats or raises
ValueError naming the argument."""

from __future__ import annotations

import numpy as np


def vector(name: str, value: object, dim: int | None = None) -> np.ndarray:
    """``value`` as a finite float64 (d,) array, d = ``dim`` or 2 / 3, else ValueError."""
    want = "2 or 3" if dim is None else str(dim)
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be {want} numbers, got {value!r}") from exc
    ok = arr.shape in ((2,), (3,)) if dim is None else arr.shape == (dim,)
    if not ok or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be {want} finite numbers, got {value!r}")
    return arr


def positive(name: str, value: object) -> float:
    """``value`` as a finite float > 0, else ValueError naming ``name``."""
    try:
        out = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a positive number, got {value!r}") from exc
    if not (np.isfinite(out) and out > 0.0):
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    return out
