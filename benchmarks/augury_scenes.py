"""``augury_scenes``: the BFEMP scenes where augury applies, beside ``two_stage`` and ``barrier``.

Issue 14: ``rings`` with the MPM ring taking part through MPM foreground particles (bfemp's
extension, EXPLICIT_STRATEGIES.md 1.4), and ``slope`` with the softened material at the
explicit stable step; momentum, closest approach, energy and wall time recorded beside the
other strategies' numbers on the same discretisation, in one run.

- rings (``benchmarks.rings`` scene, the discretisation of ``two_stage_rings``; quick: dx = 1/3
  m, ppc 4, 0.15 s; full: the partial discretisation, dx = 0.2 m, the paper's FEM mesh, 0.3 s):
  augury (APIC contact operator, N = 1, "separate" mode as the rings are frictionless, contact
  grid 2 x the FEM boundary edge by default) and two_stage at ``dt="auto"``; barrier
  (``rings._run_one``, its integrator and dt) beside them. Recorded: momentum drift, closest
  distance (barrier, two_stage; augury has no barrier distance, NaN), particles inside the FEM
  ring at any step (``rings._PenetrationCheck``; augury admits some, AUG section 2.3), energy
  loss over the paper's window where the run reaches it, wall time.
- slope (``two_stage_slope``'s softened scene, E = 1e5 Pa, kappa 1e6 Pa, dt 5e-5 s): augury
  with the fixed FEM slope as kinematic foreground (``kinematic_foreground=True``: without it
  the box falls through the slope, whose nodes are all scripted), mu = 0 and 0.2 = tan theta;
  the acceleration error against g (sin theta - mu cos theta) and the speed after the fit start,
  beside two_stage's.

No (T) target of its own: the numbers stand beside barrier's and two_stage's. The test asserts
what augury guarantees here: momentum drift of the free rings < 1e-10 (APIC conserves it).
"""

from __future__ import annotations

import logging
import math
import time
from pathlib import Path

from benchmarks import rings, two_stage_rings, two_stage_slope
from benchmarks.common import environment, peak_memory_mb, write_json
from benchmarks.runner import Benchmark, register
from bfemp.steppers.augury import AuguryOptions

log = logging.getLogger(__name__)

NAME = "augury_scenes"

MODES = {
    "quick": {"rings": "quick", "slope": "quick"},
    "full": {"rings": "partial", "slope": "partial"},
    # what tests/benchmarks/test_augury_scenes.py runs: the quick rings to 0.05 s, no slope
    "smoke": {"rings": "quick", "slope": None, "t_end": 0.05},
}


def _strip(run: dict) -> dict:
    return {k: v for k, v in run.items() if k != "series"}


def _rings(mode: str) -> dict:
    cfg = dict(two_stage_rings.MODES[MODES[mode]["rings"]])
    if "t_end" in MODES[mode]:
        cfg["t_end"] = MODES[mode]["t_end"]
    options = AuguryOptions(mode="separate", penetration_check_every=0)
    out = {
        "augury": two_stage_rings._run_one(cfg, "apic", strategy="augury", options=options),
        "two_stage": two_stage_rings._run_one(cfg, "apic"),
    }
    barrier_cfg = {**rings.MODES["quick" if MODES[mode]["rings"] == "quick" else "partial"]}
    barrier_cfg["t_end"] = cfg["t_end"]
    started = time.perf_counter()
    out["barrier"] = rings._run_one(barrier_cfg, "apic")
    out["barrier"]["wall_s"] = time.perf_counter() - started
    out["barrier"]["dt_s"] = barrier_cfg["dt"]
    for name, r in out.items():
        log.info(
            "rings %s: drift %.2e, closest %s m, %d inside, energy loss %s %%, %.1f s",
            name,
            r["momentum_drift_rel"],
            r["min_distance"],
            r["penetrations"],
            r["energy_loss_pct"],
            r["wall_s"],
        )
    return {"discretisation": cfg, "runs": {k: _strip(v) for k, v in out.items()}}


def _slope(mode: str) -> dict | None:
    slope_mode = MODES[mode]["slope"]
    if slope_mode is None:
        return None
    physics = {
        "strategy": "augury",
        "options": AuguryOptions(kinematic_foreground=True, penetration_check_every=0),
    }
    out = {}
    for name, p in (("augury", physics), ("two_stage", None)):
        started = time.perf_counter()
        res = two_stage_slope.run_cases(slope_mode, "kappa_paper", p)
        out[name] = {
            "wall_s": time.perf_counter() - started,
            "cases": [
                {
                    k: c.get(k)
                    for k in (
                        "mu",
                        "accel",
                        "accel_analytic",
                        "accel_rel_error",
                        "max_speed_after_fit_start",
                        "error",
                        "steps",
                        "wall_s",
                    )
                }
                for c in res["cases"]
            ],
        }
    return {"mode": slope_mode, "runs": out}


def run(mode: str = "full", out: str | Path = "results") -> dict:
    """Run ``mode``; write ``augury_scenes[_MODE].json``."""
    if mode not in MODES:
        raise ValueError(f"augury_scenes mode must be one of {sorted(MODES)}, got {mode!r}")
    started = time.perf_counter()
    payload = {
        "benchmark": NAME,
        "mode": mode,
        "rings": _rings(mode),
        "slope": _slope(mode),
        "paper_bfemp_energy_loss_pct": rings.PAPER["energy_loss_pct"],
        "wall_s": time.perf_counter() - started,
        "peak_memory_mb": peak_memory_mb(),
        "environment": environment(),
    }
    aug = payload["rings"]["runs"]["augury"]
    payload["augury_momentum_drift_below_1e-10"] = bool(aug["momentum_drift_rel"] < 1e-10)
    dist = aug.get("min_distance")
    payload["augury_min_distance"] = (
        None if dist is None or (isinstance(dist, float) and math.isnan(dist)) else dist
    )
    name = NAME if mode == "full" else f"{NAME}_{mode}"
    path = write_json(out, name, payload)
    return {"json": str(path), **payload}


BENCHMARK = register(Benchmark(NAME, __doc__, MODES, None, own_run=run))
