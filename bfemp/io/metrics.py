"""Per-step metrics table of a run (energies, momenta, iterations, timings, ...).

:class:`MetricsLog` is a column-oriented table of numbers with one row per time step. Columns
appear when a row first names them; earlier rows read NaN there, as do later rows that omit them.
Values are kept as Python ``int`` (integers, booleans) or ``float``; ``None`` means missing (NaN).

CSV format (:meth:`MetricsLog.to_csv`): a header line with the column names, then one line per
row; integers as integers, floats with ``repr`` (shortest text that reads back to the same
float64), NaN as ``nan`` and infinities as ``inf``/``-inf``. Reading accepts an empty field as NaN.
So a round trip keeps every value bit for bit, and integer columns stay integers.

A column NaN in every row, the initial one included, is not defined in its run
(:func:`undefined_column`: ``energy_contact`` under a strategy without a contact energy,
``min_distance`` and ``residual`` under an explicit one); checks (``[check]``) and plots treat
it as absent, not as non-finite.
"""

from __future__ import annotations

import csv
import io
import math
import numbers
import re
from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np

from bfemp.io.vtk import atomic_write_text

_INT_RE = re.compile(r"[+-]?\d+")

Number = float | int

__all__ = ["MetricsLog", "undefined_column"]


def undefined_column(values: np.ndarray) -> bool:
    """Whether a metrics column ``(rows,)`` is not defined in its run: NaN in every row, the
    initial one included (a strategy without a contact energy has ``energy_contact`` NaN, an
    explicit strategy ``min_distance``). A column that turns NaN after finite rows is
    defined and went non-finite."""
    values = np.asarray(values, dtype=np.float64)
    return bool(values.size) and bool(np.all(np.isnan(values)))


def _as_number(column: str, value: object) -> Number:
    """Convert one cell value to ``int`` or ``float``; raise ValueError naming the column."""
    if value is None:
        return math.nan
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value[()]
    if isinstance(value, (bool, np.bool_, numbers.Integral)):
        return int(value)
    if isinstance(value, numbers.Real):
        return float(value)
    raise ValueError(f"metrics column {column!r}: value {value!r} is not a real number")


def _parse(token: str, where: str) -> Number:
    token = token.strip()
    if not token:
        return math.nan
    if _INT_RE.fullmatch(token):
        return int(token)
    try:
        return float(token)
    except ValueError:
        raise ValueError(f"{where}: {token!r} is not a number") from None


def _format(value: Number) -> str:
    return str(value) if isinstance(value, int) else repr(float(value))


class MetricsLog:
    """Table of per-step numbers whose columns may grow.

    Args:
        rows: optional initial rows (each a mapping column name -> number), appended in order.
    """

    def __init__(self, rows: Iterable[Mapping[str, Number | None]] = ()) -> None:
        self._data: dict[str, list[Number]] = {}
        self._n = 0
        self.extend(rows)

    def append(self, row: Mapping[str, Number | None]) -> None:
        """Append one row: column name -> ``int``/``float``/numpy scalar/``bool``/``None``.

        New columns are created (NaN in earlier rows); columns missing from ``row`` get NaN.
        The row is validated as a whole before anything is stored.
        """
        if not isinstance(row, Mapping):
            raise ValueError(f"row must be a mapping column -> number, got {type(row).__name__}")
        values: dict[str, Number] = {}
        for key, value in row.items():
            if not isinstance(key, str) or not key.strip() or key != key.strip():
                raise ValueError(f"metrics column name {key!r} must be a non-empty trimmed string")
            values[key] = _as_number(key, value)
        for key in values:
            if key not in self._data:
                self._data[key] = [math.nan] * self._n
        for key, column in self._data.items():
            column.append(values.get(key, math.nan))
        self._n += 1

    def extend(self, rows: Iterable[Mapping[str, Number | None]]) -> None:
        """Append several rows in order (see :meth:`append`)."""
        for row in rows:
            self.append(row)

    def __len__(self) -> int:
        return self._n

    def __contains__(self, name: object) -> bool:
        return name in self._data

    def __repr__(self) -> str:
        return f"MetricsLog({self._n} rows, columns={self.columns})"

    @property
    def columns(self) -> list[str]:
        """Column names in order of first appearance."""
        return list(self._data)

    def column(self, name: str) -> np.ndarray:
        """Values of one column as a ``(len(self),)`` float64 array (NaN where missing)."""
        if name not in self._data:
            raise ValueError(f"unknown metrics column {name!r}; columns are {self.columns}")
        return np.array(self._data[name], dtype=np.float64)

    @property
    def rows(self) -> list[dict[str, Number]]:
        """All rows as dicts with every column (NaN where missing)."""
        return [{k: col[i] for k, col in self._data.items()} for i in range(self._n)]

    @property
    def last(self) -> dict[str, Number]:
        """The last row as a dict with every column; ValueError when the log is empty."""
        if self._n == 0:
            raise ValueError("MetricsLog is empty: there is no last row")
        return {k: col[-1] for k, col in self._data.items()}

    def as_dict(self) -> dict[str, list[Number | None]]:
        """JSON-friendly copy: column name -> list of values, non-finite values as ``None``."""
        return {
            k: [v if isinstance(v, int) or math.isfinite(v) else None for v in col]
            for k, col in self._data.items()
        }

    def to_csv(self, path: str | Path) -> Path:
        """Write the table as CSV (format in the module docstring), atomically; returns the path."""
        buffer = io.StringIO()
        writer = csv.writer(buffer, lineterminator="\n")
        writer.writerow(self.columns)
        columns = list(self._data.values())
        writer.writerows([_format(col[i]) for col in columns] for i in range(self._n))
        return atomic_write_text(path, buffer.getvalue())

    @classmethod
    def from_csv(cls, path: str | Path) -> MetricsLog:
        """Read a table written by :meth:`to_csv` (or any numeric CSV with a header line)."""
        path = Path(path)
        with path.open(newline="", encoding="utf-8") as f:
            lines = list(csv.reader(f))
        if not lines:
            raise ValueError(f"{path}: empty file, expected a header line")
        header = lines[0]
        duplicates = sorted({h for h in header if header.count(h) > 1})
        if duplicates:
            raise ValueError(f"{path}: duplicate columns {duplicates}")
        log = cls()
        for line_no, fields in enumerate(lines[1:], start=2):
            if not fields:
                continue
            if len(fields) != len(header):
                raise ValueError(
                    f"{path}, line {line_no}: {len(fields)} fields, header has {len(header)}"
                )
            where = f"{path}, line {line_no}, column"
            log.append(
                {h: _parse(v, f"{where} {h!r}") for h, v in zip(header, fields, strict=True)}
            )
        # Columns of a header-only file still exist.
        for h in header:
            log._data.setdefault(h, [math.nan] * log._n)
        return log
