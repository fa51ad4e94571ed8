"""``scenes``: the BFEMP rings and slope (``benchmarks.catalogue``) under an explicit strategy.

``python -m benchmarks scenes --strategy S [--scene rings|slope]``, or by the old names:

- ``augury_scenes`` (``--strategy augury``): rings with the MPM ring taking part through MPM
  foreground particles (APIC contact operator, N = 1, "separate" mode, contact grid 2 x the FEM
  boundary edge) and two_stage at ``dt="auto"``, barrier (``rings.run_transfer``) beside them;
  slope (the softened box below) with the fixed FEM slope as kinematic foreground, mu = 0 and
  0.2 = tan theta, beside two_stage. The record asserts APIC's momentum drift < 1e-10.
- ``lr_scenes`` (``--strategy lr``): rings with the FEM ring as a material meshed at h = dx / 2
  (lr sees it through its boundary nodes), both rings as MPM bodies (LR's multimaterial
  setting), barrier beside them (FLIP, frictionless); slope meshed at dx / 2 and 1 cm thick
  (``catalogue.LR_SLOPE``), beside two_stage.
- ``two_stage_rings`` (``--strategy two_stage --scene rings``): symplectic Euler at the explicit
  stable step; targets (T): momentum drift < 1e-9, closest distance > 0 at every step, no
  particle inside the FEM ring; energy loss over the paper's window (0.025-0.293 s) beside
  BFEMP's 8.57 % (APIC) / 9.67 % (FLIP).
- ``two_stage_slope`` (``--strategy two_stage --scene slope``): the slope box softened from
  E = 4e12 Pa to ``E_SOFT`` = 1e5 Pa (explicit_strategies.md 3.5: at 4e12 the explicit step
  would be ~1e-8 s) at ``DT`` = 5e-5 s, two barrier stiffnesses (``KAPPAS``: scaled alike,
  2.5e-2 Pa, and the paper's 1e6 Pa); settling as in ``slope``, release at each mu, centre of
  mass fitted after ``fit_start_s``. Targets (T): relative acceleration error against
  g (sin theta - mu cos theta) below ``TARGET_REL``; at mu = tan(theta) the speed after the fit
  start below ``STICK_FACTOR`` eps_v. ``two_stage_slope_sticking`` (``sticking``) tests 1.05 and
  1.5 tan(theta) from rest and records Newton iterations against eps_v.

Measured results are in ``benchmarks/records/`` (``two_stage_rings.md``,
``two_stage_slope.md``, ``two_stage_slope_sticking.md`` and the JSON records).
"""

from __future__ import annotations

import argparse
import logging
import time
from collections.abc import Mapping
from pathlib import Path

import numpy as np

import bfemp
from benchmarks import catalogue as cat
from benchmarks import rings, slope
from benchmarks.common import figure, log_row, save
from benchmarks.runner import Benchmark, register
from bfemp.steppers.augury import AuguryOptions
from bfemp.steppers.lr import LROptions
from bfemp.steppers.two_stage import TwoStageOptions, TwoStageStepper

log = logging.getLogger(__name__)

NAME = "scenes"
#: (strategy, scene) -> the record's name (the benchmark names before the merge)
RECORD_NAMES = {
    ("augury", "both"): "augury_scenes",
    ("lr", "both"): "lr_scenes",
    ("two_stage", "rings"): "two_stage_rings",
    ("two_stage", "slope"): "two_stage_slope",
}

#: the rings' discretisations (two_stage's quick runs to 0.15 s, in contact from 0.025 s)
RINGS_MODES = {
    m: {**cat.RINGS_DISCRETISATION[m], "t_end": 0.3, "transfers": ("apic", "flip")}
    for m in ("full", "partial")
} | {"quick": {**cat.RINGS_DISCRETISATION["quick"], "t_end": 0.15, "transfers": ("apic",)}}
DRIFT_TARGET = 1e-9
#: what the comparisons (augury, lr) run per mode: the rings' and the slope's modes
COMPARE_MODES = {
    "quick": {"rings": "quick", "slope": "quick"},
    "full": {"rings": "partial", "slope": "partial"},
    # what the tests run: the quick rings to 0.05 s, no slope
    "smoke": {"rings": "quick", "slope": None, "t_end": 0.05},
}

# ----------------------------------------------------------------------------- softened slope
E_SOFT = 1e5  # Pa
DT = 5e-5  # s
PHYSICS = {
    **cat.SLOPE_PHYSICS,
    "E_Pa": E_SOFT,
    "kappa_Pa": cat.SLOPE_PHYSICS["kappa_Pa"] * E_SOFT / cat.SLOPE_PHYSICS["E_Pa"],
    "strategy": "two_stage",
    "integrator": "symplectic_euler",
    "dt_s": DT,
    "tol_m_s": 1e-6,
    # Newton from x* as recorded (issue 40 made "auto" the default: x^n under friction)
    "options": TwoStageOptions(tol=1e-6, start="free"),
}
PHYSICS.pop("velocity_update")
KAPPAS = {"kappa_scaled": PHYSICS["kappa_Pa"], "kappa_paper": cat.SLOPE_PHYSICS["kappa_Pa"]}
_ALL_MUS = (0.0, 0.1, 0.1999, 0.2)
SLOPE_MODES = {
    "full": dict(
        settle_s=0.1,
        release_s=0.5,
        fit_start_s=0.1,
        mus=_ALL_MUS,
        kappas=("kappa_scaled", "kappa_paper"),
    ),
    # what the 2-core machine ran (full: 84,000 steps at ~24 ms, over half an hour)
    "partial": dict(**cat.SLOPE_TIMES["partial"], mus=_ALL_MUS, kappas=("kappa_paper",)),
    "quick": dict(**cat.SLOPE_TIMES["quick"], mus=(0.0, 0.2), kappas=("kappa_paper",)),
}
TARGET_REL = {"full": 2e-3, "partial": 2e-3, "quick": 2e-2}
STICK_FACTOR = 10.0  # mu = 0.2: max speed after the fit start below this many eps_v
_SLOPE_KEYS = (
    "mu",
    "accel",
    "accel_analytic",
    "accel_rel_error",
    "max_speed_after_fit_start",
    "error",
    "steps",
    "wall_s",
)


def _strip(run: Mapping) -> dict:
    return {k: v for k, v in run.items() if k != "series"}


# ----------------------------------------------------------------------------- rings
def _run_rings(sim: bfemp.Simulation, t_end: float, callback: object = None) -> tuple:
    """Run ``sim`` to ``t_end`` s: ``(common, t, energy)``: ``common`` the record entries every
    rings run has (its ``StepError`` message or None, dt and steps, wall time, particles, energy
    loss (%) over the paper's window when reached), ``t (n,)`` s and the kinetic plus elastic
    energy ``(n,)`` J/m of every step."""
    error, wall = rings.collide(sim, t_end, callback)
    m = sim.metrics
    t = m.column("t")
    energy = m.column("energy_kinetic") + m.column("energy_elastic")
    e0, e1 = cat.window_energies(t, energy)
    reached = t[-1] >= cat.WINDOW[1] - 1e-9
    common = {
        "error": error,
        "dt_s": sim.dt,
        "steps": int(len(t) - 1),
        "wall_s": wall,
        "particles": int(sim.model.n_particles),
        "energy_loss_pct": 100.0 * (e0 - e1) / e0 if reached else None,
    }
    return common, t, energy


def run_rings(
    cfg: dict, transfer: str, strategy: str = "two_stage", options: object = None
) -> dict:
    """One run of the rings (``catalogue.rings_scene``) under an explicit ``strategy`` at
    ``dt="auto"`` to ``cfg["t_end"]`` s: momentum drift, closest distance (m), particles inside
    the FEM ring, energy loss (%) over the paper's window when reached, Newton iterations."""
    sim = bfemp.Simulation(
        cat.rings_scene(cfg), strategy=strategy, transfer=transfer, dt="auto", options=options
    )
    model = sim.model
    check = cat.RingsPenetration(sim)
    common, t, energy = _run_rings(sim, cfg["t_end"], check)
    m = sim.metrics
    scale = float(
        np.linalg.norm(model.fem_mass @ model.fem_v0)
        + np.linalg.norm(model.mpm_mass @ model.mpm_v0)
    )
    dist = m.column("min_distance")[1:]
    pairs = m.column("contact_pairs")[1:]
    iters = (
        m.column("iterations_newton")[1:]
        if "iterations_newton" in m.columns
        else np.zeros(len(t) - 1)  # a strategy without Newton (augury)
    )
    return {
        "transfer": transfer,
        **common,
        "fem_vertices": int(model.n_fem_nodes),
        "momentum_drift_rel": float(rings.momentum_drift(m, scale).max()),
        "min_distance": float(np.nanmin(dist)) if np.isfinite(dist).any() else None,
        "contact_steps": int(np.count_nonzero(pairs > 0)),
        "penetrations": int(check.worst),
        "newton_iterations": int(np.nansum(iters)),
        "newton_per_contact_step": float(np.nanmean(iters[pairs > 0])) if (pairs > 0).any() else 0,
        "newton_iterations_max": int(np.nanmax(iters)) if iters.size else 0,
        "series": {"t": t[::10].tolist(), "total": energy[::10].tolist()},
    }


def _run_mpm_rings(cfg: dict) -> dict:
    """Both rings as MPM bodies under lr (frictionless, ``dt="auto"``)."""
    from scipy.spatial import cKDTree

    sim = bfemp.Simulation(
        cat.mpm_rings_scene(cfg), strategy="lr", dt="auto", options=LROptions(law="frictionless")
    )
    common, _, _ = _run_rings(sim, cfg["t_end"])
    model, x = sim.model, sim.state.mpm_x
    scale = float(np.abs(model.mpm_mass[:, None] * model.mpm_v0).sum())
    # closest approach of the two rings' particles at the end (a crude overlap measure)
    left = model.mpm_particle_body == 0
    gap = float(cKDTree(x[~left]).query(x[left])[0].min())
    return {
        **common,
        "momentum_drift_rel": float(rings.momentum_drift(sim.metrics, scale).max()),
        "closest_particles_end_m": gap,
    }


def _compared_rings(mode: str, strategy: str) -> dict:
    """The rings under ``strategy`` (augury or lr) beside barrier (and two_stage)."""
    cfg = dict(RINGS_MODES[COMPARE_MODES[mode]["rings"]])
    if "t_end" in COMPARE_MODES[mode]:
        cfg["t_end"] = COMPARE_MODES[mode]["t_end"]
    if strategy == "augury":
        transfer, options = "apic", AuguryOptions(mode="separate", penetration_check_every=0)
        out = {
            "augury": run_rings(cfg, transfer, strategy="augury", options=options),
            "two_stage": run_rings(cfg, transfer),
        }
    else:
        transfer, lr_cfg = "flip", {**cfg, "fem_h": 0.5 * cfg["dx"]}
        out = {
            "lr_fem_material": run_rings(
                lr_cfg, transfer, strategy="lr", options=LROptions(law="frictionless")
            ),
            "lr_mpm_rings": _run_mpm_rings(cfg),
        }
    barrier_cfg = {**rings.MODES[COMPARE_MODES[mode]["rings"]], "t_end": cfg["t_end"]}
    out["barrier"] = {**rings.run_transfer(barrier_cfg, transfer), "dt_s": barrier_cfg["dt"]}
    for name, r in out.items():
        log.info("rings %s: drift %.2e, %.1f s", name, r["momentum_drift_rel"], r["wall_s"])
    found = {"discretisation": cfg}
    if strategy == "lr":
        found["lr_fem_h"] = 0.5 * cfg["dx"]
    return {**found, "runs": {k: _strip(v) for k, v in out.items()}}


def _two_stage_rings(mode: str) -> dict:
    cfg = RINGS_MODES[mode]
    runs = {tr: run_rings(cfg, tr) for tr in cfg["transfers"]}
    drift = max(r["momentum_drift_rel"] for r in runs.values())
    dists = [r["min_distance"] for r in runs.values() if r["min_distance"] is not None]
    targets = {
        "momentum_drift_below": DRIFT_TARGET,
        "momentum_met": drift < DRIFT_TARGET,
        "min_distance_positive": bool(dists) and min(dists) > 0.0,
        "no_penetration": all(r["penetrations"] == 0 and r["error"] is None for r in runs.values()),
    }
    met = all(targets[k] for k in ("momentum_met", "min_distance_positive", "no_penetration"))
    parameters = {
        **cfg,
        "strategy": "two_stage",
        "dt": "auto",
        "dhat": cat.DHAT,
        "kappa": cat.KAPPA,
        "material": cat.MATERIAL,
    }
    return {
        "momentum_drift_rel": drift,
        "min_distance": min(dists) if dists else None,
        "energy_loss_pct": {tr: r["energy_loss_pct"] for tr, r in runs.items()},
        "bfemp_energy_loss_pct": rings.PAPER["energy_loss_pct"],
        "targets": targets,
        "target_met": met,
        "runs": {tr: _strip(r) for tr, r in runs.items()},
        "parameters": parameters,
        "series": {tr: r["series"] for tr, r in runs.items()},
    }


def _plot_two_stage_rings(payload: dict, png: Path) -> None:
    fig, ax = figure((6.0, 4.0), layout="tight")
    for tr, series in payload["series"].items():
        ax.plot(series["t"], series["total"], label=f"two_stage {tr}")
    ax.set(xlabel="t (s)", ylabel="kinetic + elastic energy (J/m)")
    title = f"rings under two_stage ({payload['mode']}); drift {payload['momentum_drift_rel']:.1e}"
    ax.set_title(title, fontsize=9)
    save(fig, png, [ax], legend="medium")


# ----------------------------------------------------------------------------- slope
def stable_dt() -> float:
    """The explicit stable step (s) of the softened settling scene's initial state."""
    model = cat.slope_scene("tilted_gravity", 0.0, with_stop=True, p=PHYSICS).build()
    return TwoStageStepper.auto_dt(model)


def run_cases(
    mode: str, kappa: str, physics: dict | None = None, variant: str = "tilted_gravity"
) -> dict:
    """Settle the softened box once, release at each mu of ``SLOPE_MODES[mode]`` with barrier
    stiffness ``KAPPAS[kappa]``; ``physics`` overrides entries of ``PHYSICS`` (another
    strategy), ``variant`` is the ``catalogue.SLOPE_VARIANTS`` entry."""
    cfg = SLOPE_MODES[mode]
    p = {**PHYSICS, "kappa_Pa": KAPPAS[kappa], **(physics or {})}
    settled, settle = cat.settle_slope(variant, round(cfg["settle_s"] / DT), p)
    cases = []
    for mu in cfg["mus"]:
        case = cat.release_slope(
            variant, mu, settled, round(cfg["release_s"] / DT), cfg["fit_start_s"], p
        )
        tau = np.array(case["series"]["tau_s"])
        v = np.abs(np.array(case["series"]["speed_along_m_s"]))
        after = v[tau >= cfg["fit_start_s"]]
        case["max_speed_after_fit_start"] = float(after.max()) if after.size else None
        case["kappa"] = kappa
        log_row(log, f"{kappa} mu={mu:g}", case, "accel accel_analytic wall_s")
        cases.append(case)
    return {"settle": settle, "cases": cases}


def _compared_slope(mode: str, strategy: str) -> dict | None:
    """The softened slope under ``strategy`` (augury or lr) beside two_stage."""
    slope_mode = COMPARE_MODES[mode]["slope"]
    if slope_mode is None:
        return None
    if strategy == "augury":
        options = AuguryOptions(kinematic_foreground=True, penetration_check_every=0)
        physics, variant = {"strategy": "augury", "options": options}, "tilted_gravity"
    else:
        physics = {
            "strategy": "lr",
            "options": LROptions(),
            "transfer": "flip",
            "slope_lower_upper_m": cat.LR_SLOPE,
        }
        variant = "dense_slope"
    out = {}
    for name, p, v in ((strategy, physics, variant), ("two_stage", None, "tilted_gravity")):
        started = time.perf_counter()
        res = run_cases(slope_mode, "kappa_paper", p, variant=v)
        out[name] = {
            "wall_s": time.perf_counter() - started,
            "cases": [{k: c.get(k) for k in _SLOPE_KEYS} for c in res["cases"]],
        }
    return {"mode": slope_mode, "runs": out}


def _slope_targets(cases: list[dict], mode: str) -> dict:
    eps_v = PHYSICS["eps_v_m_s"]
    sliding = [c for c in cases if c["accel_analytic"] > 0]
    sticking = [c for c in cases if c["mu"] >= PHYSICS["tan_theta"]]
    return {
        "accel_met": all(
            c["error"] is None
            and c["accel_rel_error"] is not None
            and c["accel_rel_error"] < TARGET_REL[mode]
            for c in sliding
        ),
        "stick_met": all(
            c["error"] is None
            and c["max_speed_after_fit_start"] is not None
            and c["max_speed_after_fit_start"] < STICK_FACTOR * eps_v
            for c in sticking
        ),
    }


def _two_stage_slope(mode: str) -> dict:
    cfg = SLOPE_MODES[mode]
    results = {kappa: run_cases(mode, kappa) for kappa in cfg["kappas"]}
    variants = {
        kappa: {
            "kappa_Pa": KAPPAS[kappa],
            "settle": r["settle"],
            "cases": [_strip(c) for c in r["cases"]],
            "targets": _slope_targets(r["cases"], mode),
        }
        for kappa, r in results.items()
    }
    everything = [c for r in results.values() for c in r["cases"]]
    targets = {
        "accel_rel_error_below": TARGET_REL[mode],
        "stick_max_speed_below_m_s": STICK_FACTOR * PHYSICS["eps_v_m_s"],
        **_slope_targets(everything, mode),
    }
    settles = [r["settle"] for r in results.values()]
    return {
        "variants": variants,
        "targets": targets,
        "target_met": targets["accel_met"] and targets["stick_met"],
        "failed_cases": [
            f"{c['kappa']} mu={c['mu']:g}: {c['error']}" for c in everything if c["error"]
        ],
        "stable_dt_s": stable_dt(),
        "dt_s": DT,
        "steps": sum(s["steps"] for s in settles) + sum(c["steps"] for c in everything),
        "newton_iterations": sum(s["newton_iterations"] for s in settles)
        + sum(c["newton_iterations"] for c in everything),
        "parameters": {
            **{k: v for k, v in PHYSICS.items() if k not in ("options", "kappa_Pa")},
            "kappas_Pa": KAPPAS,
            "options": {"friction": "once", "tol_m_s": 1e-6, "start": "free"},
            "softened_from": {
                "E_Pa": cat.SLOPE_PHYSICS["E_Pa"],
                "kappa_Pa": cat.SLOPE_PHYSICS["kappa_Pa"],
            },
            **cfg,
        },
        "series": {f"{c['kappa']} {c['mu']}": c["series"] for c in everything},
    }


def _plot_two_stage_slope(payload: dict, png: Path) -> None:
    mode, kappa = payload["mode"], SLOPE_MODES[payload["mode"]]["kappas"][-1]
    title = (
        f"two_stage: soft MPM box on a FEM slope, tan theta = 0.2 ({mode}, dt = {DT:g} s, {kappa})"
    )
    cases = [
        {**c, "series": payload["series"][f"{c['kappa']} {c['mu']}"]}
        for c in payload["variants"][kappa]["cases"]
    ]
    slope.plot_cases({"tilted_gravity": {"cases": cases}}, png, title)


# ----------------------------------------------------------------------------- sticking
#: ``sticking``'s one mode: ``plan`` holds (Newton start, eps_v in m/s, mu / tan(theta)) in the
#: order run; what TS reports, the setup and the sticking criterion are in the record's .md
STICKING_MODES = {
    "full": dict(
        plan=tuple(
            (start, eps_v, f)
            for start, eps_v in (
                ("auto", 1e-5),
                ("free", 1e-5),
                ("auto", 1e-4),
                ("auto", 1e-3),
                ("free", 1e-3),
            )
            for f in (1.05, 1.5)
        ),
        release_from="initial",
        release_s=0.1,
        fit_start_s=0.05,
        settle_s=0.02,
    )
}


def sticking(mode: str, cfg: Mapping, release_from: str | None = None) -> dict:
    """Sticking at mu = f tan(theta), released from rest, and Newton iterations per step
    against eps_v (m/s), for each (Newton start, eps_v, f) of ``cfg["plan"]``.

    ``release_from`` (default ``cfg``'s): ``"initial"`` (no settling: the unstressed lattice at
    rest at its initial gap d-hat above the slope, friction on from the first step) or
    ``"settled"`` (settled for ``settle_s`` s as ``two_stage_slope``, frictionless against the
    slope and the stop plane, ``kappa_paper``; the velocities then zeroed; removing the plane
    releases the box's along-slope compression). Each case runs ``release_s`` s. Per case:
    Newton iterations per step, the mean speed along the slope over [``fit_start_s``, end] (net
    displacement / time, m/s: the box's undamped elastic vibration moves its centre back and
    forth at well above eps_v, so the maximum speed measures the vibration, not sliding) and its
    ratio to eps_v, the maximum speed, the displacement over the release (m), the fitted
    acceleration (m/s^2) over [``fit_start_s``, end], and the steady creep speed of the
    friction mollifier (``sticking_metrics``)."""
    release_from = release_from or cfg["release_from"]
    if release_from not in ("settled", "initial"):
        raise ValueError(f"release_from must be 'settled' or 'initial', got {release_from!r}")
    plan, fit_start_s = cfg["plan"], cfg["fit_start_s"]
    base = {**PHYSICS, "kappa_Pa": KAPPAS["kappa_paper"]}
    if release_from == "settled":
        settled, settle = cat.settle_slope("tilted_gravity", round(cfg["settle_s"] / DT), base)
        settle["com_speed_before_zeroing_m_s"] = settle.pop("com_speed_at_release_m_s")
        rest = settled.copy()
        rest.mpm_v[:] = 0.0
        rest.mpm_C[:] = 0.0
    else:
        scene = cat.slope_scene("tilted_gravity", 0.0, with_stop=False, p=base)
        rest, settle = cat.slope_simulation(scene, base).state.copy(), {"steps": 0}
    cases = []
    for start, eps_v, f in plan:
        p = {**base, "eps_v_m_s": eps_v, "options": TwoStageOptions(tol=1e-6, start=start)}
        mu = f * PHYSICS["tan_theta"]
        steps = round(cfg["release_s"] / DT)
        case = cat.release_slope("tilted_gravity", mu, rest, steps, fit_start_s, p)
        case.update(start=start, eps_v=eps_v, mu_over_tan_theta=f)
        sticking_metrics(case, fit_start_s)
        label = f"start={start} eps_v={eps_v:g} mu={mu:.3g}"
        log_row(log, label, case, "newton_per_step mean_speed_after_fit_start wall_s")
        cases.append(case)
    return {
        "settle": settle,
        "cases": [_strip(c) for c in cases],
        "parameters": {
            **{k: v for k, v in PHYSICS.items() if k not in ("options", "kappa_Pa", "eps_v_m_s")},
            "kappa_Pa": KAPPAS["kappa_paper"],
            "options": {"friction": "once", "tol_m_s": 1e-6},
            "plan_start_eps_v_mu_factor": [list(x) for x in plan],
            "release_from": release_from,
            "settle_s": cfg["settle_s"] if release_from == "settled" else 0.0,
            "release_s": cfg["release_s"],
            "fit_start_s": fit_start_s,
        },
        "series": {  # every 4th step (the metrics use every step)
            f"{c['start']} eps_v={c['eps_v']:g} mu={c['mu']:.3g}": {
                k: v[::4] for k, v in c["series"].items()
            }
            for c in cases
        },
        "_cases": cases,
    }


def sticking_metrics(case: dict, fit_start_s: float) -> None:
    """Adds the sticking metrics of a released case (``catalogue.release_slope`` with ``start``,
    ``eps_v`` and ``mu_over_tan_theta`` set) at ``fit_start_s`` s after release, in place.

    ``creep_speed_mollifier_m_s``: the speed at which the mollified friction of BFEMP eq. 36
    (f1(y) = 2 y / eps - y^2 / eps^2 for y < eps = eps_v dt, 1 beyond) balances gravity on a
    rigid box, f1 = tan(theta) / mu: v = eps_v (1 - sqrt(1 - tan(theta) / mu)). A box that
    sticks as well as the smoothed friction allows creeps at this speed."""
    eps_v, f = case["eps_v"], case["mu_over_tan_theta"]
    tau = np.array(case["series"]["tau_s"])
    v = np.array(case["series"]["speed_along_m_s"])
    after = np.abs(v[tau >= fit_start_s - 1e-12])
    s_t = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(tau))])
    i0 = int(np.searchsorted(tau, fit_start_s - 1e-12))
    mean_v = float((s_t[-1] - s_t[i0]) / (tau[-1] - tau[i0])) if i0 < tau.size - 1 else None
    fit = cat.fit_acceleration(tau, s_t, fit_start_s)
    creep = eps_v * (1.0 - np.sqrt(1.0 - 1.0 / f)) if f > 1.0 else None
    case.update(
        fit_start_s=fit_start_s,
        accel=fit["accel"],
        fit_window_s=fit["fit_window_s"],
        newton_per_step=case["newton_iterations"] / max(case["steps"], 1),
        max_speed_after_fit_start=float(after.max()) if after.size else None,
        max_speed_over_eps_v=float(after.max() / eps_v) if after.size else None,
        displacement_m=float(s_t[-1]),
        mean_speed_after_fit_start=mean_v,
        mean_speed_over_eps_v=None if mean_v is None else abs(mean_v) / eps_v,
        creep_speed_mollifier_m_s=None if creep is None else float(creep),
        sticks=bool(case["error"] is None and mean_v is not None and abs(mean_v) < eps_v),
    )


def _plot_sticking(payload: dict, path: Path) -> None:
    """Speed along the slope over eps_v against time since release, per case."""
    cases = payload["_cases"]
    fig, axes = figure((11, 4.2), 1, 2)
    eps_vs = sorted({c["eps_v"] for c in cases})
    for c in cases:
        ax = axes[0 if c["mu_over_tan_theta"] < 1.2 else 1]
        s = c["series"]
        ax.semilogy(
            s["tau_s"],
            np.maximum(np.abs(s["speed_along_m_s"]) / c["eps_v"], 1e-6),
            "-" if c["start"] == "auto" else ":",
            color=f"C{eps_vs.index(c['eps_v'])}",
            label=f"{c['start']} eps_v={c['eps_v']:g} ({c['newton_per_step']:.1f} Newton/step)",
        )
    for ax, f in zip(axes, ("~1.05", "~1.5"), strict=True):
        ax.axhline(1.0, color="k", lw=0.8)
        ax.set(
            xlabel="t since release (s)",
            ylabel="|speed along slope| / eps_v",
            title=f"mu = {f} tan(theta), from rest",
        )
    save(fig, path, axes, "two_stage_slope sticking (dotted: start='free')", legend="xx-small")


# ----------------------------------------------------------------------------- entry
def _scene_of(strategy: str, scene: str | None) -> str:
    scene = scene or ("both" if strategy in ("augury", "lr") else None)
    if (strategy, scene) not in RECORD_NAMES:
        raise ValueError(
            f"scenes: strategy/scene must be one of {sorted(RECORD_NAMES)}, got "
            f"({strategy!r}, {scene!r})"
        )
    return scene


def _modes_of(scene: str) -> Mapping:
    if scene == "both":
        return COMPARE_MODES
    return RINGS_MODES if scene == "rings" else {**SLOPE_MODES, "sticking": {}}


def measure(
    mode: str, cfg: Mapping, strategy: str = "two_stage", scene: str | None = None, **_: object
) -> dict:
    """The record of ``strategy`` on ``scene`` (see the module docstring)."""
    scene = _scene_of(strategy, scene)
    modes, name = _modes_of(scene), RECORD_NAMES[strategy, scene]
    if mode not in modes:
        raise ValueError(f"{name}: mode must be one of {sorted(modes)}, got {mode!r}")
    if scene == "rings":
        return {"benchmark": name, **_two_stage_rings(mode)}
    if scene == "slope":
        return {"benchmark": name, **_two_stage_slope(mode)}
    payload = {
        "benchmark": name,
        "rings": _compared_rings(mode, strategy),
        "slope": _compared_slope(mode, strategy),
    }
    runs = payload["rings"]["runs"]
    if strategy == "augury":  # run_rings' min_distance: finite or None
        payload["paper_bfemp_energy_loss_pct"] = rings.PAPER["energy_loss_pct"]
        drift = runs["augury"]["momentum_drift_rel"]
        payload["augury_momentum_drift_below_1e-10"] = bool(drift < 1e-10)
        payload["augury_min_distance"] = runs["augury"]["min_distance"]
    else:
        drift = runs["lr_mpm_rings"]["momentum_drift_rel"]
        payload["lr_mpm_rings_drift_below_1e-10"] = bool(drift < 1e-10)
    return payload


def _plot(payload: dict, png: Path) -> None:
    if payload["benchmark"] == "two_stage_rings":
        _plot_two_stage_rings(payload, png)
    elif payload["benchmark"] == "two_stage_slope":
        _plot_two_stage_slope(payload, png)


def _record(mode: str, options: Mapping) -> str:
    strategy = options.get("strategy", "two_stage")
    name = RECORD_NAMES[strategy, _scene_of(strategy, options.get("scene"))]
    return name if mode == "full" or name.startswith("two_stage") else f"{name}_{mode}"


def _arguments(parser: argparse._ActionsContainer) -> None:
    """``--strategy`` and ``--scene`` (the old names imply them)."""
    parser.add_argument("--strategy", choices=("augury", "lr", "two_stage"))
    parser.add_argument("--scene", choices=("rings", "slope"))


BENCHMARK = register(
    Benchmark(
        NAME,
        __doc__,
        {**COMPARE_MODES, **RINGS_MODES},
        measure,
        plot=_plot,
        record=_record,
        arguments=_arguments,
        aliases={
            "augury_scenes": {"strategy": "augury"},
            "lr_scenes": {"strategy": "lr"},
            "two_stage_rings": {"strategy": "two_stage", "scene": "rings"},
            "two_stage_slope": {"strategy": "two_stage", "scene": "slope"},
        },
    )
)
run = BENCHMARK.run
register(
    Benchmark(
        "two_stage_slope_sticking", sticking.__doc__, STICKING_MODES, sticking, _plot_sticking
    )
)
