"""The BFEMP slope under ``two_stage``: static and sliding friction at the explicit stable step.

The ``slope`` scene (``benchmarks.slope``: MPM box 0.1 m x 0.02 m, 369 particles, dx = 0.005 m,
rho = 100 kg/m^2, nu = 0.2, on a fixed FEM slope with tan(theta) = 0.2, g = 5.10 m/s^2, dhat =
1e-3 m, eps_v = 1e-5 m/s; tilted gravity) with the material softened from E = 4e12 Pa to 1e5 Pa
(EXPLICIT_STRATEGIES.md 3.5: at 4e12 the explicit step would be ~1e-8 s) and kappa scaled alike
(1e6 Pa x 1e5 / 4e12 = 2.5e-2 Pa), both recorded. Symplectic Euler at ``DT`` = 5e-5 s, under the
explicit stable step of the initial state (0.4 dx / c_p = 6.0e-5 s, recorded). Settling: as in
``slope`` (frictionless, against the slope and the extra stop plane); release without the plane
at each mu, the centre of mass fitted with s0 + v0 t + a t^2 / 2 after ``fit_start_s``.

Targets (T): relative acceleration error against g (sin theta - mu cos theta) below 2e-3 (full)
and 2e-2 (quick); at mu = 0.2 = tan(theta) the box sticks: its speed stays of the order of eps_v
(max speed after the fit start below 10 eps_v). Quick: mu in (0, 0.2), 0.01 s settling,
0.06 s release (1,200 steps each), fit over [0.02, 0.06] s.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

from benchmarks import slope
from benchmarks.common import environment, peak_memory_mb, write_json
from bfemp.steppers.two_stage import TwoStageOptions, TwoStageStepper

log = logging.getLogger(__name__)

NAME = "two_stage_slope"

E_SOFT = 1e5  # Pa
DT = 5e-5  # s

PHYSICS = {
    **slope.PHYSICS,
    "E_Pa": E_SOFT,
    "kappa_Pa": slope.PHYSICS["kappa_Pa"] * E_SOFT / slope.PHYSICS["E_Pa"],
    "strategy": "two_stage",
    "integrator": "symplectic_euler",
    "dt_s": DT,
    "tol_m_s": 1e-6,
    "options": TwoStageOptions(tol=1e-6),
}
PHYSICS.pop("velocity_update")

MODES = {
    "full": {"settle_s": 0.1, "release_s": 0.5, "fit_start_s": 0.1, "mus": (0.0, 0.1, 0.1999, 0.2)},
    "quick": {"settle_s": 0.01, "release_s": 0.06, "fit_start_s": 0.02, "mus": (0.0, 0.2)},
}
TARGET_REL = {"full": 2e-3, "quick": 2e-2}
STICK_FACTOR = 10.0  # mu = 0.2: max speed after the fit start below this many eps_v


def stable_dt() -> float:
    """The explicit stable step (s) of the settling scene's initial state."""
    model = slope._scene("tilted_gravity", 0.0, with_stop=True, p=PHYSICS).build()
    return TwoStageStepper.auto_dt(model)


def run_cases(mode: str) -> dict:
    """Settle once, release at each mu of ``mode``; the settle record and the cases."""
    cfg = MODES[mode]
    settled, settle = slope._settle("tilted_gravity", round(cfg["settle_s"] / DT), PHYSICS)
    cases = []
    for mu in cfg["mus"]:
        case = slope._release(
            "tilted_gravity",
            mu,
            settled,
            round(cfg["release_s"] / DT),
            cfg["fit_start_s"],
            PHYSICS,
        )
        tau = np.array(case["series"]["tau_s"])
        v = np.abs(np.array(case["series"]["speed_along_m_s"]))
        after = v[tau >= cfg["fit_start_s"]]
        case["max_speed_after_fit_start"] = float(after.max()) if after.size else None
        log.info(
            "mu=%g: accel %.6g (analytic %.6g), speed after fit start <= %.3g m/s, %.1f s",
            mu,
            case["accel"],
            case["accel_analytic"],
            case["max_speed_after_fit_start"],
            case["wall_s"],
        )
        cases.append(case)
    return {"settle": settle, "cases": cases}


def run(mode: str = "full", out: str | Path = "results") -> dict:
    """Run ``mode`` (``"quick"`` or ``"full"``); write ``two_stage_slope.json`` and ``.png``."""
    if mode not in MODES:
        raise ValueError(f"mode must be one of {sorted(MODES)}, got {mode!r}")
    started = time.perf_counter()
    out = Path(out)
    results = run_cases(mode)
    cases = results["cases"]
    eps_v = PHYSICS["eps_v_m_s"]
    sliding = [c for c in cases if c["accel_rel_error"] is not None]
    sticking = [c for c in cases if c["mu"] >= PHYSICS["tan_theta"]]
    targets = {
        "accel_rel_error_below": TARGET_REL[mode],
        "accel_met": all(
            c["error"] is None and c["accel_rel_error"] < TARGET_REL[mode] for c in sliding
        ),
        "stick_max_speed_below_m_s": STICK_FACTOR * eps_v,
        "stick_met": all(
            c["error"] is None
            and c["max_speed_after_fit_start"] is not None
            and c["max_speed_after_fit_start"] < STICK_FACTOR * eps_v
            for c in sticking
        ),
    }
    payload = {
        "benchmark": NAME,
        "mode": mode,
        "cases": slope._strip(cases),
        "settle": results["settle"],
        "targets": targets,
        "target_met": targets["accel_met"] and targets["stick_met"],
        "failed_cases": [f"mu={c['mu']:g}: {c['error']}" for c in cases if c["error"]],
        "stable_dt_s": stable_dt(),
        "dt_s": DT,
        "steps": results["settle"]["steps"] + sum(c["steps"] for c in cases),
        "newton_iterations": results["settle"]["newton_iterations"]
        + sum(c["newton_iterations"] for c in cases),
        "wall_s": time.perf_counter() - started,
        "peak_memory_mb": peak_memory_mb(),
        "parameters": {
            **{k: v for k, v in PHYSICS.items() if k != "options"},
            "options": {"friction": "once", "tol_m_s": 1e-6, "start": "free"},
            "softened_from": {"E_Pa": slope.PHYSICS["E_Pa"], "kappa_Pa": slope.PHYSICS["kappa_Pa"]},
            **MODES[mode],
        },
        "environment": environment(),
        "series": {str(c["mu"]): c["series"] for c in cases},
    }
    path = write_json(out, NAME, payload)
    png = out / f"{NAME}.png"
    slope._plot(
        {"tilted_gravity": {"cases": cases}},
        png,
        f"two_stage: soft MPM box on a FEM slope, tan theta = 0.2 ({mode}, dt = {DT:g} s)",
    )
    return {"json": str(path), "png": str(png), **payload}
