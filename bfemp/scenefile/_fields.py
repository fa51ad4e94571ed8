"""Typed, located access to the tables of a scene file.

A :class:`Table` wraps one TOML table with its location (file, body, key path). Every getter
validates type, unit and range and raises :class:`~bfemp.errors.SceneError` naming the file, the
body and the field; unknown keys are refused with the allowed ones and the closest match.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Iterable

import numpy as np

from bfemp.errors import SceneError
from bfemp.scenefile._units import SI, parse_quantity

__all__ = ["MISSING", "Table"]

MISSING = object()


def _toml(value: object) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    return repr(value)


class Table:
    """One table of a scene file.

    Args:
        data: the parsed table.
        file: the scene file (for messages), or None for text.
        body: e.g. ``"fem body 'beam'"`` when the table belongs to a body.
        path: dotted key path of the table (``"material"``, ``"simulation"``, ...).
    """

    def __init__(
        self, data: object, *, file: str | None, body: str | None = None, path: str = ""
    ) -> None:
        self.file, self.body, self.path = file, body, path
        if not isinstance(data, dict):
            raise self.error(f"must be a table, got {type(data).__name__} {_toml(data)}")
        self.data = data

    # ------------------------------------------------------------------ messages
    def field(self, key: str | None = None) -> str | None:
        """Dotted path of ``key`` in this table (the table itself for None)."""
        parts = [p for p in (self.path, key) if p]
        return ".".join(parts) or None

    def error(self, message: str, key: str | None = None, hint: str | None = None) -> SceneError:
        """A located error about ``key`` (or the table itself)."""
        return SceneError(message, file=self.file, body=self.body, field=self.field(key), hint=hint)

    def check_keys(self, allowed: Iterable[str], required: Iterable[str] = ()) -> None:
        """Refuse keys outside ``allowed``; require those of ``required``."""
        allowed = sorted(set(allowed))
        for key in self.data:
            if key not in allowed:
                close = difflib.get_close_matches(str(key), allowed, n=1)
                hint = f"did you mean '{close[0]}'?" if close else None
                raise self.error(
                    f"unknown key '{key}'; allowed keys are {', '.join(allowed)}", hint=hint
                )
        for key in required:
            if key not in self.data:
                raise self.error(f"missing key '{key}'", key)

    # ------------------------------------------------------------------ getters
    def has(self, key: str) -> bool:
        """Whether ``key`` is present."""
        return key in self.data

    def raw(self, key: str, default: object = MISSING) -> object:
        """The value as parsed, or ``default`` (missing key is an error without one)."""
        if key in self.data:
            return self.data[key]
        if default is MISSING:
            raise self.error(f"missing key '{key}'", key)
        return default

    def number(
        self,
        key: str,
        kind: str | None = None,
        *,
        default: object = MISSING,
        positive: bool = False,
        minimum: float | None = None,
        hint: str | None = None,
    ) -> float:
        """A finite number (SI; a ``"<number> <unit>"`` string of ``kind`` is converted)."""
        value = self.raw(key, default)
        if value is default and key not in self.data:
            return value  # type: ignore[return-value]
        try:
            out = parse_quantity(value, kind)
        except ValueError as err:
            raise self.error(str(err), key, hint) from None
        unit = f" {SI[kind]}" if kind else ""
        if not math.isfinite(out):
            raise self.error(f"must be a finite number, got {_toml(value)}", key, hint)
        if positive and not out > 0.0:
            raise self.error(f"must be > 0{unit}, got {_toml(value)}", key, hint)
        if minimum is not None and out < minimum:
            raise self.error(f"must be >= {minimum:g}{unit}, got {_toml(value)}", key, hint)
        return out

    def integer(self, key: str, *, default: object = MISSING, minimum: int | None = None) -> int:
        """An integer (TOML integer; a float with an integral value is refused)."""
        value = self.raw(key, default)
        if value is default and key not in self.data:
            return value  # type: ignore[return-value]
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(f"must be an integer, got {_toml(value)}", key)
        if minimum is not None and value < minimum:
            raise self.error(f"must be an integer >= {minimum}, got {value}", key)
        return value

    def string(
        self, key: str, *, default: object = MISSING, choices: Iterable[str] | None = None
    ) -> str:
        """A string, optionally one of ``choices``."""
        value = self.raw(key, default)
        if value is default and key not in self.data:
            return value  # type: ignore[return-value]
        if not isinstance(value, str):
            raise self.error(f"must be a string, got {_toml(value)}", key)
        if choices is not None:
            choices = sorted(choices)
            if value not in choices:
                close = difflib.get_close_matches(value, choices, n=1)
                raise self.error(
                    f"must be one of {', '.join(choices)}; got '{value}'",
                    key,
                    f"did you mean '{close[0]}'?" if close else None,
                )
        return value

    def boolean(self, key: str, *, default: object = MISSING) -> bool:
        """A boolean (``true`` / ``false``)."""
        value = self.raw(key, default)
        if value is default and key not in self.data:
            return value  # type: ignore[return-value]
        if not isinstance(value, bool):
            raise self.error(f"must be true or false, got {_toml(value)}", key)
        return value

    def vector(
        self, key: str, dim: int | None, *, default: object = MISSING, finite: bool = True
    ) -> tuple[float, ...]:
        """``dim`` numbers (SI) as a tuple of floats (``dim`` None: 2 or 3)."""
        value = self.raw(key, default)
        if value is default and key not in self.data:
            return value  # type: ignore[return-value]
        want = "2 or 3" if dim is None else str(dim)
        ok = isinstance(value, list) and all(
            isinstance(v, int | float) and not isinstance(v, bool) for v in value
        )
        if not ok or (len(value) != dim if dim else len(value) not in (2, 3)):
            raise self.error(f"must be a list of {want} numbers, got {_toml(value)}", key)
        out = tuple(float(v) for v in value)
        if finite and not all(math.isfinite(v) for v in out):
            raise self.error(f"must hold finite numbers, got {_toml(value)}", key)
        return out

    def array(self, key: str, dtype: type, width: int | None = None) -> np.ndarray:
        """A rectangular list of numbers as an array (``(n,)`` or ``(n, width)``)."""
        value = self.raw(key)
        kind = "integers" if dtype is np.int64 else "numbers"
        try:
            if not isinstance(value, list):
                raise TypeError
            arr = np.array(value, dtype=object)
            flat = arr.ravel().tolist()
            if any(isinstance(v, bool) or not isinstance(v, int | float) for v in flat):
                raise TypeError
            if dtype is np.int64 and any(isinstance(v, float) for v in flat):
                raise TypeError
            arr = np.array(value, dtype=dtype)
        except (TypeError, ValueError):
            shape = f"(n, {width})" if width else "(n,)"
            raise self.error(f"must be a list {shape} of {kind}", key) from None
        if width is not None and (arr.ndim != 2 or arr.shape[1] != width):
            raise self.error(f"must be a list of rows of {width} {kind}, got {arr.shape}", key)
        if width is None and arr.ndim != 1:
            raise self.error(f"must be a flat list of {kind}, got shape {arr.shape}", key)
        if dtype is not np.int64 and not np.all(np.isfinite(arr)):
            bad = np.flatnonzero(~np.all(np.isfinite(arr.reshape(arr.shape[0], -1)), axis=1))
            raise self.error(f"holds NaN or inf at rows {bad[:10].tolist()}", key)
        return np.ascontiguousarray(arr)

    def sub(self, key: str, *, default_empty: bool = False, body: str | None = None) -> Table:
        """The sub-table ``key`` (an empty one when missing and ``default_empty``)."""
        value = self.raw(key, {} if default_empty else MISSING)
        return Table(value, file=self.file, body=body or self.body, path=self.field(key) or "")

    def tables(self, key: str) -> list[dict]:
        """The array of tables ``key`` (``[[key]]``), empty when missing."""
        value = self.data.get(key, [])
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            raise self.error(f"must be written as [[{key}]] tables, got {_toml(value)}", key)
        return value
