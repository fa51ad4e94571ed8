"""One point of the trade study across strategies: ``run_point(settings)`` (``tradeoff``).

``settings``: ``scene`` (a key of ``_tradeoff_scenes.SCENES``), ``strategy`` (a registry name),
``dt`` (s, or ``"auto"``), ``options`` (the strategy's options as a dict: ``Options(**options)``),
``transfer`` where the scene declares one, and the scene's own settings (its ``base``). Each scene
runs through the benchmark module that defines it (``RUNNERS``), with the variant each strategy
needs (``_tradeoff_scenes`` states which). Returns JSON-ready scalars: ``iterations`` (the run's
summed iteration counts: Newton for barrier and two_stage, 0 for the purely explicit ones),
``failure`` (the ``StepError`` message, None when every step ran), ``max_penetration_m`` (m, the
deepest any FEM node or particle went inside another FEM body, the shared ``penetration_depth``
check; None without FEM bodies) and, where the run built a stepper, the bound it is judged
against (``penetration_bound_m`` in m, ``penetration_bound_cells``, ``penetration_grid_dx_m``:
``benchmarks._penetration``).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable

import numpy as np

import bfemp
from benchmarks import catalogue
from benchmarks._penetration import KEYS as PENETRATION_KEYS
from benchmarks._penetration import penetration_bound, penetration_summary
from benchmarks._shared import check_settings
from bfemp.steppers import stepper_class

log = logging.getLogger(__name__)

EXPLICIT_INTEGRATOR = "symplectic_euler"


def _options(strategy: str, options: dict) -> object:
    return stepper_class(strategy).Options(**options)


# ----------------------------------------------------------------------------- rings
RINGS_KEYS = ("strategy", "dt", "options", "transfer", "dx", "ppc", "dhat", "fem_h", "t_end")


def rings_point(s: dict, on_done: Callable[[bfemp.Simulation], None] | None = None) -> dict:
    """One rings point; ``on_done(sim)`` is called after the run (``benchmarks.lr_variants``)."""
    from benchmarks import rings

    check_settings("rings point", s, RINGS_KEYS)
    strategy = s["strategy"]
    cfg = dict(s)
    if strategy == "lr":  # lr sees the FEM ring through its boundary nodes: h = dx / 2
        cfg["fem_h"] = 0.5 * s["dx"]
    implicit = strategy == "barrier"
    sim = bfemp.Simulation(
        catalogue.rings_scene(cfg),
        strategy=strategy,
        integrator=rings.INTEGRATOR if implicit else EXPLICIT_INTEGRATOR,
        transfer=s["transfer"],
        dt=s["dt"],
        options=_options(strategy, s["options"]),
    )
    check = catalogue.RingsPenetration(sim)
    failure = None
    try:
        sim.run(t_end=s["t_end"], progress=False, callback=check)
    except bfemp.StepError as err:  # recorded; the metrics so far are still reduced
        failure = str(err)
    if on_done is not None:
        on_done(sim)
    m = sim.metrics
    t = m.column("t")
    energy = m.column("energy_kinetic") + m.column("energy_elastic")
    e0, e1 = catalogue.window_energies(t, energy)
    pairs = m.column("contact_pairs")[1:]
    touching = t[1:][pairs > 0]
    iters = m.column("iterations_newton")[1:] if "iterations_newton" in m.columns else [0]
    return {
        "energy_loss_pct": 100.0 * (e0 - e1) / e0 if t[-1] >= rings.WINDOW[1] - 1e-9 else None,
        "contact_duration_s": float(touching[-1] - touching[0]) if touching.size else None,
        "dt_s": float(sim.dt),
        "steps": int(len(t) - 1),
        "iterations": int(np.nansum(iters)),
        "penetrations": int(check.worst),
        "particles": int(sim.model.n_particles),
        "fem_vertices": int(sim.model.n_fem_nodes),
        **penetration_summary(sim),
        "failure": failure,
    }


# ----------------------------------------------------------------------------- slope
SLOPE_KEYS = ("strategy", "dt", "options", "dx", "ppc", "dhat", "eps_v", "mu")
SLOPE_KEYS += ("settle_s", "release_s", "fit_start_s")


def slope_physics(s: dict) -> tuple[dict, str]:
    """The ``slope`` physics dict and ``slope.VARIANTS`` name of a slope point's settings (the
    keys of ``SLOPE_KEYS``, plus ``transfer`` for lr)."""
    from benchmarks import scenes, slope

    strategy = s["strategy"]
    keys = SLOPE_KEYS + (("transfer",) if strategy == "lr" else ())
    check_settings("slope point", s, keys)
    options = dict(s["options"])
    point = {k: s[k] for k in ("dt", "dx", "ppc", "dhat", "eps_v")} | {"strategy": strategy}
    point["tol"] = options.get("tol", slope.PHYSICS["tol_m_s"])
    p = slope.point_physics(point)
    variant = "tilted_gravity"
    if strategy == "barrier":
        if set(options) - {"tol"}:
            raise ValueError(f"slope: barrier takes only the option tol, got {sorted(options)}")
    else:  # the softened box at the explicit step (two_stage_slope), the paper's kappa
        p.update(E_Pa=scenes.E_SOFT, integrator=EXPLICIT_INTEGRATOR)
        p["options"] = _options(strategy, options)
        if strategy == "lr":
            p.update(transfer=s["transfer"], slope_lower_upper_m=catalogue.LR_SLOPE)
            variant = "dense_slope"
    return p, variant


def _slope(s: dict) -> dict:

    p, variant = slope_physics(s)
    dt = s["dt"]
    sims: list[bfemp.Simulation] = []  # the settling's and the release's, for the penetration

    def keep(sim: bfemp.Simulation, _report: object) -> None:
        if not sims or sims[-1] is not sim:
            sims.append(sim)

    try:
        settled, settle = catalogue.settle_slope(
            variant, round(s["settle_s"] / dt), p, on_step=keep
        )
    except bfemp.StepError as err:  # no release without a settled box
        out = {"accel_rel_error": None, "steps": None, "failure": str(err)}
        return out | (penetration_summary(*sims) if sims else {"max_penetration_m": None})
    case = catalogue.release_slope(
        variant, s["mu"], settled, round(s["release_s"] / dt), s["fit_start_s"], p, on_step=keep
    )
    out = {k: v for k, v in case.items() if k not in ("series", "error")}
    out.update(
        steps=settle["steps"] + case["steps"],
        iterations=settle["newton_iterations"] + case["newton_iterations"],
        failure=case["error"],
        **penetration_summary(*sims),
    )
    return out


# ----------------------------------------------------------------------------- hertz
def _barrier_options(scene: str, options: dict) -> dict:
    """barrier's ``tol`` and ``max_newton_iterations`` on the disk (``hertz.run_material``'s
    settings); any other option is refused."""
    keys = ("tol", "max_newton_iterations")
    if set(options) - set(keys):
        raise ValueError(f"{scene}: unsupported barrier options {sorted(set(options) - set(keys))}")
    return {key: options[key] for key in keys}


def _hertz(s: dict) -> dict:
    from benchmarks import hertz

    if s["strategy"] != "barrier":
        raise ValueError(f"hertz: only barrier applies here, got {s['strategy']!r}")
    point = {k: v for k, v in s.items() if k != "options"}
    out = hertz.run_point(point | _barrier_options("hertz", s["options"]))
    out["iterations"] = out.get("newton_iterations")
    return out


HERTZ_SOFT_KEYS = ("strategy", "dt", "options", "dx", "spacing", "dhat", "eps_v", "material")
HERTZ_SOFT_KEYS += ("mu", "t_end", "boundary_refine", "grid_offset_cells")


def _hertz_soft(s: dict) -> dict:
    """The softened disk (``hertz.SOFT``, plates meshed at dx / 2): barrier by backward Euler,
    the explicit strategies by symplectic Euler at ``dt`` (``"auto"``: the stable step)."""
    from benchmarks import hertz

    check_settings("hertz_soft point", s, HERTZ_SOFT_KEYS)
    strategy = s["strategy"]
    cfg = {k: v for k, v in s.items() if k != "options"} | hertz.SOFT
    cfg["plate_h"] = 0.5 * s["dx"]
    if strategy == "barrier":
        cfg.update(_barrier_options("hertz_soft", s["options"]))
    else:
        cfg.update(integrator=EXPLICIT_INTEGRATOR, options=_options(strategy, s["options"]))
    run = hertz.run_material(cfg, s["material"])
    out = {k: v for k, v in run.items() if k not in ("samples", "error")}
    samples = run["samples"]
    out.update(
        E_Pa=hertz.SOFT_E,
        dt_s=run["dt_s"],
        lowest_gap_min_m=float(np.min(samples["lowest_gap"])) if samples["t"] else None,
        F_stress_end=samples["F_stress"][-1] if samples["t"] else None,
        F_end=samples["F"][-1] if samples["t"] else None,
        iterations=run["newton_iterations"],
        failure=run["error"],
    )
    return out


# ----------------------------------------------------------------------------- sine_boundary
#: the scripted strip's density over the box's, for every strategy: it changes nothing for
#: barrier and two_stage (scripted nodes are no unknowns; barrier's quick base: the largest
#: compressive force moved by 1e-13, relative) and weighs the strip's nodes in lr's
#: mass-weighted velocity mixing: at 1 x, 164 particles ended inside the strip (0.21 m deep),
#: at 1e4 x 2 (6.9 mm deep) (measured, quick base)
SINE_STRIP_DENSITY_FACTOR = 1e4
SINE_KEYS = ("strategy", "dt", "options", "scale", "dx", "ppc", "strip_h", "t_stop")


def _sine_boundary(s: dict) -> dict:
    from benchmarks import sine_boundary

    check_settings("sine_boundary point", s, SINE_KEYS)
    cfg = {k: s[k] for k in ("scale", "dx", "ppc", "strip_h", "dt", "t_stop")}
    cfg["strip_density_factor"] = SINE_STRIP_DENSITY_FACTOR
    if s["strategy"] == "barrier":
        cfg |= s["options"]
    else:  # the explicit strategies on the same scene (the box's E sets the stable step)
        options = _options(s["strategy"], s["options"])
        cfg |= {"strategy": s["strategy"], "integrator": EXPLICIT_INTEGRATOR, "options": options}
    run = sine_boundary.run_treatment(cfg, "bfemp")
    keys = ("steps", "t_end", "penetrations", "max_penetration_depth", "max_tensile_force")
    keys += ("dt_s", *PENETRATION_KEYS)
    out = {k: run[k] for k in keys + ("max_compressive_force", "particles", "min_distance")}
    out.update(iterations=run["newton_iterations"], failure=run["error"])
    return out


# ----------------------------------------------------------------------------- augury_blocks
BLOCKS_KEYS = ("strategy", "dt", "options", "dx", "t_end")


def _augury_blocks(s: dict) -> dict:
    from benchmarks import augury_blocks
    from bfemp.contact.penetration import PenetrationCheck

    check_settings("augury_blocks point", s, BLOCKS_KEYS)
    if s["strategy"] in ("barrier", "two_stage"):
        return _blocks_barrier(s)
    if s["strategy"] != "augury":
        raise ValueError(f"augury_blocks: augury, barrier or two_stage, got {s['strategy']!r}")
    h = s["dx"]
    model = augury_blocks.blocks_scene(h).build()
    options = _options("augury", {"grid_dx": 2.0 * h, **s["options"]})
    stepper = stepper_class("augury")(model, dt=s["dt"], options=options)
    state = stepper.initialize(model.initial_state())
    ledger = _blocks_ledger(model, state)
    # the stepper runs without a Simulation, so without its penetration_depth column: the same
    # check (bfemp.contact.penetration) after every step, as Simulation does (and pays)
    check = PenetrationCheck.for_model(model)
    deepest = check.depth(state)
    failure, done = None, 0
    for _ in range(int(round(s["t_end"] / s["dt"]))):
        try:
            state, _report = stepper.step(state)
        except bfemp.StepError as err:
            failure = str(err)
            break
        done += 1
        deepest = max(deepest, check.depth(state))
    return {
        **ledger(state, done),
        "iterations": 0,
        "max_penetration_m": deepest,
        **penetration_bound(stepper),
        "failure": failure,
    }


def _blocks_ledger(model: bfemp.Model, state: bfemp.State) -> Callable[[bfemp.State, int], dict]:
    """``end(state, steps)``: the blocks' energy loss ``1 - E(end) / E0`` (kinetic + FEM
    elastic, J) and momentum drift ``|p(end) - p0| / |p0|`` from the start ``state``."""
    from bfemp import diagnostics
    from bfemp.terms import fem_elastic_groups

    groups = fem_elastic_groups(model)

    def energy(state: bfemp.State) -> float:
        kinetic = diagnostics.kinetic_energy(model, state)
        return kinetic + diagnostics.fem_elastic_energy(model, state, groups)

    e0, p0 = energy(state), diagnostics.linear_momentum(model, state)

    def end(state: bfemp.State, steps: int) -> dict:
        drift = np.linalg.norm(diagnostics.linear_momentum(model, state) - p0) / np.linalg.norm(p0)
        return {
            "energy_loss": 1.0 - energy(state) / e0,
            "momentum_drift_rel": float(drift),
            "steps": steps,
            "nodes_per_block": int(model.fem_bodies[0].n_nodes),
        }

    return end


#: barrier contact of the blocks (m, Pa): the rotated block's nearest edge starts 0.07 m away
BLOCKS_DHAT, BLOCKS_KAPPA = 1e-2, 1e5
#: barrier's integrator on the blocks: Newmark with implicit contact (the rings' choice), the
#: elastic collision without backward Euler's numerical damping
BLOCKS_INTEGRATOR = "newmark_implicit_contact"


def _blocks_barrier(s: dict) -> dict:
    """The blocks by barrier (Newmark, implicit contact) or two_stage (symplectic Euler), with
    frictionless barrier contact (``BLOCKS_DHAT``, ``BLOCKS_KAPPA``)."""
    from benchmarks import augury_blocks

    strategy = s["strategy"]
    scene = augury_blocks.blocks_scene(s["dx"])
    scene.set_contact(dhat=BLOCKS_DHAT, kappa=BLOCKS_KAPPA, mu=0.0)
    integrator = BLOCKS_INTEGRATOR if strategy == "barrier" else EXPLICIT_INTEGRATOR
    sim = bfemp.Simulation(
        scene,
        strategy=strategy,
        integrator=integrator,
        dt=s["dt"],
        options=_options(strategy, s["options"]),
    )
    ledger = _blocks_ledger(sim.model, sim.state)
    failure, done, iterations = None, 0, 0
    for _ in range(int(round(s["t_end"] / sim.dt))):
        try:
            report = sim.step()
        except bfemp.StepError as err:
            failure = str(err)
            break
        done += 1
        iterations += report.newton_iterations
    m = sim.metrics
    closest = (
        float(np.nanmin(m.column("min_distance")[1:]))
        if "min_distance" in m.columns and done
        else None
    )
    return {
        **ledger(sim.state, done),
        "dt_s": float(sim.dt),
        "iterations": int(iterations),
        "min_distance": closest,
        **penetration_summary(sim),
        "failure": failure,
    }


# ----------------------------------------------------------------------------- lr_compression
COMPRESSION_KEYS = ("strategy", "dt", "options", "transfer", "v0_over_cK", "strain")


def _lr_compression(s: dict) -> dict:
    from benchmarks import lr_compression as lc

    check_settings("lr_compression point", s, COMPRESSION_KEYS)
    if s["strategy"] != "lr" or s["dt"] != "auto":
        raise ValueError("lr_compression: strategy 'lr' at dt = 'auto' only (lr_compression)")
    v0 = s["v0_over_cK"] * lc.C_K
    runs, cost = {}, {}
    for name, single in (("column", False), ("single_material", True)):
        wall, cpu = time.perf_counter(), time.process_time()
        scene = lc.column_scene(v0=v0, single=single)
        runs[name] = lc.run_case(
            scene, strain=s["strain"], v0=v0, transfer=s["transfer"], **s["options"]
        )
        cost[name] = (time.perf_counter() - wall, time.process_time() - cpu)
    _, worst = lc.stress_error(runs["column"], runs["single_material"])
    column = runs["column"]
    return {
        "max_abs_error_percent": worst if math.isfinite(worst) else None,
        "dt_s": column["dt"],
        "steps": column["steps"],
        "iterations": 0,
        "mean_contact_nodes": column["mean_contact_nodes"],
        # the cost of the point: the two-block run alone (its single-material twin is the
        # reference, not part of what the strategy costs)
        "point_wall_s": cost["column"][0],
        "point_cpu_s": cost["column"][1],
        "reference_wall_s": cost["single_material"][0],
        "max_penetration_m": None,  # MPM blocks only: no FEM body to be inside
        "failure": None,
    }


RUNNERS = {
    "rings": rings_point,
    "slope": _slope,
    "hertz": _hertz,
    "hertz_soft": _hertz_soft,
    "sine_boundary": _sine_boundary,
    "augury_blocks": _augury_blocks,
    "lr_compression": _lr_compression,
}


def run_point(settings: dict) -> dict:
    """Run one point (module docstring); ``settings["scene"]`` picks the scene."""
    settings = dict(settings)
    scene = settings.pop("scene", None)
    if scene not in RUNNERS:
        raise ValueError(f"unknown scene {scene!r}; available: {', '.join(sorted(RUNNERS))}")
    return RUNNERS[scene](settings)
