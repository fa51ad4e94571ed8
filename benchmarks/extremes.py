"""Stability at the extremes: one base impact scene, one knob pushed to its limit per case.

The cases (``benchmarks/_extreme_cases.CASES``) push stiffness, Poisson ratio, dt, dhat, the
density ratio, the contact geometry, kappa, friction and the integrator, and rest a block on a
fixed slab for many steps (drift). Modes: ``quick`` runs the cases marked ``quick`` (the tests
assert their expected outcomes), ``full`` every case finer and longer.

Every step of every case is checked independently of the solver (``_Checks``):

- no penetration: no particle inside any FEM mesh at its current positions
  (``geometry.sampling.points_in_mesh``, points on a facet count as inside);
- J > 0 for every FEM cell (``F = sum_a x_a grad N_a^T``) and every particle (``det mpm_F``);
- no NaN or inf in positions, velocities, F or the energies;
- bounded energy: ``(E(t) - E(0)) / E_ref < ENERGY_TOL[integrator]``, ``E = energy_total`` of
  ``sim.metrics`` (kinetic + elastic + gravity + barrier), ``E_ref = E(0)`` (the block's kinetic
  energy) or, resting, the block's weight times its height; no work enters these scenes
  (friction only dissipates);
- resting case: the block's mean height must not drift by more than ``DRIFT_TOL`` dhat over the
  second half of the run.

The outcome of a case is ``"pass"``; or the solver's named failure (``StepError`` status and
message, or ``FRICTION_NOT_CONVERGED`` when a step's report says the friction loop hit its cap);
``"REFUSED: ..."`` when the library rejects the set-up with a ``ValueError`` that names the field;
or ``"UNEXPLAINED: ..."`` when a check fails without a reason from the solver (or the library
raised something other than ``StepError``): those are bugs. Every strategy (``--strategy NAME``,
repeatable, or ``all``) runs the same cases; ``benchmarks/_extreme_strategies.py`` maps them and
names the outcomes beside those above (``NOT_APPLICABLE``, ``TOO_MANY_STEPS``, ``PENETRATION``,
``INVERTED``, ``DRIFT``, the extra run at ``dt = "auto"`` in ``row["auto"]``).

Energy allowance (``ENERGY_TOL``, this benchmark's choice): backward Euler 1e-2 (it only
dissipates: round-off and Newton tolerance), Newmark 2e-2, symplectic Euler 5e-2: its velocities
are half-step ones, so its reported kinetic energy is off by O(dt omega) and oscillates (bounded)
about the conserved modified energy, a few per cent of a vibrating body's elastic energy at the
CFL numbers of ``dt = "auto"`` (0.4-0.5). Records: ``extremes[_MODE].json`` (one row per case and
strategy), ``.md`` and ``.png`` (``_extreme_report``).
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import math
import time
import traceback
from collections import Counter
from pathlib import Path

import numpy as np

import bfemp
from benchmarks._extreme_cases import (
    CASES,
    MODES,
    SCENE_SIZE,
    Case,
    CaseConfig,
    build_scene,
    n_steps,
    quick_cases,
)
from benchmarks._extreme_report import markdown_table, plot_cases
from benchmarks._extreme_strategies import (
    EXPLICIT,
    EXPLICIT_DURATION,
    MAX_STEPS,
    NO_CROSSING,
    STRATEGY_NAMES,
    crossing_reason,
    drift_reason,
    duration,
    not_applicable,
    strategy_options,
)
from benchmarks.common import json_ready, log_row
from benchmarks.runner import Benchmark, name_unless, register
from geometry.mesh import TriMesh
from geometry.sampling import points_in_mesh

log = logging.getLogger(__name__)

NAME = "extremes"
#: allowed relative energy gain per integrator
ENERGY_TOL = {
    "backward_euler": 1e-2,
    "newmark": 2e-2,
    "newmark_implicit_contact": 1e-2,
    "symplectic_euler": 5e-2,
}
#: why an explicit strategy may invert a cell or particle (named outcome ``INVERTED``)
INVERSION_REASON = (
    "explicit elasticity has no det F > 0 guard; its stable step is set by the wave speed at "
    "rest, and a cell or particle crushed towards J = 0 stiffens past it"
)
#: allowed drift of the resting block's mean height over the second half of the run, in dhat
DRIFT_TOL = 0.1


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """Smallest distance in m from points ``p (n, 2)`` to segments ``a -> b`` ``(k, 2)``."""
    if p.shape[0] == 0 or a.shape[0] == 0:
        return math.inf
    ab = b - a  # (k, 2)
    ap = p[:, None, :] - a[None, :, :]  # (n, k, 2)
    t = np.clip(np.einsum("nki,ki->nk", ap, ab) / np.einsum("ki,ki->k", ab, ab), 0.0, 1.0)
    diff = ap - t[..., None] * ab[None]
    return float(np.sqrt(np.einsum("nki,nki->nk", diff, diff).min()))


class _Checks:
    """Independent per-step checks of a running simulation."""

    def __init__(
        self,
        sim: bfemp.Simulation,
        energy_ref: float,
        energy_tol: float,
        *,
        crossing_allowed: bool = False,
    ) -> None:
        """``crossing_allowed``: particles inside a FEM mesh are counted (``penetrations``,
        ``first_penetration``) but not reported as a problem (a strategy that does not promise
        to keep them out)."""
        self.sim = sim
        self.crossing_allowed = crossing_allowed
        self.first_penetration: int | None = None
        self.n_checks = 0
        self.model = sim.model
        self.energy0 = float(sim.metrics.column("energy_total")[0])
        self.energy_ref = energy_ref
        self.energy_tol = energy_tol
        self.min_J_fem = math.inf
        self.min_J_mpm = math.inf
        self.min_geometric = math.inf
        self.max_penetrations = 0
        self.energy_growth = -math.inf

    def __call__(self) -> list[str]:
        """Check the current state; returns the problems found (empty: all good)."""
        model, state = self.model, self.sim.state
        problems = []
        self.n_checks += 1
        fields = ("fem_x", "fem_v", "mpm_x", "mpm_v", "mpm_F")
        bad = [name for name in fields if not np.all(np.isfinite(getattr(state, name)))]
        if bad:
            return [f"non-finite {', '.join(bad)} after a converged step"]
        F = np.einsum("mai,maj->mij", state.fem_x[model.fem_cells], model.fem_cell_grad)
        j_fem = float(np.linalg.det(F).min())
        j_mpm = float(np.linalg.det(state.mpm_F).min())
        self.min_J_fem = min(self.min_J_fem, j_fem)
        self.min_J_mpm = min(self.min_J_mpm, j_mpm)
        if j_fem <= 0.0:
            problems.append(f"inverted FEM cell (J = {j_fem:.3g})")
        if j_mpm <= 0.0:
            problems.append(f"inverted particle (J = {j_mpm:.3g})")
        energy = float(self.sim.metrics.column("energy_total")[-1])
        if not math.isfinite(energy):
            # an inverted cell or particle has an infinite Neo-Hookean energy (log J): the
            # inversion above is then the reason, else the non-finite energy is the problem
            return problems or ["non-finite energy_total after a converged step"]
        inside = 0
        for body in model.fem_bodies:
            cells = model.fem_cells[body.cells] - body.nodes.start
            mesh = TriMesh(state.fem_x[body.nodes], cells)
            inside += int(np.count_nonzero(points_in_mesh(mesh, state.mpm_x)))
            edges = body.boundary
            d = _segment_distance(state.mpm_x, state.fem_x[edges[:, 0]], state.fem_x[edges[:, 1]])
            self.min_geometric = min(self.min_geometric, d)
        self.max_penetrations = max(self.max_penetrations, inside)
        if inside and self.first_penetration is None:
            self.first_penetration = self.n_checks
        if inside and not self.crossing_allowed:
            problems.append(f"{inside} particles inside the FEM mesh")
        growth = (energy - self.energy0) / self.energy_ref
        self.energy_growth = max(self.energy_growth, growth)
        if growth > self.energy_tol:
            problems.append(f"energy grew by {growth:.3g} of E_ref (tolerance {self.energy_tol})")
        return problems


def _finite(value: float) -> float | None:
    return float(value) if value is not None and math.isfinite(value) else None


@contextlib.contextmanager
def _warnings_logged():
    """Collects the library's warnings (``bfemp`` loggers) while inside: yields the list their
    messages go to."""
    handler = logging.Handler(logging.WARNING)
    messages: list[str] = []
    handler.emit = lambda record: messages.append(record.getMessage())
    logging.getLogger("bfemp").addHandler(handler)
    try:
        yield messages
    finally:
        logging.getLogger("bfemp").removeHandler(handler)


def _simulation(scene: bfemp.Scene, cfg: CaseConfig, strategy: str, dt: float | str):
    """The case's simulation under ``strategy`` (``ValueError`` when the library refuses)."""
    if strategy == "barrier":
        return bfemp.Simulation(
            scene,
            integrator=cfg.integrator,
            transfer="apic",
            dt=dt,
            tol=cfg.tol,
            max_newton_iterations=cfg.max_newton_iterations,
        )
    # explicit strategies: their default integrator (symplectic Euler) and transfer;
    # single_field couples nothing with the slab (bfemp refuses the pair): it runs here on
    # purpose, as the no-contact baseline whose outcome is PENETRATION
    return bfemp.Simulation(
        scene,
        strategy=strategy,
        dt=dt,
        options=strategy_options(cfg, strategy),
        allow_uncoupled=strategy == "single_field",
    )


def _is_stable_step_refusal(err: ValueError) -> bool:
    return "exceeds the explicit stable step" in str(err)


def run_case(case: Case, mode: str, strategy: str = "barrier") -> dict:
    """Run one case under one strategy; returns its table row (see the module docstring)."""
    cfg = case.config
    planned = n_steps(cfg, mode, duration=duration(case, mode, strategy))
    row: dict = {
        "name": case.name,
        "strategy": strategy,
        "group": case.group,
        "knob": case.knob,
        "config": cfg.as_dict(),
        "dhat_m": cfg.dhat,
        "steps_planned": planned,
        "expect_quick": case.expect,
    }
    reason = not_applicable(case, strategy)
    if reason is not None:
        return row | _not_run("NOT_APPLICABLE", reason)
    scene, info = build_scene(cfg, mode)
    row.update(info)
    try:
        with _warnings_logged() as warned:
            sim = _simulation(scene, cfg, strategy, cfg.dt)
    except ValueError as err:  # the library refused the input and said why
        row.update(_not_run("REFUSED", err))
        if strategy in EXPLICIT and _is_stable_step_refusal(err) and case.group != "dt":
            # the extra run at the stable step (the dt cases would repeat the base case's)
            try:
                with _warnings_logged() as warned:
                    sim = _simulation(build_scene(cfg, mode)[0], cfg, strategy, "auto")
            except ValueError as auto_err:  # refused for another reason (two_stage: kappa auto)
                row["auto"] = {
                    **_not_run("REFUSED", auto_err),
                    "dt": "auto",
                    "steps_planned": planned,
                }
                return row
            row["auto"] = _run(sim, case, mode, strategy, info, warned)
        return row
    row.update(_run(sim, case, mode, strategy, info, warned))
    return row


def _not_run(status: str, why: object) -> dict:
    """The outcome of a case that does not step: ``STATUS: why``, no step, no time."""
    return {"outcome": f"{status}: {why}", "status": status, "steps": 0, "wall_s": 0.0}


def _run(
    sim: bfemp.Simulation, case: Case, mode: str, strategy: str, info: dict, warnings: list[str]
) -> dict:
    """Step ``sim`` through the case with the checks; returns the row's measured values."""
    cfg = case.config
    planned = n_steps(cfg, mode, dt=sim.dt, duration=duration(case, mode, strategy))
    row: dict = {
        "dt": sim.dt,
        "integrator": sim.integrator.name,
        "transfer": sim.transfer,
        "steps_planned": planned,
        "warnings": list(warnings),
    }
    if planned > MAX_STEPS[mode]:
        why = (
            f"the stable dt {sim.dt:.3g} s needs {planned} steps for {planned * sim.dt:.3g} s "
            f"(cap {MAX_STEPS[mode]} in {mode} mode): not run"
        )
        return row | _not_run("TOO_MANY_STEPS", why)
    started, cpu_started = time.perf_counter(), time.process_time()
    energy0 = float(sim.metrics.column("energy_total")[0])
    energy_ref = info["energy_ref_J"] if info["energy_ref_J"] else abs(energy0)
    reason = crossing_reason(strategy)
    checks = _Checks(
        sim, energy_ref, ENERGY_TOL[sim.integrator.name], crossing_allowed=reason is not None
    )
    iters, distances, heights = [], [], []
    notes: Counter[str] = Counter()  # note code -> steps that reported it
    ended = None  # (status, outcome) of a run stopped before its last step
    friction_bad = 0
    block = sim.model.mpm_bodies[0].particles
    for k in range(1, planned + 1):
        try:
            report = sim.step()
        except bfemp.StepError as err:
            rep = err.report
            iters.append(rep.newton_iterations)
            ended = rep.status, f"{rep.status} at step {k}: {rep.message}"
            break
        except Exception as err:  # noqa: BLE001 - any other exception is a bug to report
            log.error("%s: %s", case.name, traceback.format_exc())
            ended = "UNEXPLAINED", f"UNEXPLAINED: {type(err).__name__} at step {k}: {err}"
            break
        iters.append(report.newton_iterations)
        distances.append(report.min_distance)
        heights.append(float(sim.state.mpm_x[block, 1].mean()))
        notes.update(note.split(":", 1)[0] for note in report.notes)
        if not report.friction_converged:
            friction_bad += 1
            last_friction = (k, report.friction_iterations)
        ended = _stopped(checks(), sim, strategy, checks, k)
        if ended is not None:
            break
    row["wall_s"] = time.perf_counter() - started
    row["cpu_s"] = time.process_time() - cpu_started
    status, outcome = ended or (None, None)
    if outcome is None and checks.max_penetrations:
        # (only where crossing is allowed: else the check above ended the run)
        status = "PENETRATION"
        outcome = (
            f"PENETRATION: up to {checks.max_penetrations} particles inside the FEM body at "
            f"once (first at step {checks.first_penetration}; {reason})"
        )
        if warnings:
            outcome += f"; the library warned: {warnings[0]}"
    drift = _drift(heights) if cfg.geometry == "resting" else None
    if outcome is None and drift is not None and drift > DRIFT_TOL * cfg.dhat:
        status, outcome = _drifted(drift, strategy, float(sim.state.mpm_v[block, 1].mean()))
    if outcome is None and friction_bad:
        status = "FRICTION_NOT_CONVERGED"
        outcome = (
            f"FRICTION_NOT_CONVERGED: friction loop did not converge in {last_friction[1]} "
            f"iterations at {friction_bad} steps (last: step {last_friction[0]})"
        )
    if outcome is None:
        status = outcome = "pass"
    dist = np.asarray(distances, dtype=np.float64)
    closest = np.nanmin(dist) if np.isfinite(dist).any() else None
    it = np.asarray(iters, dtype=np.int64)
    energy = np.asarray(sim.metrics.column("energy_total"), dtype=np.float64)
    row.update(
        outcome=outcome,
        status=status,
        steps=len(distances),
        t_end=float(sim.state.t),
        min_distance=_finite(closest),
        min_distance_over_dhat=None if closest is None else _finite(closest / cfg.dhat),
        min_distance_geometric=_finite(checks.min_geometric),
        contact_steps=int(np.count_nonzero(np.isfinite(dist))),
        penetrations=checks.max_penetrations,
        first_penetration_step=checks.first_penetration,
        min_J_fem=_finite(checks.min_J_fem),
        min_J_mpm=_finite(checks.min_J_mpm),
        min_J=_finite(min(checks.min_J_fem, checks.min_J_mpm)),
        energy_ref_J=energy_ref,
        energy_growth_max=_finite(checks.energy_growth),
        energy_final_rel=_finite((energy[-1] - energy0) / energy_ref),
        newton_iterations=int(it.sum()),
        newton_iterations_max=int(it.max()) if it.size else 0,
        friction_unconverged_steps=friction_bad,
        drift_m=drift,
        final_speed=_finite(float(np.abs(sim.state.mpm_v[block]).max())),
        notes=dict(notes),
    )
    log_row(log, f"{case.name} {strategy} {mode}", row, "steps wall_s outcome")
    return row


def _drift(heights: list[float]) -> float | None:
    """How far (m) the resting block's mean height ``heights`` (one per step) varied over the
    run's second half (None: fewer than 4 steps)."""
    if len(heights) < 4:
        return None
    half = heights[len(heights) // 2 - 1 :]
    return float(max(half) - min(half))


def _drifted(drift: float, strategy: str, speed: float) -> tuple[str, str]:
    """``(status, outcome)`` of a resting block that drifted ``drift`` m (more than
    ``DRIFT_TOL`` dhat), its mean vertical velocity ``speed`` m/s at the end: a named ``DRIFT``
    where the strategy explains it (``drift_reason``), else a bug."""
    why = drift_reason(strategy)
    if why is None:
        return (
            "UNEXPLAINED",
            f"UNEXPLAINED: the resting block drifted {drift:.3g} m (> {DRIFT_TOL} dhat)",
        )
    return "DRIFT", (
        f"DRIFT: the resting block's mean height varied by {drift:.3g} m over the second half "
        f"(> {DRIFT_TOL} dhat; mean vertical velocity {speed:.3g} m/s at the end): {why}"
    )


def _stopped(
    problems: list[str], sim: bfemp.Simulation, strategy: str, checks: _Checks, k: int
) -> tuple[str, str] | None:
    """``(status, outcome)`` that ends the run at step ``k`` for the checks' ``problems``
    (None: no problem, the run goes on)."""
    if not problems:
        return None
    named = [d for d in sim.diagnostics if d.startswith("ENERGY_GROWTH")]
    if named and all(p.startswith("energy grew") for p in problems):
        # the simulation itself named the energy gain (Newmark with stiff contact)
        outcome = f"{named[0]} (step {k})"
        if strategy in EXPLICIT:  # the library's advice is for Newmark: say what was seen
            outcome += (
                f"; {strategy} with symplectic Euler: growth {checks.energy_growth:.3g} of "
                f"E_ref > its allowance {ENERGY_TOL[sim.integrator.name]}"
            )
        return "ENERGY_GROWTH", outcome
    if strategy in EXPLICIT and all(p.startswith("inverted") for p in problems):
        # explicit elasticity has no det F > 0 filter (the barrier's line search has)
        outcome = f"INVERTED: {'; '.join(problems)} at step {k} ({INVERSION_REASON})"
        if checks.max_penetrations:
            outcome += (
                f"; before it, up to {checks.max_penetrations} particles inside the FEM "
                f"body (first at step {checks.first_penetration})"
            )
        return "INVERTED", outcome
    return "UNEXPLAINED", f"UNEXPLAINED: {'; '.join(problems)} at step {k}"


def _runs(row: dict) -> list[dict]:
    """The row and its extra ``dt = "auto"`` run, if any."""
    return [row] + ([row["auto"]] if "auto" in row else [])


def _counts(rows: list[dict]) -> dict:
    """Outcome counts of rows (the extra auto runs counted apart)."""
    statuses = [r["status"] for r in rows]
    autos = [r["auto"]["status"] for r in rows if "auto" in r]
    every = [run for r in rows for run in _runs(r)]
    return {
        "n_cases": len(rows),
        "n_pass": statuses.count("pass"),
        "n_named_failures": sum(
            s not in ("pass", "UNEXPLAINED", "NOT_APPLICABLE") for s in statuses
        ),
        "n_not_applicable": statuses.count("NOT_APPLICABLE"),
        "n_auto_runs": len(autos),
        "n_auto_pass": autos.count("pass"),
        "n_unexplained": sum(run["status"] == "UNEXPLAINED" for run in every),
        "wall_s": float(sum(run.get("wall_s", 0.0) for run in every)),
        "steps": int(sum(run.get("steps", 0) for run in every)),
    }


def resolve_strategies(names: list[str] | tuple[str, ...] | None) -> tuple[str, ...]:
    """The strategies to run, in table order: ``None`` or ``"all"`` for every one."""
    if not names or "all" in names:
        return STRATEGY_NAMES
    unknown = [n for n in names if n not in STRATEGY_NAMES]
    if unknown:
        raise ValueError(f"--strategy must be 'all' or one of {STRATEGY_NAMES}, got {unknown}")
    return tuple(s for s in STRATEGY_NAMES if s in names)


def measure(mode: str, cfg: dict, strategy: list[str] | None = None) -> dict:
    """Every case of ``mode`` under each strategy (``strategy``: names, None or ``all``: every
    one): the table (module docstring)."""
    strategies = resolve_strategies(strategy)

    cases = quick_cases() if mode == "quick" else CASES
    rows = [run_case(case, mode, s) for s in strategies for case in cases]
    every = [run for r in rows for run in _runs(r)]
    by_strategy = {s: _counts([r for r in rows if r["strategy"] == s]) for s in strategies}
    counts = _counts(rows)
    del counts["wall_s"]  # the run's wall time is the runner's (scene builds included)
    payload = {
        "strategies": list(strategies),
        **counts,
        "n_cases": len(cases),
        "n_rows": len(rows),
        "unexplained": [
            f"{r['name']} ({r['strategy']})"
            for r in rows
            if any(run["status"] == "UNEXPLAINED" for run in _runs(r))
        ],
        "no_nan": not any("non-finite" in run["outcome"] for run in every),
        "no_inversion": all(run.get("min_J") is None or run["min_J"] > 0.0 for run in every),
        "no_penetration": {
            s: all(
                run.get("penetrations", 0) == 0
                for r in rows
                if r["strategy"] == s
                for run in _runs(r)
            )
            for s in strategies
        },
        "min_J": min((run["min_J"] for run in every if run.get("min_J") is not None), default=None),
        "newton_iterations": int(sum(run.get("newton_iterations", 0) for run in every)),
        "table": {
            case.name: {
                r["strategy"]: r["status"]
                + (f" / auto: {r['auto']['status']}" if "auto" in r else "")
                for r in rows
                if r["name"] == case.name
            }
            for case in cases
        },
        "by_strategy": by_strategy,
        "parameters": {
            "mode": cfg,
            "scene_size_m": SCENE_SIZE,
            "energy_tol": ENERGY_TOL,
            "drift_tol_dhat": DRIFT_TOL,
            "max_steps": MAX_STEPS[mode],
            "explicit_duration_s": {k: v[mode] for k, v in EXPLICIT_DURATION.items()},
            "no_crossing_promise": sorted(NO_CROSSING),
            "transfer": {"barrier": "apic", "others": "the strategy's default"},
            "base": "see benchmarks/_extreme_cases.py: free FEM slab, MPM block at 40 m/s",
        },
        "cases": rows,
    }
    return json_ready(payload)


# ---------------------------------------------------------------------------------- CLI
def _arguments(parser: argparse._ActionsContainer) -> None:
    """``--strategy NAME`` (repeatable; ``all``, the default, runs every strategy)."""
    parser.add_argument(
        "--strategy",
        action="append",
        choices=("all",) + STRATEGY_NAMES,
        help="coupling strategy to run the cases under (repeatable; default all)",
    )


def _plot(payload: dict, png: Path) -> None:
    plot_cases(payload, png, title=f"extremes ({payload['mode']})")


BENCHMARK = register(
    Benchmark(
        NAME,
        __doc__,
        MODES,
        measure,
        _plot,
        markdown_table,
        record=name_unless("full", NAME),
        arguments=_arguments,
    )
)
run = BENCHMARK.run
