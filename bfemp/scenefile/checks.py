"""The ``[check]`` table of a scene file: assertions a run must satisfy (examples, regression).

Keys (all optional):

- ``description``: free text.
- ``finite = true``: every position, velocity and deformation gradient stays finite, and so do
  the energy and momentum columns of the metrics.
- ``energy_drift_max = r``: ``|E(t_end) - E(0)| <= r * scale``, E the total energy (J, J/m in
  2D) and ``scale = max(|E(0)|, max_t E_kinetic, max_t E_elastic)``.
- ``energy_growth_max = r``: ``max_t E(t) - E(0) <= r * scale`` (dissipation is allowed).
- ``drift_max = { column = tol }``: ``max_t |c(t) - c(0)| <= tol`` in the column's units (e.g.
  ``momentum_x`` in kg m/s, per unit thickness in 2D).
- ``min = { column = v }`` / ``max = { column = v }``: the column stays ``>= v`` / ``<= v``.
- ``bounds = { lower = [...], upper = [...] }``: every FEM node and particle stays in this box
  (m; +-inf for an open side) at every step.

The metrics checks see the whole run (a resumed run restores the earlier rows); ``finite`` and
``bounds`` see the states of the current session, which :class:`CheckRecorder` records.

A metrics column NaN in every row, the initial one included, is not defined in the run
(:func:`bfemp.io.metrics.undefined_column`: ``energy_contact`` under a strategy without a
contact energy, ``min_distance`` under an explicit strategy): ``finite`` does not judge it (its
detail names it), and a ``drift_max``, ``min`` or ``max`` check of it is skipped (printed
``skip``, not failed: the strategy does not measure it) rather than compared with NaN.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from bfemp.io.metrics import undefined_column
from bfemp.scenefile._fields import Table

__all__ = ["CheckRecorder", "CheckResult", "evaluate_checks", "validate_checks"]

_KEYS = (
    "description",
    "finite",
    "energy_drift_max",
    "energy_growth_max",
    "drift_max",
    "min",
    "max",
    "bounds",
)


def validate_checks(data: dict, *, file: str | None, dim: int) -> dict:
    """The ``[check]`` table validated (types, known keys); returns a normalised copy."""
    t = Table(data, file=file, path="check")
    t.check_keys(_KEYS)
    out: dict = {}
    if t.has("description"):
        out["description"] = t.string("description")
    if t.has("finite"):
        out["finite"] = t.boolean("finite")
    for key in ("energy_drift_max", "energy_growth_max"):
        if t.has(key):
            out[key] = t.number(key, minimum=0.0)
    for key in ("drift_max", "min", "max"):
        if t.has(key):
            sub = t.sub(key)
            out[key] = {col: sub.number(col) for col in sub.data}
    if t.has("bounds"):
        b = t.sub("bounds")
        b.check_keys({"lower", "upper"})
        out["bounds"] = {
            k: list(b.vector(k, dim, finite=False)) for k in ("lower", "upper") if b.has(k)
        }
    return out


@dataclass
class CheckRecorder:
    """Run callback recording what the checks need at every step: position extremes, finiteness.

    Use as ``sim.run(..., callback=recorder)``; call :meth:`record` once on the initial state.
    """

    lower: np.ndarray | None = None
    upper: np.ndarray | None = None
    finite: bool = True
    first_non_finite_t: float | None = None
    steps: int = 0

    def record(self, sim: object) -> None:
        """Record the current state of ``sim`` (a ``bfemp.Simulation``)."""
        state = sim.state
        x = np.concatenate([state.fem_x, state.mpm_x])
        if x.size:
            lo, hi = x.min(axis=0), x.max(axis=0)
            self.lower = lo if self.lower is None else np.minimum(self.lower, lo)
            self.upper = hi if self.upper is None else np.maximum(self.upper, hi)
        ok = all(
            np.all(np.isfinite(a)) for a in (state.fem_x, state.fem_v, state.mpm_x, state.mpm_F)
        )
        if not ok and self.finite:
            self.finite, self.first_non_finite_t = False, float(state.t)

    def __call__(self, sim: object) -> None:
        self.steps += 1
        self.record(sim)


@dataclass(frozen=True)
class CheckResult:
    """Outcome of one check: its name, whether it holds and what was measured; ``skipped``: a
    check of a column the run does not define (``ok``, printed ``skip``)."""

    name: str
    ok: bool
    detail: str = field(default="")
    skipped: bool = False

    def __str__(self) -> str:
        mark = "skip" if self.skipped else ("ok  " if self.ok else "FAIL")
        return f"{mark} {self.name}: {self.detail}"


def _column(metrics: object, name: str) -> np.ndarray:
    if name not in metrics.columns:
        raise ValueError(f"check: metrics have no column '{name}'; columns are {metrics.columns}")
    return metrics.column(name)


#: why a check of a column the run does not define is skipped
_UNDEFINED = "is not defined in this run (NaN in every row: the strategy does not compute it)"
#: the checks of one metrics column: key, measured value of the column, format, relation
_COLUMN_CHECKS = (
    ("drift_max", lambda c: np.nanmax(np.abs(c - c[0])), ".3g", "<="),
    ("min", np.nanmin, ".6g", ">="),
    ("max", np.nanmax, ".6g", "<="),
)


def evaluate_checks(check: dict, metrics: object, recorder: CheckRecorder) -> list[CheckResult]:
    """Evaluate a validated ``[check]`` table against a run's metrics log and recorder."""
    results = []
    if check.get("finite"):
        cols = [c for c in metrics.columns if c.startswith(("energy_", "momentum_", "angular_"))]
        undefined = [c for c in cols if undefined_column(metrics.column(c))]
        bad = [c for c in cols if c not in undefined and not np.all(np.isfinite(metrics.column(c)))]
        ok = recorder.finite and not bad
        detail = "state and metrics finite" if ok else f"non-finite state/columns {bad}"
        if undefined:
            detail += f" (not defined in this run, NaN in every row: {', '.join(undefined)})"
        if recorder.first_non_finite_t is not None:
            detail += f" (state first non-finite at t = {recorder.first_non_finite_t:g} s)"
        results.append(CheckResult("finite", ok, detail))
    if "energy_drift_max" in check or "energy_growth_max" in check:
        e = _column(metrics, "energy_total")
        scale = max(
            abs(e[0]),
            float(np.nanmax(_column(metrics, "energy_kinetic"))),
            float(np.nanmax(_column(metrics, "energy_elastic"))),
            1e-300,
        )
        drift = abs(e[-1] - e[0]) / scale
        growth = (float(np.nanmax(e)) - e[0]) / scale
        for key, r in (("energy_drift_max", drift), ("energy_growth_max", growth)):
            if key in check:
                results.append(
                    CheckResult(key, bool(r <= check[key]), f"{r:.3g} <= {check[key]:g}")
                )
    for key, measure, fmt, relation in _COLUMN_CHECKS:
        for name, limit in check.get(key, {}).items():
            c = _column(metrics, name)
            if undefined_column(c):
                detail = f"{name} {_UNDEFINED}"
                results.append(CheckResult(f"{key}.{name}", True, detail, skipped=True))
                continue
            value = float(measure(c))
            ok = value <= limit if relation == "<=" else value >= limit
            results.append(CheckResult(f"{key}.{name}", ok, f"{value:{fmt}} {relation} {limit:g}"))
    if "bounds" in check:
        lo = np.array(check["bounds"].get("lower", [-math.inf] * 3))
        hi = np.array(check["bounds"].get("upper", [math.inf] * 3))
        if recorder.lower is None:
            results.append(CheckResult("bounds", False, "no positions were recorded"))
        else:
            d = recorder.lower.size
            ok = bool(np.all(recorder.lower >= lo[:d]) and np.all(recorder.upper <= hi[:d]))
            detail = (
                f"positions span {np.round(recorder.lower, 6).tolist()} to "
                f"{np.round(recorder.upper, 6).tolist()} m"
            )
            results.append(CheckResult("bounds", ok, detail))
    return results
