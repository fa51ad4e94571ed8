"""Stability at the extremes: one base impact scene, one knob pushed to its limit per case.

The cases (``benchmarks/_extreme_cases.py``): E from 1e3 to 1e12 Pa, nu up to 0.499, dt from
1e-5 to 1e-1 s for a 40 m/s impact, dhat from 1e-2 down to 1e-6 of the scene size, density ratios
1e-4 to 1e4 between the bodies, grazing contact, corner-first contact (MPM corner and FEM corner),
particles exactly over mesh vertices, particles on grid-cell centres, kappa far too small (1 Pa)
and far too large (1e16 Pa) and "auto", a block resting on a fixed slab under gravity for many
steps (drift), Newmark (at the mode's and at the coarse resolution), and grazing with friction.
Quick mode runs the subset marked ``quick`` (the tests assert its expected outcomes); full mode
runs every case on the finer discretisation for longer.

Every step of every case is checked independently of the solver:

- no penetration: no particle inside any FEM mesh at its current positions
  (``geometry.sampling.points_in_mesh``, points on a facet count as inside);
- J > 0 for every FEM cell (``F = sum_a x_a grad N_a^T``) and every particle (``det mpm_F``);
- no NaN or inf in positions, velocities, F or the energies;
- bounded energy: ``(E(t) - E(0)) / E_ref < ENERGY_TOL[integrator]`` with ``E = energy_total`` of
  ``sim.metrics`` (kinetic + elastic + gravity + barrier) and ``E_ref = E(0)`` (the block's
  kinetic energy), or the block's weight times its
  height for the resting case; no friction or external work enters these scenes (friction only
  dissipates), so backward Euler must not gain energy; Newmark gets a small allowance;
- resting case: the block's mean height must not drift by more than ``DRIFT_TOL`` dhat over the
  second half of the run.

The outcome of a case is ``"pass"``; or the solver's named failure (``StepError`` status and
message, or ``FRICTION_NOT_CONVERGED`` when a step's report says the friction loop hit its cap);
``"REFUSED: ..."`` when the library rejects the set-up with a ``ValueError`` that names the field;
or ``"UNEXPLAINED: ..."`` when a check fails without a reason from the solver (or the library
raised something other than ``StepError``): those are bugs. Each case records its min distance
(the reports' ``min_distance``, and an independent particle-to-boundary distance), min J, max
energy growth, Newton iterations (sum, max), steps, wall time and outcome; the table goes to
``extremes.json`` (top level: ``cases`` plus counts) and ``extremes.md``; ``extremes.png`` plots
the per-case values.
"""

from __future__ import annotations

import logging
import math
import time
import traceback
from pathlib import Path

import numpy as np

import bfemp
from benchmarks._extreme_cases import (
    CASES,
    MODES,
    SCENE_SIZE,
    Case,
    build_scene,
    n_steps,
    quick_cases,
)
from benchmarks.common import environment, peak_memory_mb, write_json
from geometry.mesh import TriMesh
from geometry.sampling import points_in_mesh

log = logging.getLogger(__name__)

NAME = "extremes"
#: allowed relative energy gain per integrator
ENERGY_TOL = {"backward_euler": 1e-2, "newmark": 2e-2, "newmark_implicit_contact": 1e-2}
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

    def __init__(self, sim: bfemp.Simulation, energy_ref: float, energy_tol: float) -> None:
        self.sim = sim
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
        arrays = {
            "fem_x": state.fem_x,
            "fem_v": state.fem_v,
            "mpm_x": state.mpm_x,
            "mpm_v": state.mpm_v,
            "mpm_F": state.mpm_F,
        }
        bad = [name for name, a in arrays.items() if not np.all(np.isfinite(a))]
        energy = float(self.sim.metrics.column("energy_total")[-1])
        if not math.isfinite(energy):
            bad.append("energy_total")
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
        inside = 0
        for body in model.fem_bodies:
            cells = model.fem_cells[body.cells] - body.nodes.start
            mesh = TriMesh(state.fem_x[body.nodes], cells)
            inside += int(np.count_nonzero(points_in_mesh(mesh, state.mpm_x)))
            edges = body.boundary
            d = _segment_distance(state.mpm_x, state.fem_x[edges[:, 0]], state.fem_x[edges[:, 1]])
            self.min_geometric = min(self.min_geometric, d)
        self.max_penetrations = max(self.max_penetrations, inside)
        if inside:
            problems.append(f"{inside} particles inside the FEM mesh")
        growth = (energy - self.energy0) / self.energy_ref
        self.energy_growth = max(self.energy_growth, growth)
        if growth > self.energy_tol:
            problems.append(f"energy grew by {growth:.3g} of E_ref (tolerance {self.energy_tol})")
        return problems


def _clean(obj: object) -> object:
    """``obj`` with numpy scalars as Python numbers and non-finite floats as None (strict JSON)."""
    if isinstance(obj, dict):
        return {k: _clean(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_clean(v) for v in obj]
    if isinstance(obj, np.integer | np.bool_):
        return obj.item()
    if isinstance(obj, float | np.floating):
        return float(obj) if math.isfinite(obj) else None
    return obj


def _finite(value: float) -> float | None:
    return float(value) if value is not None and math.isfinite(value) else None


def run_case(case: Case, mode: str) -> dict:
    """Run one case; returns its table row (see the module docstring)."""
    cfg = case.config
    row: dict = {
        "name": case.name,
        "group": case.group,
        "knob": case.knob,
        "config": cfg.as_dict(),
        "dhat_m": cfg.dhat,
        "steps_planned": n_steps(cfg, mode),
        "expect_quick": case.expect,
    }
    started, cpu_started = time.perf_counter(), time.process_time()
    try:
        scene, info = build_scene(cfg, mode)
        row.update(info)
        sim = bfemp.Simulation(
            scene,
            integrator=cfg.integrator,
            transfer="apic",
            dt=cfg.dt,
            tol=cfg.tol,
            max_newton_iterations=cfg.max_newton_iterations,
        )
    except ValueError as err:  # the library refused the input and said why
        row.update(outcome=f"REFUSED: {err}", status="REFUSED", steps=0, wall_s=0.0)
        return row
    energy0 = float(sim.metrics.column("energy_total")[0])
    energy_ref = info["energy_ref_J"] if info["energy_ref_J"] else abs(energy0)
    checks = _Checks(sim, energy_ref, ENERGY_TOL[cfg.integrator])
    iters, distances, heights = [], [], []
    outcome = status = None
    friction_bad = 0
    block = sim.model.mpm_bodies[0].particles
    for k in range(1, row["steps_planned"] + 1):
        try:
            report = sim.step()
        except bfemp.StepError as err:
            rep = err.report
            iters.append(rep.newton_iterations)
            status = rep.status
            outcome = f"{rep.status} at step {k}: {rep.message}"
            break
        except Exception as err:  # noqa: BLE001 - any other exception is a bug to report
            log.error("%s: %s", case.name, traceback.format_exc())
            status = "UNEXPLAINED"
            outcome = f"UNEXPLAINED: {type(err).__name__} at step {k}: {err}"
            break
        iters.append(report.newton_iterations)
        distances.append(report.min_distance)
        heights.append(float(sim.state.mpm_x[block, 1].mean()))
        if not report.friction_converged:
            friction_bad += 1
            last_friction = (k, report.friction_iterations)
        problems = checks()
        named = [d for d in sim.diagnostics if d.startswith("ENERGY_GROWTH")]
        if problems and named and all(p.startswith("energy grew") for p in problems):
            # the simulation itself named the energy gain (Newmark with stiff contact)
            status = "ENERGY_GROWTH"
            outcome = f"{named[0]} (step {k})"
            break
        if problems:
            status = "UNEXPLAINED"
            outcome = f"UNEXPLAINED: {'; '.join(problems)} at step {k}"
            break
    row["wall_s"] = time.perf_counter() - started
    row["cpu_s"] = time.process_time() - cpu_started
    drift = None
    if cfg.geometry == "resting" and len(heights) >= 4:
        half = heights[len(heights) // 2 - 1 :]
        drift = float(max(half) - min(half))
        if outcome is None and drift > DRIFT_TOL * cfg.dhat:
            status = "UNEXPLAINED"
            outcome = f"UNEXPLAINED: the resting block drifted {drift:.3g} m (> {DRIFT_TOL} dhat)"
    if outcome is None and friction_bad:
        status = "FRICTION_NOT_CONVERGED"
        outcome = (
            f"FRICTION_NOT_CONVERGED: friction loop did not converge in {last_friction[1]} "
            f"iterations at {friction_bad} steps (last: step {last_friction[0]})"
        )
    if outcome is None:
        status = outcome = "pass"
    dist = np.asarray(distances, dtype=np.float64)
    it = np.asarray(iters, dtype=np.int64)
    energy = np.asarray(sim.metrics.column("energy_total"), dtype=np.float64)
    row.update(
        outcome=outcome,
        status=status,
        steps=len(distances),
        t_end=float(sim.state.t),
        min_distance=_finite(np.nanmin(dist)) if np.isfinite(dist).any() else None,
        min_distance_over_dhat=(
            _finite(np.nanmin(dist) / cfg.dhat) if np.isfinite(dist).any() else None
        ),
        min_distance_geometric=_finite(checks.min_geometric),
        contact_steps=int(np.count_nonzero(np.isfinite(dist))),
        penetrations=checks.max_penetrations,
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
    )
    log.info(
        "%-16s %-6s steps %4d  %.1f s  %s", case.name, mode, row["steps"], row["wall_s"], outcome
    )
    return row


def run(mode: str = "full", out: str | Path = "results") -> dict:
    """Run every case of ``mode`` and write ``extremes.json``, ``extremes.md``, ``extremes.png``."""
    if mode not in MODES:
        raise ValueError(f"mode must be one of {sorted(MODES)}, got {mode!r}")
    out = Path(out)
    cases = quick_cases() if mode == "quick" else CASES
    started = time.perf_counter()
    rows = [run_case(case, mode) for case in cases]
    wall = time.perf_counter() - started
    statuses = [r["status"] for r in rows]
    payload = {
        "benchmark": NAME,
        "mode": mode,
        "n_cases": len(rows),
        "n_pass": statuses.count("pass"),
        "n_named_failures": sum(s not in ("pass", "UNEXPLAINED") for s in statuses),
        "n_unexplained": statuses.count("UNEXPLAINED"),
        "unexplained": [r["name"] for r in rows if r["status"] == "UNEXPLAINED"],
        "no_nan": not any("non-finite" in r["outcome"] for r in rows),
        "no_inversion": all(r.get("min_J") is None or r["min_J"] > 0.0 for r in rows),
        "no_penetration": all(r.get("penetrations", 0) == 0 for r in rows),
        "min_J": min((r["min_J"] for r in rows if r.get("min_J") is not None), default=None),
        "wall_s": wall,
        "steps": int(sum(r.get("steps", 0) for r in rows)),
        "newton_iterations": int(sum(r.get("newton_iterations", 0) for r in rows)),
        "peak_memory_mb": peak_memory_mb(),
        "parameters": {
            "mode": MODES[mode],
            "scene_size_m": SCENE_SIZE,
            "energy_tol": ENERGY_TOL,
            "drift_tol_dhat": DRIFT_TOL,
            "transfer": "apic",
            "base": "see benchmarks/_extreme_cases.py: free FEM slab, MPM block at 40 m/s",
        },
        "cases": rows,
        "environment": environment(),
    }
    payload = _clean(payload)
    path = write_json(out, NAME, payload)
    md = out / f"{NAME}.md"
    md.write_text(markdown_table(payload))
    plot_cases(rows, out / f"{NAME}.png", title=f"extremes ({mode})")
    return {"json": str(path), "markdown": str(md), "png": str(out / f"{NAME}.png"), **payload}


# ---------------------------------------------------------------------------------- report
def _fmt(value: object, spec: str = ".3g") -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return format(value, spec)
    return str(value)


def markdown_table(payload: dict) -> str:
    """The case table as markdown: one row per case with every recorded value."""
    lines = [
        f"# extremes ({payload['mode']} mode)",
        "",
        f"{payload['n_cases']} cases: {payload['n_pass']} pass, {payload['n_named_failures']} "
        f"named failures, {payload['n_unexplained']} unexplained. Wall time "
        f"{payload['wall_s']:.1f} s, commit `{payload['environment']['commit'][:10]}`.",
        "",
        "min d: smallest active contact distance of the step reports (NaN rows, no pair within "
        "dhat, skipped); geometric: independent particle-to-boundary distance; growth: "
        "max_t (E(t) - E(0)) / E_ref; Newton: sum / max per step.",
        "",
        "| case | knob | steps | min d [m] | min d / dhat | geometric d [m] | penetrations "
        "| min J (FEM) | min J (MPM) | max energy growth | Newton sum / max | wall [s] | cpu [s] "
        "| outcome |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in payload["cases"]:
        steps = f"{r.get('steps', 0)} / {r['steps_planned']}"
        newton = f"{r.get('newton_iterations', 0)} / {r.get('newton_iterations_max', 0)}"
        outcome = str(r["outcome"]).replace("|", "\\|")
        if r.get("drift_m") is not None:
            outcome += f" (drift {r['drift_m']:.2e} m)"
        cells = [
            r["name"],
            r["knob"],
            steps,
            _fmt(r.get("min_distance")),
            _fmt(r.get("min_distance_over_dhat")),
            _fmt(r.get("min_distance_geometric")),
            _fmt(r.get("penetrations")),
            _fmt(r.get("min_J_fem"), ".4g"),
            _fmt(r.get("min_J_mpm"), ".4g"),
            _fmt(r.get("energy_growth_max"), ".2e"),
            newton,
            _fmt(r.get("wall_s"), ".2f"),
            _fmt(r.get("cpu_s"), ".2f"),
            outcome,
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def plot_cases(rows: list[dict], path: Path, title: str) -> None:
    """Per case: min distance / dhat, min J, max energy growth and max Newton iterations, bars
    coloured by outcome (green pass, orange named failure, red unexplained)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    names = [r["name"] for r in rows]
    colours = [
        "tab:green"
        if r["status"] == "pass"
        else "tab:red"
        if r["status"] == "UNEXPLAINED"
        else "tab:orange"
        for r in rows
    ]
    panels = (
        ("min_distance_over_dhat", "min distance / dhat", "log"),
        ("min_J", "min J", "log"),
        ("energy_growth_max", "max (E - E0) / E_ref", "symlog"),
        ("newton_iterations_max", "max Newton its / step", "log"),
    )
    fig = Figure(figsize=(14.0, 0.28 * len(rows) + 2.0), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, len(panels), sharey=True)
    y = np.arange(len(rows))
    for ax, (key, label, scale) in zip(axes, panels, strict=True):
        vals = np.array([np.nan if r.get(key) is None else r[key] for r in rows], dtype=float)
        ax.barh(y, np.nan_to_num(vals, nan=0.0), color=colours)
        ax.set_xscale(scale, **({"linthresh": 1e-4} if scale == "symlog" else {}))
        if scale == "symlog":
            ax.axvline(ENERGY_TOL["backward_euler"], color="k", ls="--", lw=0.8)
            ax.set_xlim(-1.0, max(1.0, float(np.nanmax(vals, initial=0.0))) * 1.2)
            ax.set_xticks([-1.0, -1e-2, -1e-4, 0.0, 1e-4, 1e-2, 1.0])
            ax.tick_params(axis="x", labelsize="small")
        ax.set_xlabel(label)
        ax.grid(True, axis="x", alpha=0.3)
    axes[0].set_yticks(y, names, fontsize="small")
    axes[0].invert_yaxis()
    fig.suptitle(title + ": green pass, orange named failure, red unexplained")
    fig.savefig(path, dpi=110)
