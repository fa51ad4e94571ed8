"""Speed knobs of the implicit step (issue 6): each measured on and off on the same scenes.

Knobs:

- ``friction_back_solve``: the friction loop of Algorithm 1 stops when the Newton increment under
  refreshed friction data is below the tolerance. On: that increment comes from a back-solve with
  the last factorisation (``BarrierOptions.friction_back_solve``, the default); off: from a full
  Newton iteration (assembly + factorisation). Scenes: an MPM block on a tilted FEM floor, sticking
  (mu = 0.5) and sliding (mu = 0.1), backward Euler, 0.3 s.
- ``warm_start``: Newton starts from the predicted x^{n+1} where no contact is active
  (``Simulation(warm_start=True)``) instead of x^n. Scenes: the rings demo (to 0.1 s: flight
  and impact; quick: 0.04 s) and the cantilever demo (1 s; quick: 0.2 s). Off by default: it
  does not pay (the JSON says how much).
- ``broad_phase_share``: the share of the step time spent in
  ``bfemp.contact.pairs.candidate_pairs`` (cProfile, rings demo from 0.02 s to 0.1 s; quick: to
  0.04 s), with a line search's trials sharing one broad phase (``BarrierTerm``).

For each run: Newton iterations, numeric factorisations, wall seconds (min of ``repeats`` runs;
the machine is shared) and a result (final positions) whose on/off difference is recorded, so the
knob's effect on the answer is visible too. Output: ``speed_knobs.json``.
"""

from __future__ import annotations

import cProfile
import logging
import pstats
from collections.abc import Callable

import numpy as np

import bfemp
from benchmarks._phases import timed
from benchmarks.runner import Benchmark, register
from bfemp.demo import cantilever_scene, colliding_rings_scene

log = logging.getLogger(__name__)

NAME = "speed_knobs"
MODES = {
    "full": {"repeats": 3, "t_block": 0.3, "t_rings": 0.1, "t_cantilever": 1.0},
    "quick": {"repeats": 1, "t_block": 0.05, "t_rings": 0.04, "t_cantilever": 0.2},
}


def block_on_floor(mu: float) -> bfemp.Scene:
    """A 0.3 x 0.1 m MPM block resting dhat-close on a fixed FEM floor, gravity tilted by 11.5
    deg (tan = 2 / 9.81): it sticks for mu = 0.5 and slides for mu = 0.1."""
    scene = bfemp.Scene(dim=2, gravity=(2.0, -9.81))
    mat = bfemp.NeoHookean(E=1e6, nu=0.3, density=1000.0)
    floor = bfemp.shapes.rectangle((-0.5, -0.2), (2.0, 0.0), h=0.1)
    scene.add_fem(floor, material=mat, prescribed=bfemp.motion.Fixed())
    x, vol = bfemp.sample.box((0.0, 0.0011), (0.3, 0.1011), dx=0.025, ppc=4)
    scene.add_mpm(x, vol, material=mat)
    scene.set_grid(dx=0.025)
    scene.set_contact(dhat=1e-3, kappa=1e4, mu=mu, eps_v=1e-4)
    return scene


def _measure(make: Callable[[], bfemp.Simulation], t_end: float, repeats: int) -> dict:
    """Run ``make()`` to ``t_end`` ``repeats`` times; iterations, factorisations, min wall."""
    walls = []
    for _ in range(repeats):
        sim = make()
        walls.append(timed(lambda sim=sim: sim.run(t_end, progress=False))[1])
    positions = np.concatenate([sim.state.fem_x.ravel(), sim.state.mpm_x.ravel()])
    return {
        "newton_iterations": int(np.nansum(sim.metrics.column("iterations_newton"))),
        "factorisations": int(sim.stepper.linear_solver.n_numeric),
        "wall_s": min(walls),
        "_positions": positions,
    }


def _on_off(make: Callable[[bool], bfemp.Simulation], t_end: float, repeats: int) -> dict:
    """``_measure`` of ``make(False)`` (knob off) and ``make(True)`` (on), and how far apart
    their final positions are (m)."""
    off, on = (_measure(lambda on=on: make(on), t_end, repeats) for on in (False, True))
    diff = float(np.abs(on.pop("_positions") - off.pop("_positions")).max())
    return {"off": off, "on": on, "max_position_difference_m": diff}


def _friction_back_solve(cfg: dict) -> dict:
    def block(mu: float, on: bool) -> bfemp.Simulation:
        options = bfemp.BarrierOptions(tol=1e-6, friction_back_solve=on)
        return bfemp.Simulation(block_on_floor(mu), dt=5e-3, options=options)

    return {
        label: _on_off(lambda on, mu=mu: block(mu, on), cfg["t_block"], cfg["repeats"])
        for label, mu in (("sticking_mu_0.5", 0.5), ("sliding_mu_0.1", 0.1))
    }


def _warm_start(cfg: dict) -> dict:
    scenes = {
        "rings_demo": (colliding_rings_scene, 2e-3, cfg["t_rings"]),
        "cantilever_demo": (cantilever_scene, 1e-2, cfg["t_cantilever"]),
    }
    return {
        label: _on_off(
            lambda on, scene=scene, dt=dt: bfemp.Simulation(
                scene(), integrator="newmark", dt=dt, tol=1e-6, warm_start=on
            ),
            t_end,
            cfg["repeats"],
        )
        for label, (scene, dt, t_end) in scenes.items()
    }


def _broad_phase_share(cfg: dict) -> dict:
    sim = bfemp.Simulation(colliding_rings_scene(), integrator="newmark", dt=2e-3, tol=1e-6)
    sim.run(0.02, progress=False)  # compile and reach the flight phase untimed
    profile = cProfile.Profile()
    profile.enable()
    sim.run(cfg["t_rings"], progress=False)
    profile.disable()
    stats = pstats.Stats(profile).stats
    total = max(v[3] for v in stats.values())
    broad = sum(v[3] for k, v in stats.items() if k[2] == "candidate_pairs")
    return {
        "step_time_s": float(total),
        "candidate_pairs_s": float(broad),
        "share": float(broad / total),
    }


def measure(mode: str, cfg: dict) -> dict:
    """Each knob of ``mode`` on and off."""
    return {
        "friction_back_solve": _friction_back_solve(cfg),
        "warm_start": _warm_start(cfg),
        "broad_phase_share": _broad_phase_share(cfg),
        "defaults": {"friction_back_solve": True, "warm_start": False},
        "parameters": cfg,
    }


BENCHMARK = register(Benchmark(NAME, __doc__, MODES, measure))
run = BENCHMARK.run
