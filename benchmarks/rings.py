"""Colliding rings (BFEMP paper, section 6.1, figures 6-7): momentum and energy of a collision.

Two identical 2D Neo-Hookean rings (inner radius 3 m, outer radius 4 m, E = 1e8 Pa, nu = 0.2,
rho = 1000 kg/m^2) fly at each other at 40 m/s each; the left ring is MPM, the right ring FEM, the
gap between their outer surfaces is 2 m, so they touch at t = 2 m / 80 m/s = 0.025 s. No gravity,
no friction; barrier contact with dhat = 1e-2 m, kappa = 1e7 Pa; Newmark, dt = 2e-4 s, Newton
tolerance 1e-6 m/s. The run is repeated with APIC and with FLIP transfers.

Metrics (top level of ``rings.json``):

- ``momentum_drift_rel``: max over the steps of both runs of ``|P(t) - P(0)|`` divided by
  ``|P_mpm(0)| + |P_fem(0)|`` (P: total linear momentum, kg m/s per unit thickness);
- ``min_distance``: the smallest particle-boundary distance seen at any step of either run (NaN
  rows, no pair within dhat, are skipped);
- ``energy_loss_pct``: ``(E(0.025) - E(0.293)) / E(0.025) * 100`` per transfer with ``E =
  kinetic + elastic`` (the barrier energy is recorded and plotted apart); E(0.025) at the last
  step at or before 0.025 s, E(0.293) at the first at or after 0.293 s
  (``catalogue.window_energies``);
- ``penetrations``: the largest count at any step of particles inside the deformed FEM ring,
  checked independently of the solver (``catalogue.RingsPenetration``; must be 0).

Integrator (``INTEGRATOR``): ``"newmark_implicit_contact"``, mid-point Newmark for both rings
with the barrier forces memory-free (:mod:`bfemp.integrators`). The paper's mid-point Newmark
read literally, with the barrier inside the trapezoidal rule, gains energy here: at the paper's
dt the closing speed carries a point through dhat within one step, and the trapezoidal rule
carries the stiff barrier force of one step into the next through a^n. Partial and full modes
also run it (``COMPARED_INTEGRATORS``, unless ``--no-compare``), recorded under
``compared_integrators``; ``energy_peak_over_start`` is the max of kinetic + elastic + barrier
over its value at t = 0. Measured results: ``benchmarks/records/rings.md``.

Choices where the paper is silent (recorded in the JSON ``parameters``):

- The discretisations are ``catalogue.RINGS_DISCRETISATION``'s (full: FEM ring h = 0.13, 1714
  vertices against the paper's 1830; MPM ring at dx = 0.1 m, ppc = 9, 19796 particles against
  20098); quick mode coarsens them (its energy loss is not expected to match the paper),
  partial mode coarsens the MPM grid only.
- Ring centres at (-5, 0) (MPM) and (5, 0) (FEM); run to t = 0.3 s, which holds the paper's
  collision window 0.025 s - 0.293 s.
- The MPM grid is shifted by a quarter of the particle spacing (``rings_grid_origin``: with
  ppc = 9 and an unshifted grid Newton cannot converge, even in free flight).
"""

from __future__ import annotations

import argparse
import logging
import time
from pathlib import Path

import numpy as np

import bfemp
from benchmarks.catalogue import (
    DHAT,
    GAP,
    KAPPA,
    MATERIAL,
    R_INNER,
    R_OUTER,
    RINGS_DISCRETISATION,
    SPEED,
    TOL,
    WINDOW,
    RingsPenetration,
    rings_grid_origin,
    rings_scene,
    window_energies,
)
from benchmarks.common import figure, log_row, save
from benchmarks.runner import Benchmark, register

log = logging.getLogger(__name__)

NAME = "rings"
PAPER = {
    "energy_loss_pct": {"apic": 8.57, "flip": 9.67},
    "particles": 20098,
    "fem_vertices": 1830,
    "fem_triangles": 3310,
}
TRANSFERS = ("apic", "flip")
#: the integrator of every run and of the top-level metrics (see the module docstring)
INTEGRATOR = "newmark_implicit_contact"
#: also run in partial and full modes, recorded under ``compared_integrators``
COMPARED_INTEGRATORS = ("newmark",)

#: the catalogue's discretisations (partial: paper dt and FEM mesh, MPM grid coarsened 2x) with
#: their steps
MODES = {
    "full": dict(**RINGS_DISCRETISATION["full"], dt=2e-4, t_end=0.3),
    "partial": dict(**RINGS_DISCRETISATION["partial"], dt=2e-4, t_end=0.3),
    "quick": dict(**RINGS_DISCRETISATION["quick"], dt=2e-3, t_end=0.3),
}
SERIES_POINTS = 400  # per-step curves stored in the JSON are subsampled to about this many


def collide(sim: bfemp.Simulation, t_end: float, callback: object = None) -> tuple:
    """Run ``sim`` to ``t_end`` s with the per-step ``callback``: ``(the StepError message or
    None, wall time in s)``; a failed step ends the run, the metrics so far stand."""
    started, error = time.perf_counter(), None
    try:
        sim.run(t_end=t_end, progress=False, callback=callback)
    except bfemp.StepError as err:
        error = str(err)
        log.error("rings under %s: %s", sim.strategy, err)
    return error, time.perf_counter() - started


def momentum_drift(metrics: object, scale: float) -> np.ndarray:
    """``|P(t) - P(0)| / scale`` ``(n,)`` of the total linear momentum of each row of the
    ``metrics`` (``scale`` in kg m/s per unit thickness)."""
    momentum = np.stack([metrics.column("momentum_x"), metrics.column("momentum_y")], axis=1)
    return np.linalg.norm(momentum - momentum[0], axis=1) / scale


def run_transfer(cfg: dict, transfer: str, keep: dict | None = None) -> dict:
    """One transfer: run to ``t_end`` and reduce the metrics table (``keep`` given: the
    simulation is stored under ``keep["sim"]``)."""
    scene = rings_scene(cfg)
    sim = bfemp.Simulation(
        scene,
        strategy=cfg.get("strategy", "barrier"),
        integrator=cfg.get("integrator", INTEGRATOR),
        transfer=transfer,
        dt=cfg["dt"],
        tol=cfg.get("tol", TOL),
    )
    model = sim.model
    if keep is not None:
        keep["sim"] = sim
    check = RingsPenetration(sim)
    error, wall = collide(sim, cfg["t_end"], check)
    m = sim.metrics
    t = m.column("t")
    # the spec's E = kinetic + elastic (no gravity here); the barrier energy is kept apart
    energy = m.column("energy_kinetic") + m.column("energy_elastic")
    contact_energy = (
        m.column("energy_contact") if "energy_contact" in m.columns else np.zeros_like(t)
    )
    p_fem = model.fem_mass @ model.fem_v0
    p_mpm = model.mpm_mass @ model.mpm_v0
    scale = float(np.linalg.norm(p_fem) + np.linalg.norm(p_mpm))
    drift = momentum_drift(m, scale)
    dist = m.column("min_distance")[1:]
    pairs = m.column("contact_pairs")[1:]
    touching = t[1:][pairs > 0]
    iters = m.column("iterations_newton")[1:]
    e0, e1 = window_energies(t, energy)
    return {
        "transfer": transfer,
        "error": error,
        "steps": int(len(t) - 1),
        "wall_s": wall,
        "particles": int(model.n_particles),
        "fem_vertices": int(model.n_fem_nodes),
        "fem_triangles": int(model.fem_cells.shape[0]),
        "momentum_drift_rel": float(drift.max()),
        "momentum_scale": scale,
        "min_distance": float(np.nanmin(dist)) if np.isfinite(dist).any() else float("nan"),
        "contact_steps": int(np.count_nonzero(pairs > 0)),
        "contact_window_s": [float(touching[0]), float(touching[-1])] if touching.size else None,
        "energy_window_J": [e0, e1],
        "energy_loss_pct": 100.0 * (e0 - e1) / e0,
        "energy_peak_over_start": float(np.max(energy + contact_energy) / energy[0]),
        "penetrations": int(check.worst),
        "diagnostics": list(getattr(sim, "diagnostics", [])),
        "newton_iterations": int(np.nansum(iters)),
        "newton_iterations_max": int(np.nanmax(iters)) if iters.size else 0,
        # seconds per phase summed over the steps (factorize, assemble, line_search, ...)
        "phase_s": {
            c[len("time_") :]: float(np.nansum(m.column(c)))
            for c in m.columns
            if c.startswith("time_")
        },
        "series": {
            "t": t,
            "kinetic": m.column("energy_kinetic"),
            "elastic": m.column("energy_elastic"),
            "total": energy,
            "contact": contact_energy,
            "drift": drift,
            "min_distance": m.column("min_distance"),
        },
    }


def _for_json(run: dict) -> dict:
    """A run's summary with its per-step curves subsampled (every k-th step and the last)."""
    out = {key: value for key, value in run.items() if key != "series"}
    n = run["series"]["t"].size
    keep = np.unique(np.r_[np.arange(0, n, max(1, n // SERIES_POINTS)), n - 1])
    out["series"] = {key: value[keep].tolist() for key, value in run["series"].items()}
    return out


def _summary(runs: dict) -> dict:
    """The record's entries over the transfers' ``runs`` (transfer -> ``run_transfer``'s
    result): largest drift and penetration count, smallest distance, summed wall time and
    Newton iterations, each transfer's energy loss and peak, the runs subsampled."""
    return {
        "momentum_drift_rel": max(r["momentum_drift_rel"] for r in runs.values()),
        "min_distance": float(np.nanmin([r["min_distance"] for r in runs.values()])),
        "energy_loss_pct": {k: r["energy_loss_pct"] for k, r in runs.items()},
        "energy_peak_over_start": {k: r["energy_peak_over_start"] for k, r in runs.items()},
        "penetrations": max(r["penetrations"] for r in runs.values()),
        "wall_s": sum(r["wall_s"] for r in runs.values()),
        "newton_iterations": sum(r["newton_iterations"] for r in runs.values()),
        "runs": {k: _for_json(r) for k, r in runs.items()},
    }


def plot(payload: dict, path: Path) -> None:
    """Figure 7 style: energies of each transfer over time (with the total energy of the
    ``compared_integrators`` runs), and the momentum drift."""

    def arrays(runs: dict) -> dict:
        return {
            k: {**r, "series": {s: np.asarray(v, dtype=float) for s, v in r["series"].items()}}
            for k, r in runs.items()
        }

    runs = arrays(payload["runs"])
    compared = {k: arrays(c["runs"]) for k, c in payload["compared_integrators"].items()}
    fig, axes = figure((8.0, 9.0), 3, 1, sharex=True, layout="constrained")
    for ax, (transfer, run) in zip(axes[:2], runs.items(), strict=True):
        s = run["series"]
        for key, style, label in (
            ("total", "k-", "total (kinetic + elastic)"),
            ("kinetic", "C0-", "kinetic"),
            ("elastic", "C1-", "elastic"),
            ("contact", "C2:", "barrier"),
        ):
            ax.plot(s["t"], s[key] / 1e6, style, label=label)
        for k, (integrator, by_transfer) in enumerate(compared.items()):
            other = by_transfer[transfer]
            loss = other["energy_loss_pct"]
            label = f"total, {integrator} (lost {loss:.2f} %)"
            series = other["series"]
            ax.plot(series["t"], series["total"] / 1e6, f"C{3 + k}--", label=label)
        ax.set_title(
            f"{transfer.upper()}: energy lost over the window {run['energy_loss_pct']:.2f} % "
            f"(paper {PAPER['energy_loss_pct'][transfer]:.2f} %)",
            fontsize="medium",
        )
        ax.set_ylabel("energy [MJ/m]")
    for transfer, run in runs.items():
        s = run["series"]
        axes[2].semilogy(s["t"], np.maximum(s["drift"], 1e-18), label=transfer.upper())
    axes[2].set_ylabel("|P(t) - P(0)| / sum |P_body(0)|")
    axes[2].set_title("total linear momentum drift", fontsize="medium")
    axes[2].set_xlabel("t [s]")
    for ax, run in zip(axes, (*runs.values(), None), strict=True):
        ax.axvspan(*WINDOW, color="0.85", zorder=0, label="paper's collision window")
        window = None if run is None else run["contact_window_s"]
        for k, edge in enumerate(window or ()):
            label = "first / last step with contact" if k == 0 else None
            ax.axvline(edge, color="0.3", ls="--", lw=0.8, label=label)
    save(fig, path, axes, f"Colliding rings, MPM (left) vs FEM (right), {payload['mode']} mode")


def _arguments(group: argparse._ActionsContainer) -> None:
    """``--no-compare``: skip ``COMPARED_INTEGRATORS`` (the two transfers alone, half the time)."""
    group.add_argument(
        "--no-compare",
        dest="compare",
        action="store_false",
        help="run the two transfers only, without the compared integrators",
    )


def measure(mode: str, cfg: dict, compare: bool = True) -> dict:
    """Both transfers in ``mode``: ``"full"`` (paper resolution), ``"partial"`` (paper dt and
    FEM mesh, MPM grid 2x coarser) or ``"quick"`` (coarse, < 60 s); with ``compare``, in
    partial and full modes, also ``COMPARED_INTEGRATORS`` (doubles the time)."""
    runs = {transfer: run_transfer(cfg, transfer) for transfer in TRANSFERS}
    compared = {}
    if compare and mode != "quick":  # the paper's literal mid-point Newmark (see the docstring)
        compared = {
            name: {t: run_transfer({**cfg, "integrator": name}, t) for t in TRANSFERS}
            for name in COMPARED_INTEGRATORS
        }
    first = runs["apic"]
    payload = {
        **_summary(runs),
        "steps": first["steps"],
        "steps_total": sum(r["steps"] for r in runs.values()),
        # seconds per step phase summed over both transfers (each run's own under runs.*)
        "phase_s": {
            phase: sum(r["phase_s"].get(phase, 0.0) for r in runs.values())
            for phase in sorted({p for r in runs.values() for p in r["phase_s"]})
        },
        "paper": PAPER,
        "targets": {
            "momentum_drift_rel": "< 1e-9",
            "min_distance": "> 0 at every step",
            "energy_loss_pct": "within 2 percentage points of the paper (full mode)",
        },
        "parameters": {
            **cfg,
            "r_inner_m": R_INNER,
            "r_outer_m": R_OUTER,
            "gap_m": GAP,
            "speed_m_s": SPEED,
            "material": {"model": "NeoHookean", **MATERIAL},
            "dhat_m": DHAT,
            "kappa_Pa": KAPPA,
            "mu": 0.0,
            "gravity": 0.0,
            "integrator": INTEGRATOR,
            "tol_m_s": TOL,
            "energy_window_s": list(WINDOW),
            "grid_origin_m": list(rings_grid_origin(cfg)),
            "particles": first["particles"],
            "fem_vertices": first["fem_vertices"],
            "fem_triangles": first["fem_triangles"],
        },
    }
    payload["compared_integrators"] = {
        name: {
            **_summary(by_transfer),
            "diagnostics": {k: r["diagnostics"] for k, r in by_transfer.items()},
        }
        for name, by_transfer in compared.items()
    }
    payload["wall_s"] += sum(c["wall_s"] for c in payload["compared_integrators"].values())
    log_row(log, NAME, payload, "momentum_drift_rel min_distance energy_loss_pct")
    return payload


BENCHMARK = register(Benchmark(NAME, __doc__, MODES, measure, plot=plot, arguments=_arguments))
run = BENCHMARK.run
