"""``explicit_speed``: cost of an ``augury`` and a ``two_stage`` step against a ``barrier`` step
on the same 2D scene (issues 14 and 16).

Scene (ours): two soft Neo-Hookean squares (0.2 m, E 1e5 Pa, nu 0.3, rho 1000) meeting head-on
at 1 m/s each, vertically offset by 0.05 m, mesh h in {0.05, 0.025} (quick) or down to 0.00625
(full); barrier contact d-hat 2e-3 m, kappa 1e5 Pa. Each strategy runs to t_end = 0.1 s at its
own usable step: augury and two_stage at ``dt="auto"`` (the explicit stable step; augury tau =
dt, N = 1), barrier at dt = 5e-3 s (implicit, backward Euler; what the bfemp examples take for
scenes of this size).

Recorded per run: steps, wall time per step, the per-step split of an explicit strategy into
mechanics (the engine's free-motion step) and contact (augury: stencils, normals and H
applications, the interpenetration check off; two_stage: the contact minimisation and its
set-up, with its Newton iterations per contact step), foreground particle-steps per second
(augury), the wall time per simulated second and its ratio barrier / strategy, and the final
relative speed and momentum drift of each.

Targets: the augury contact part costs less than its mechanics part (issue 14); two_stage's
Newton iterations per step (issue 16 expects 1-3) and its time to the same simulated time
against barrier are recorded.
"""

from __future__ import annotations

import logging
import time

import numpy as np

import bfemp
from benchmarks.runner import Benchmark, register
from bfemp import diagnostics
from bfemp.steppers.augury import AuguryOptions

log = logging.getLogger(__name__)

NAME = "explicit_speed"
EXPLICIT = ("augury", "two_stage")
MODES = {
    "quick": (0.05, 0.025),
    "full": (0.05, 0.025, 0.0125, 0.00625),
    "smoke": (0.05,),  # what tests/benchmarks/test_explicit_speed.py runs
}
T_END = 0.1
BARRIER_DT = 5e-3
MAT = dict(E=1e5, nu=0.3, density=1000.0)


def scene(h: float) -> bfemp.Scene:
    """The two squares (module docstring) at mesh size ``h`` m."""
    mat = bfemp.NeoHookean(**MAT)
    s = bfemp.Scene(dim=2)
    s.add_fem(bfemp.shapes.rectangle((0, 0), (0.2, 0.2), h=h), material=mat, velocity=(1.0, 0))
    s.add_fem(
        bfemp.shapes.rectangle((0.22, 0.05), (0.42, 0.25), h=h), material=mat, velocity=(-1.0, 0)
    )
    s.set_contact(dhat=2e-3, kappa=1e5)
    return s


def _relative_speed(sim: bfemp.Simulation) -> float:
    m, (a, b) = sim.model.fem_mass, sim.model.fem_bodies
    va = m[a.nodes] @ sim.state.fem_v[a.nodes] / m[a.nodes].sum()
    vb = m[b.nodes] @ sim.state.fem_v[b.nodes] / m[b.nodes].sum()
    return float(vb[0] - va[0])


def run_strategy(h: float, strategy: str) -> dict:
    """One run to ``T_END``; wall time and its split."""
    options = AuguryOptions(penetration_check_every=0) if strategy == "augury" else None
    dt = "auto" if strategy in EXPLICIT else BARRIER_DT
    sim = bfemp.Simulation(scene(h), strategy=strategy, options=options, dt=dt)
    p0 = diagnostics.linear_momentum(sim.model, sim.state)
    steps = int(np.ceil(T_END / sim.dt - 1e-9))
    mech = contact = 0.0
    newton = contact_steps = 0
    started = time.perf_counter()
    for _ in range(steps):
        report = sim.step()
        tm = report.timings
        if strategy == "augury":
            contact += tm.get("augury_H", 0.0) + tm.get("augury_stencils", 0.0)
            mech += tm["step"] - tm["augury"]
        elif strategy == "two_stage":
            solve = tm.get("contact", 0.0)
            contact += solve
            mech += tm["step"] - solve
            if report.contact_pairs:
                contact_steps += 1
                newton += int(report.iterations.get("newton", 0))
    wall = time.perf_counter() - started
    out = {
        "h": h,
        "strategy": strategy,
        "dt": sim.dt,
        "steps": steps,
        "wall_s": wall,
        "s_per_step": wall / steps,
        "wall_per_simulated_s": wall / (steps * sim.dt),
        "relative_speed_end": _relative_speed(sim),
        "momentum_drift": float(
            np.abs(diagnostics.linear_momentum(sim.model, sim.state) - p0).max()
        ),
        "nodes": sim.model.n_fem_nodes,
    }
    if strategy in EXPLICIT:
        out |= {
            "mechanics_s_per_step": mech / steps,
            "contact_s_per_step": contact / steps,
            "contact_below_mechanics": contact < mech,
        }
    if strategy == "augury":
        n_fg = int(sim.stepper.fem_foreground.size)
        out |= {"foreground": n_fg, "foreground_particle_steps_per_s": n_fg * steps / wall}
    if strategy == "two_stage":
        out |= {
            "contact_steps": contact_steps,
            "newton_per_contact_step": newton / contact_steps if contact_steps else 0.0,
        }
    return out


def measure(mode: str, cfg) -> dict:
    """Every strategy at every h of ``mode``."""
    rows = []
    for strategy in (*EXPLICIT, "barrier"):  # warm-up: first calls and numba loading not timed
        run_strategy(MODES[mode][0], strategy)
    for h in MODES[mode]:
        row = {"h": h} | {s: run_strategy(h, s) for s in (*EXPLICIT, "barrier")}
        for s in EXPLICIT:
            row[f"barrier_over_{s}_wall_per_simulated_s"] = (
                row["barrier"]["wall_per_simulated_s"] / row[s]["wall_per_simulated_s"]
            )
            per_step = row["barrier"]["s_per_step"] / row[s]["s_per_step"]
            row[f"barrier_over_{s}_s_per_step"] = per_step
        rows.append(row)
        log.info(
            "explicit_speed h=%g: augury %.3g s/step, two_stage %.3g s/step, barrier %.3g s/step",
            h,
            row["augury"]["s_per_step"],
            row["two_stage"]["s_per_step"],
            row["barrier"]["s_per_step"],
        )
    payload = {
        "rows": rows,
        "target": "augury contact part < mechanics part per step",
        "target_met": all(r["augury"]["contact_below_mechanics"] for r in rows),
        "two_stage_newton_per_contact_step": [
            r["two_stage"]["newton_per_contact_step"] for r in rows
        ],
        "parameters": {
            **MAT,
            "t_end_s": T_END,
            "barrier_dt_s": BARRIER_DT,
            "explicit_dt": "auto (explicit stable step)",
            "dhat_m": 2e-3,
            "kappa_Pa": 1e5,
        },
    }
    return payload


BENCHMARK = register(
    Benchmark(
        NAME, __doc__, MODES, measure, timings=r"s_per_step|per_simulated_s|contact_below_mech"
    )
)
run = BENCHMARK.run
