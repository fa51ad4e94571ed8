"""The "dx gap" (TS notes): an MPM block at rest on a floor, three ways.

A soft Neo-Hookean MPM block (0.1 m x 0.04 m, E = 1e5 Pa, nu = 0.2, rho = 100 kg/m^2, particles
on a dx/2 lattice) is dropped from ``START_GAP`` = 0.025 m (beyond the grid's 1.5 dx reach of
the floor) onto a floor at y = 0 and comes to rest under g = 9.81 m/s^2 (symplectic Euler,
dt = "auto", PIC transfer for every case, which damps the bounce):

- ``two_stage``: the floor is a fixed FEM plate (mesh h = 0.05 m); barrier dhat = 1e-3 m,
  kappa = 1e4 Pa;
- ``levelset``: the floor is a slip half-plane level set under ``single_field`` (grid nodes at
  or below y = 0 lose their normal velocity);
- ``augury_pic``: the FEM plate under ``augury`` with the PIC contact transfer
  (``AuguryOptions(contact_transfer="pic", kinematic_foreground=True)``: without the kinematic
  foreground the scripted plate is not on the contact grid and the block falls through it); its
  contact grid spacing is AUG's default, 2 x the plate's mean boundary edge (0.1 m, recorded).

Metric: the gap, the lowest particle's height above y = 0, averaged over the last quarter of the
run (and its min / max there). Targets (T): two_stage's gap at rest lies in (0, dhat] (tail min
> 0) and below both grid treatments'.

Measured results, with the commits they ran on: ``benchmarks/records/two_stage_gap.md``.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

import bfemp
from benchmarks.common import figure, save
from benchmarks.runner import Benchmark, register
from bfemp.steppers.augury import AuguryOptions

log = logging.getLogger(__name__)

NAME = "two_stage_gap"
MATERIAL = dict(E=1e5, nu=0.2, density=100.0)
DHAT, KAPPA = 1e-3, 1e4
TRANSFER = "pic"  # MPM transfer of every case: PIC damps the bounce, so the block comes to rest
START_GAP = 0.025  # m: beyond the grid's reach of the floor (1.5 dx) in both modes
MODES = {"quick": dict(dx=0.01, t_end=0.3), "full": dict(dx=0.005, t_end=0.6)}
CASES = ("two_stage", "levelset", "augury_pic")


def _scene(case: str, dx: float) -> bfemp.Scene:
    scene = bfemp.Scene(dim=2, gravity=(0.0, -9.81))
    mat = bfemp.NeoHookean(**MATERIAL)
    if case == "levelset":
        floor = bfemp.levelset.HalfPlane(point=(0.0, 0.0), normal=(0.0, 1.0))
        scene.add_boundary(floor, kind="slip")
    else:
        plate = bfemp.shapes.rectangle((-0.2, -0.05), (0.2, 0.0), h=0.05)
        fixed = bfemp.motion.Fixed()
        scene.add_fem(plate.points, plate.cells, material=mat, prescribed=fixed, name="plate")
    spacing = dx / 2
    xs, ys = np.meshgrid(
        np.linspace(-0.05, 0.05, round(0.1 / spacing) + 1),
        np.linspace(0.0, 0.04, round(0.04 / spacing) + 1),
    )
    pts = np.stack([xs.ravel(), ys.ravel() + START_GAP], axis=1)
    scene.add_mpm(pts, np.full(len(pts), 0.1 * 0.04 / len(pts)), material=mat, name="block")
    scene.set_grid(dx=dx, origin=(dx / 8, dx / 8))
    scene.set_contact(dhat=DHAT, kappa=KAPPA, mu=0.0)
    return scene


def _run_case(case: str, cfg: dict) -> dict:
    strategy = {"two_stage": "two_stage", "levelset": "single_field", "augury_pic": "augury"}[case]
    options = None
    if case == "augury_pic":  # the fixed plate enters the contact grid with its (zero) velocity
        options = AuguryOptions(contact_transfer="pic", kinematic_foreground=True)
    sim = bfemp.Simulation(
        _scene(case, cfg["dx"]), strategy=strategy, dt="auto", options=options, transfer=TRANSFER
    )
    started, t, low, error = time.perf_counter(), [], [], None
    try:
        while sim.state.t < cfg["t_end"]:
            sim.step()
            t.append(sim.state.t)
            low.append(float(sim.state.mpm_x[:, 1].min()))
    except bfemp.StepError as err:
        error = str(err)
    t, low = np.array(t), np.array(low)
    tail = low[t >= 0.75 * cfg["t_end"]] if t.size else low
    return {
        "case": case,
        "strategy": strategy,
        "augury_contact_dx_m": getattr(sim.stepper, "grid_dx", None),
        "dt_s": sim.dt,
        "steps": int(t.size),
        "error": error,
        "gap_at_rest_m": float(tail.mean()) if tail.size else None,
        "gap_tail_min_m": float(tail.min()) if tail.size else None,
        "gap_tail_max_m": float(tail.max()) if tail.size else None,
        "gap_over_dx": float(tail.mean() / cfg["dx"]) if tail.size else None,
        "wall_s": time.perf_counter() - started,
        "series": {"t": t[::5].tolist(), "lowest_m": low[::5].tolist()},
    }


def measure(mode: str, cfg: dict) -> dict:
    """Run the three cases of ``mode``: the gaps at rest and the targets."""
    cases = {case: _run_case(case, cfg) for case in CASES}
    ts = cases["two_stage"]
    ok = ts["error"] is None and ts["gap_tail_min_m"] is not None
    targets = {
        "two_stage_gap_within_dhat": ok
        and 0.0 < ts["gap_tail_min_m"]
        and ts["gap_at_rest_m"] <= DHAT,
        "two_stage_gap_below_the_grid_treatments": ok
        and all(
            cases[c]["gap_at_rest_m"] is not None
            and ts["gap_at_rest_m"] < cases[c]["gap_at_rest_m"]
            for c in ("levelset", "augury_pic")
        ),
    }
    return {
        "dx_m": cfg["dx"],
        "dhat_m": DHAT,
        "gap_at_rest_m": {c: r["gap_at_rest_m"] for c, r in cases.items()},
        "gap_over_dx": {c: r["gap_over_dx"] for c, r in cases.items()},
        "targets": targets,
        "target_met": all(targets.values()),
        "cases": {c: {k: v for k, v in r.items() if k != "series"} for c, r in cases.items()},
        "parameters": {**cfg, "material": MATERIAL, "kappa_Pa": KAPPA, "start_gap_m": START_GAP},
        "series": {c: r["series"] for c, r in cases.items()},
    }


def plot(payload: dict, png: Path) -> None:
    """The lowest particle's height against time, per case, beside dhat and dx."""
    fig, ax = figure((6.0, 4.0), layout="tight")
    for c, series in payload["series"].items():
        ax.plot(series["t"], series["lowest_m"], label=c)
    ax.axhline(DHAT, color="k", ls=":", lw=0.8, label="dhat")
    ax.axhline(payload["dx_m"], color="k", ls="--", lw=0.8, label="dx")
    ax.set(xlabel="t (s)", ylabel="lowest particle height (m)")
    ax.set_title(f"block at rest on a floor ({payload['mode']})", fontsize=9)
    save(fig, png, [ax])


BENCHMARK = register(Benchmark(NAME, __doc__, MODES, measure, plot=plot))
run = BENCHMARK.run
