"""``lr_scenes``: the BFEMP scenes where ``lr`` applies, beside ``barrier`` (and ``two_stage``).

Issue 15 asks for the BFEMP scenes under LR "where they apply": momentum, penetration, energy and
wall time beside barrier's, in one run.

- rings, FEM ring as a material (``benchmarks.rings`` scene, ``two_stage_rings``' quick or
  partial discretisation): lr takes the FEM ring through its boundary nodes and facet samples
  (EXPLICIT_STRATEGIES.md 2.6), which asks for a grid spacing of at least twice the FEM
  boundary edge, so the FEM ring is meshed at h = dx / 2 for lr (barrier keeps its own mesh);
  frictionless, FLIP, ``dt="auto"``.
- rings, both rings as MPM bodies: the FEM ring sampled as particles like the MPM ring (the
  multimaterial setting LR was written for).
- slope (``two_stage_slope``'s softened scene, E = 1e5 Pa, dt = 5e-5 s): the fixed FEM slope as
  a kinematic material (all its nodes are scripted), meshed at h = dx / 2 and 1 cm thick for
  lr (``LR_SLOPE``), mu = 0 and 0.2 = tan theta; the acceleration error against
  g (sin theta - mu cos theta) beside two_stage's (on its own slope).

Recorded per run: momentum drift (free rings), particles inside the FEM ring at any step
(``rings._PenetrationCheck``; FEM-ring-as-material runs only), energy loss over the paper's
window where the run reaches it, wall time. No (T) target of its own; the test asserts the
momentum drift of the free MPM rings < 1e-10 (two-material corrections conserve momentum).
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

import bfemp
from benchmarks import rings, two_stage_rings, two_stage_slope
from benchmarks.common import environment, peak_memory_mb, write_json
from benchmarks.runner import Benchmark, register
from bfemp.steppers.lr import LROptions

log = logging.getLogger(__name__)

NAME = "lr_scenes"
#: lr sees the FEM slope through its boundary nodes, so the slope is meshed at half a grid cell
#: (``slope.VARIANTS["dense_slope"]``) and made 1 cm thick instead of 0.5 m (its elastic cells,
#: all scripted, are only a cost); measured with the default 1 m mesh, 18 contact nodes under
#: the 0.1 m box and the box sank through the slope
LR_SLOPE = ((-0.8, -0.01), (0.2, 0.0))

MODES = {
    "quick": {"rings": "quick", "slope": "quick"},
    "full": {"rings": "partial", "slope": "partial"},
    # what tests/benchmarks/test_lr_scenes.py runs
    "smoke": {"rings": "quick", "slope": None, "t_end": 0.05},
}


def _mpm_rings_scene(cfg: dict) -> bfemp.Scene:
    """Both rings as MPM bodies (the FEM ring of ``rings._scene`` sampled like the MPM one)."""
    scene = bfemp.Scene(dim=2)
    material = bfemp.NeoHookean(**rings.MATERIAL)
    centre = rings.R_OUTER + 0.5 * rings.GAP
    for name, sign in (("left_ring", -1.0), ("right_ring", 1.0)):
        shape = bfemp.shapes.ring(
            (sign * centre, 0.0), rings.R_INNER, rings.R_OUTER, h=0.25 * cfg["dx"]
        )
        x, vol = bfemp.sample.mesh(shape, dx=cfg["dx"], ppc=cfg["ppc"])
        velocity = (-sign * rings.SPEED, 0.0)
        scene.add_mpm(x, vol, material=material, velocity=velocity, name=name)
    scene.set_grid(dx=cfg["dx"], origin=rings._grid_origin(cfg))
    return scene


def _run_mpm_rings(cfg: dict) -> dict:
    sim = bfemp.Simulation(_mpm_rings_scene(cfg), strategy="lr", dt="auto",
                           options=LROptions(law="frictionless"))  # fmt: skip
    started, error = time.perf_counter(), None
    try:
        sim.run(t_end=cfg["t_end"], progress=False)
    except bfemp.StepError as err:
        error = str(err)
    wall = time.perf_counter() - started
    m, model = sim.metrics, sim.model
    t = m.column("t")
    momentum = np.stack([m.column("momentum_x"), m.column("momentum_y")], axis=1)
    scale = float(np.abs(model.mpm_mass[:, None] * model.mpm_v0).sum())
    energy = m.column("energy_kinetic") + m.column("energy_elastic")
    e0, e1 = rings._window_energies(t, energy)
    reached = t[-1] >= rings.WINDOW[1] - 1e-9
    # closest approach of the two rings' particles at the end (a crude overlap measure)
    x = sim.state.mpm_x
    left = model.mpm_particle_body == 0
    from scipy.spatial import cKDTree

    gap = float(cKDTree(x[~left]).query(x[left])[0].min())
    return {
        "error": error,
        "dt_s": sim.dt,
        "steps": int(len(t) - 1),
        "wall_s": wall,
        "particles": int(model.n_particles),
        "momentum_drift_rel": float(np.linalg.norm(momentum - momentum[0], axis=1).max() / scale),
        "closest_particles_end_m": gap,
        "energy_loss_pct": 100.0 * (e0 - e1) / e0 if reached else None,
    }


def _rings(mode: str) -> dict:
    cfg = dict(two_stage_rings.MODES[MODES[mode]["rings"]])
    if "t_end" in MODES[mode]:
        cfg["t_end"] = MODES[mode]["t_end"]
    lr_cfg = {**cfg, "fem_h": 0.5 * cfg["dx"]}
    options = LROptions(law="frictionless")
    out = {
        "lr_fem_material": two_stage_rings._run_one(lr_cfg, "flip", strategy="lr", options=options),
        "lr_mpm_rings": _run_mpm_rings(cfg),
    }
    barrier_cfg = {**rings.MODES["quick" if MODES[mode]["rings"] == "quick" else "partial"]}
    barrier_cfg["t_end"] = cfg["t_end"]
    started = time.perf_counter()
    out["barrier"] = rings._run_one(barrier_cfg, "flip")
    out["barrier"]["wall_s"] = time.perf_counter() - started
    out["barrier"]["dt_s"] = barrier_cfg["dt"]
    for name, r in out.items():
        log.info("rings %s: drift %.2e, %.1f s", name, r["momentum_drift_rel"], r["wall_s"])
    strip = {k: {kk: vv for kk, vv in v.items() if kk != "series"} for k, v in out.items()}
    return {"discretisation": cfg, "lr_fem_h": lr_cfg["fem_h"], "runs": strip}


def _slope(mode: str) -> dict | None:
    slope_mode = MODES[mode]["slope"]
    if slope_mode is None:
        return None
    physics = {
        "strategy": "lr",
        "options": LROptions(),
        "transfer": "flip",
        "slope_lower_upper_m": LR_SLOPE,
    }
    out = {}
    for name, p, variant in (("lr", physics, "dense_slope"), ("two_stage", None, "tilted_gravity")):
        started = time.perf_counter()
        res = two_stage_slope.run_cases(slope_mode, "kappa_paper", p, variant=variant)
        keys = ("mu", "accel", "accel_analytic", "accel_rel_error", "max_speed_after_fit_start",
                "error", "steps", "wall_s")  # fmt: skip
        out[name] = {
            "wall_s": time.perf_counter() - started,
            "cases": [{k: c.get(k) for k in keys} for c in res["cases"]],
        }
    return {"mode": slope_mode, "runs": out}


def run(mode: str = "full", out: str | Path = "results") -> dict:
    """Run ``mode``; write ``lr_scenes[_MODE].json``."""
    if mode not in MODES:
        raise ValueError(f"lr_scenes mode must be one of {sorted(MODES)}, got {mode!r}")
    started = time.perf_counter()
    payload = {
        "benchmark": NAME,
        "mode": mode,
        "rings": _rings(mode),
        "slope": _slope(mode),
        "wall_s": time.perf_counter() - started,
        "peak_memory_mb": peak_memory_mb(),
        "environment": environment(),
    }
    mpm = payload["rings"]["runs"]["lr_mpm_rings"]
    payload["lr_mpm_rings_drift_below_1e-10"] = bool(mpm["momentum_drift_rel"] < 1e-10)
    name = NAME if mode == "full" else f"{NAME}_{mode}"
    path = write_json(out, name, payload)
    return {"json": str(path), **payload}


BENCHMARK = register(Benchmark(NAME, __doc__, MODES, None, own_run=run))
