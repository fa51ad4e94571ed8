"""Regression references: stored trajectories of small scenes that a rerun must reproduce.

A reference is a scene file (:mod:`bfemp.scenefile`, runnable with ``bfemp run`` too) whose
``[regress]`` table says how to rerun and compare it::

    [regress]
    steps = 30                    # time steps to run (dt from [simulation])
    every = 3                     # store every 3rd step (step 0 and the last one always)
    quantities = ["mpm_x", "energy_total"]   # optional; default: DEFAULT_QUANTITIES present
    [regress.tolerances]          # optional overrides of the strategy's defaults
    mpm_x = { atol = 1e-9, rtol = 1e-6 }

Beside ``NAME.toml`` live ``NAME.npz`` (the stored trajectory, float64, one array per quantity of
shape ``(n_stored, ...)`` plus ``step``) and ``NAME.json`` (settings, tolerances, bfemp version and
commit, and what the last update changed). :func:`check` reruns a reference and compares;
:func:`update` rewrites the stored files on purpose and returns what changed.

Quantities: state arrays ``fem_x``, ``fem_v`` (m, m/s; ``(N, d)``), ``mpm_x``, ``mpm_v``
(``(P, d)``), ``mpm_F`` (``(P, d, d)``), and any column of ``Simulation.metrics`` (energies in J,
``contact_pairs``, ``min_distance`` in m, ...); ``t`` (s) is always stored, so a changed dt shows.

Tolerance of a quantity: it drifted at a stored step when ``max |run - stored| > atol + rtol *
scale``, with ``scale = max |stored|`` over the whole stored trajectory of that quantity (a
per-quantity scale: positions near zero or velocities at rest are not judged on round-off
alone). NaN matches NaN only (``min_distance`` is NaN without contact pairs).

The defaults (:data:`DEFAULT_TOLERANCES`, rtol 1e-9 for the explicit strategies, 1e-6 for
``barrier`` and ``two_stage``) lie between the drift of a rerun on another thread count and the
change a 0.1 % change of E, kappa or mu makes (``tools/regress_drift.py``; design note
``measurements``, regress); the implicit one leaves room for a Newton path that ends one
iteration apart (a difference up to the Newton tolerance, 1e-7 m/s, on velocities of ~1 m/s).
"""

from __future__ import annotations

import json
import logging
import math
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from bfemp._regress_reference import (
    DEFAULT_QUANTITIES,
    DEFAULT_TOLERANCES,
    STATE_QUANTITIES,
    Reference,
    Tolerance,
    default_reference_dir,
    find_references,
    load_reference,
    tolerance_of,
)
from bfemp.errors import SceneError
from bfemp.manifest import git_output

__all__ = [
    "DEFAULT_QUANTITIES",
    "DEFAULT_TOLERANCES",
    "Drift",
    "Reference",
    "Report",
    "Tolerance",
    "Trajectory",
    "check",
    "compare",
    "default_reference_dir",
    "find_references",
    "load_reference",
    "read_trajectory",
    "run_reference",
    "tolerance_of",
    "update",
]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Trajectory:
    """Stored quantities of a run.

    Attributes:
        steps: ``(n_stored,)`` the step numbers.
        data: name -> ``(n_stored, ...)`` float64 array.
        settings: the simulation's settings (strategy, dt, options, ...).
    """

    steps: np.ndarray
    data: dict[str, np.ndarray]
    settings: dict = field(default_factory=dict)


def _sample(sim: object, quantities: tuple[str, ...]) -> dict[str, np.ndarray]:
    out = {"t": np.array(float(sim.state.t))}
    row = {c: sim.metrics.column(c)[-1] for c in sim.metrics.columns}
    for q in quantities:
        if q in STATE_QUANTITIES:
            out[q] = np.array(getattr(sim.state, q), dtype=np.float64)
        else:
            out[q] = np.array(row.get(q, math.nan), dtype=np.float64)
    return out


def _quantities(ref: Reference, sim: object) -> tuple[str, ...]:
    """The quantities to store; state arrays the scene lacks are refused here, metrics columns
    after the run (some appear only with the first step's report)."""
    has = {q: _has_state(sim.model, q) for q in STATE_QUANTITIES}
    if ref.quantities is None:
        contact = sim.model.contact is not None
        return tuple(
            q
            for q in DEFAULT_QUANTITIES
            if has.get(q, contact or q not in ("contact_pairs", "min_distance"))
        )
    for q in ref.quantities:
        if q in has and not has[q]:
            _unknown_quantity(ref, sim, q)
    return ref.quantities


def _has_state(model: object, q: str) -> bool:
    """Whether the scene has the bodies of state array ``q`` (FEM nodes or particles)."""
    return (model.n_fem_nodes if q.startswith("fem") else model.n_particles) > 0


def _unknown_quantity(ref: Reference, sim: object, q: str) -> None:
    state = [n for n in STATE_QUANTITIES if _has_state(sim.model, n)]
    raise SceneError(
        f"unknown quantity {q!r} for this scene; known: {', '.join(state + sim.metrics.columns)}",
        file=str(ref.scene_file),
        field="regress.quantities",
    )


def run_reference(ref: Reference) -> Trajectory:
    """Run the reference's scene for ``ref.steps`` steps and sample its quantities."""
    from bfemp.simulation import Simulation

    sim = Simulation.from_file(ref.scene_file)
    quantities = _quantities(ref, sim)
    wanted = set(ref.stored_steps().tolist())
    samples = [_sample(sim, quantities)]
    log.info("reference %s: %s, %d steps of %g s", ref.name, sim.strategy, ref.steps, sim.dt)
    for step in range(1, ref.steps + 1):
        sim.step()
        if step in wanted:
            samples.append(_sample(sim, quantities))
    for q in quantities:
        if q not in STATE_QUANTITIES and q not in sim.metrics.columns:
            _unknown_quantity(ref, sim, q)
    data = {k: np.stack([s[k] for s in samples]) for k in samples[0]}
    settings = {
        k: v if isinstance(v, int | float | str | bool) or v is None else str(v)
        for k, v in sim.settings.items()
    }
    return Trajectory(steps=ref.stored_steps(), data=data, settings=settings)


# ------------------------------------------------------------------------------- comparing
@dataclass(frozen=True)
class Drift:
    """The comparison of one quantity.

    Attributes:
        quantity: its name.
        max_deviation: ``max |run - stored|`` over all stored steps (inf: shapes differ, NaN
            where the other is a number, or missing).
        tolerance: the allowed deviation ``atol + rtol * scale``.
        first_step: the first step at which the deviation exceeded the tolerance (None: never).
        worst_step: the step of the largest deviation.
        note: why the comparison could not be made entry by entry, if so.
    """

    quantity: str
    max_deviation: float
    tolerance: float
    first_step: int | None
    worst_step: int | None = None
    note: str = ""

    @property
    def ok(self) -> bool:
        """Within tolerance at every stored step."""
        return self.first_step is None and not self.note


@dataclass(frozen=True)
class Report:
    """The comparison of a rerun with a stored reference (``ok`` when nothing drifted)."""

    name: str
    drifts: tuple[Drift, ...]
    notes: tuple[str, ...] = ()

    @property
    def ok(self) -> bool:
        """No quantity drifted."""
        return all(d.ok for d in self.drifts)

    @property
    def drifted(self) -> list[Drift]:
        """The quantities that drifted."""
        return [d for d in self.drifts if not d.ok]

    def table(self, *, all_quantities: bool = False) -> str:
        """A readable table: quantity, max deviation, tolerance, first step beyond it."""
        rows = self.drifts if all_quantities else self.drifted
        head = f"{self.name}: {'ok' if self.ok else 'DRIFT'}"
        lines = [head, *(f"  note: {n}" for n in self.notes)]
        if rows:
            lines.append(f"  {'quantity':<22} {'max deviation':>14} {'tolerance':>11} first step")
            for d in rows:
                first = "-" if d.first_step is None else str(d.first_step)
                line = f"  {d.quantity:<22} {d.max_deviation:>14.3e} {d.tolerance:>11.3e} {first}"
                lines.append(line + (f"  ({d.note})" if d.note else ""))
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.table()


def _compare_one(
    name: str, run: np.ndarray, stored: np.ndarray, steps: np.ndarray, tol: Tolerance
) -> Drift:
    if run.shape != stored.shape:
        return Drift(
            name, math.inf, math.nan, None, note=f"shape {run.shape} vs stored {stored.shape}"
        )
    finite = np.isfinite(stored)
    scale = float(np.max(np.abs(stored[finite]), initial=0.0))
    allowed = tol.allowed(scale)
    n = run.shape[0]
    diff = np.abs(run - stored).reshape(n, -1)
    both_nan = (np.isnan(run) & np.isnan(stored)).reshape(n, -1)
    diff = np.where(both_nan, 0.0, diff)
    diff = np.where(np.isnan(diff), math.inf, diff)  # NaN against a number
    per_step = diff.max(axis=1, initial=0.0)
    beyond = np.flatnonzero(per_step > allowed)
    worst = int(np.argmax(per_step)) if n else 0
    return Drift(
        quantity=name,
        max_deviation=float(per_step.max(initial=0.0)),
        tolerance=allowed,
        first_step=int(steps[beyond[0]]) if beyond.size else None,
        worst_step=int(steps[worst]) if n else None,
    )


def compare(trajectory: Trajectory, stored: Trajectory, ref: Reference) -> Report:
    """Compare a rerun with the stored trajectory, quantity by quantity."""
    strategy = str(stored.settings.get("strategy", trajectory.settings.get("strategy", "barrier")))
    notes = []
    if not np.array_equal(trajectory.steps, stored.steps):
        notes.append(
            f"stored steps {stored.steps.tolist()} differ from the run's "
            f"{trajectory.steps.tolist()}: update the reference ([regress] changed)"
        )
        return Report(
            ref.name, (Drift("step", math.inf, 0.0, None, note="steps differ"),), tuple(notes)
        )
    changed = {
        k: (stored.settings.get(k), v)
        for k, v in trajectory.settings.items()
        if stored.settings.get(k) != v
    }
    if changed:
        notes.append(
            "settings differ from the stored ones: "
            + ", ".join(f"{k} {a!r} -> {b!r}" for k, (a, b) in changed.items())
        )
    drifts = []
    for name in sorted(set(trajectory.data) | set(stored.data)):
        if name not in stored.data or name not in trajectory.data:
            where = "stored" if name not in stored.data else "rerun"
            drifts.append(
                Drift(name, math.inf, math.nan, None, note=f"not in the {where} trajectory")
            )
            continue
        tol = tolerance_of(ref, strategy, name)
        drifts.append(
            _compare_one(name, trajectory.data[name], stored.data[name], stored.steps, tol)
        )
    return Report(ref.name, tuple(drifts), tuple(notes))


# ------------------------------------------------------------------------------- storing
def read_trajectory(ref: Reference) -> Trajectory:
    """The stored trajectory of ``ref`` (``NAME.npz`` and the settings of ``NAME.json``)."""
    if not ref.npz_path.is_file():
        raise SceneError(
            f"no stored trajectory {ref.npz_path}",
            hint=f"write it with: bfemp regress {ref.name} --update --dir {ref.scene_file.parent}",
        )
    with np.load(ref.npz_path, allow_pickle=False) as z:
        data = {k: np.array(z[k]) for k in z.files}
    steps = data.pop("step").astype(np.int64)
    settings = {}
    if ref.meta_path.is_file():
        settings = json.loads(ref.meta_path.read_text(encoding="utf-8")).get("settings", {})
    return Trajectory(steps=steps, data=data, settings=settings)


def check(ref: Reference) -> Report:
    """Rerun ``ref`` and compare it with its stored trajectory."""
    import hashlib
    from dataclasses import replace

    stored = read_trajectory(ref)
    report = compare(run_reference(ref), stored, ref)
    if ref.meta_path.is_file():
        written = json.loads(ref.meta_path.read_text(encoding="utf-8")).get("scene_sha256")
        if written and written != hashlib.sha256(ref.scene_file.read_bytes()).hexdigest():
            note = f"{ref.scene_file.name} changed since the reference was written"
            report = replace(report, notes=(*report.notes, note))
    for d in report.drifted:
        log.info(
            "reference %s: %s drifted by %.3e (tolerance %.3e), first at step %s",
            ref.name,
            d.quantity,
            d.max_deviation,
            d.tolerance,
            d.first_step,
        )
    return report


def _commit() -> str | None:
    """The git commit of this bfemp source checkout (None for an installed copy)."""
    out = git_output("rev-parse", "--show-toplevel", "HEAD")
    lines = [] if out is None else out.split()
    # a site-packages copy inside some other repository is not that repository's commit
    if len(lines) != 2 or Path(lines[0]).resolve() / "bfemp" != Path(__file__).resolve().parent:
        return None
    return lines[1]


def update(ref: Reference, trajectory: Trajectory | None = None) -> dict[str, float | str]:
    """Rerun ``ref`` (unless ``trajectory`` is given) and rewrite ``NAME.npz`` and ``NAME.json``.

    Returns what changed against the old stored trajectory: quantity -> max absolute change
    (``"new"`` without an old one, ``"added"`` / ``"removed"`` / ``"shape ..."`` where the
    quantity set changed), and ``"scene file"`` / ``"settings"`` / ``"tolerances"`` ->
    ``"changed"``; unchanged ones are left out. When nothing changed the files are left
    untouched, and an unchanged trajectory keeps its ``.npz``.
    """
    import hashlib

    import bfemp
    from bfemp.io.vtk import atomic_path, atomic_write_text

    trajectory = run_reference(ref) if trajectory is None else trajectory
    changes: dict[str, float | str] = {}
    if ref.npz_path.is_file():
        old = read_trajectory(ref)
        same_steps = np.array_equal(old.steps, trajectory.steps)
        for name in sorted(set(old.data) | set(trajectory.data)):
            if name not in old.data:
                changes[name] = "added"
            elif name not in trajectory.data:
                changes[name] = "removed"
            elif not same_steps or old.data[name].shape != trajectory.data[name].shape:
                changes[name] = f"shape {old.data[name].shape} -> {trajectory.data[name].shape}"
            else:
                drift = _compare_one(
                    name, trajectory.data[name], old.data[name], old.steps, Tolerance(0.0, 0.0)
                )
                if drift.max_deviation > 0.0:
                    changes[name] = drift.max_deviation
    else:
        changes = {"trajectory": "new"}
    strategy = str(trajectory.settings.get("strategy", "barrier"))
    meta = {
        "name": ref.name,
        "scene_file": ref.scene_file.name,
        "scene_sha256": hashlib.sha256(ref.scene_file.read_bytes()).hexdigest(),
        "steps": ref.steps,
        "every": ref.every,
        "settings": trajectory.settings,
        "quantities": {
            name: {
                "shape": list(a.shape),
                "scale": float(np.max(np.abs(a[np.isfinite(a)]), initial=0.0)),
                **vars(tolerance_of(ref, strategy, name)),
            }
            for name, a in trajectory.data.items()
        },
        "bfemp_version": bfemp.__version__,
        "commit": _commit(),
        "written": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "changes": changes,
    }
    old_meta = {}
    if ref.meta_path.is_file():
        old_meta = json.loads(ref.meta_path.read_text(encoding="utf-8"))
    trajectory_changed = bool(changes)
    for key, what in (("scene_sha256", "scene file"), ("settings", "settings")):
        if old_meta and old_meta.get(key) != meta[key]:
            changes[what] = "changed"
    old_q, new_q = old_meta.get("quantities", {}), meta["quantities"]
    if old_meta and any(
        (old_q.get(q, {}).get("atol"), old_q.get(q, {}).get("rtol")) != (v["atol"], v["rtol"])
        for q, v in new_q.items()
    ):
        changes["tolerances"] = "changed"
    if not changes and old_meta.get("steps") == ref.steps and old_meta.get("every") == ref.every:
        log.info("reference %s unchanged", ref.name)  # keep the files and their history
        return changes
    meta["changes"] = changes
    if trajectory_changed:  # an unchanged trajectory keeps its file (zip entries carry a time)
        with atomic_path(ref.npz_path) as tmp:
            with open(tmp, "wb") as fh:
                np.savez_compressed(fh, step=trajectory.steps, **trajectory.data)
    atomic_write_text(ref.meta_path, json.dumps(meta, indent=2) + "\n")
    log.info("reference %s written: %s", ref.name, changes or "no change")
    return changes
