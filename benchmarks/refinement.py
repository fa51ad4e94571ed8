"""Convergence under refinement (BFEMP paper, section 6.5, figures 13-14): an MPM box settling on
a FEM box; the centre-of-mass height at rest converges as dx = 1/N, dhat = 1/N^2 shrink.

Setup (paper): a 2D Neo-Hookean MPM box 2 m x 1 m (E = 4e4 Pa, nu = 0.4, rho = 1e3 kg/m^2)
starts dx above a Neo-Hookean FEM box 4 m x 1 m (E = 4e4 Pa, nu = 0.4, rho = 1e2 kg/m^2) and
settles under g = 10 m/s^2. The FEM mesh size and the MPM grid spacing are both dx = 1/N, the
barrier's activation distance dhat = 1/N^2, kappa = 1e6 Pa; PIC transfer, backward Euler, a large
dt. Particles on the sub-cell centres of each cell (``bfemp.sample.box``), PPC 4, 9 and 16.

Metric: ``y_all``, the height of the centre of mass of the whole domain (FEM and MPM bodies,
mass-weighted: the paper's definition) at rest, and ``y_mpm``, that of the MPM box alone; the
error of a resolution N is ``|y(N) - y(N_ref)|`` at the same PPC (``errors`` and
``errors_mpm``). The convergence order is the slope of the least-squares line through
``(log dx, log error)`` over every N of the series (``order``, ``order_mpm``).

Measured results, with the commits they ran on: ``benchmarks/records/refinement.md``.

Choices where the paper is silent (all recorded in the JSON ``parameters``):

- Geometry: FEM box ``[-2, 2] x [0, 1]`` (``bfemp.shapes.rectangle`` with h = dx, alternating
  diagonals); its bottom row of nodes is fixed (``bfemp.motion.Fixed``), every other node is
  free. The MPM box ``[-1, 1] x [1 + dx, 2 + dx]``, centred on the FEM box; frictionless
  (mu = 0, the paper names no friction); the rest state does not depend on the initial gap.
- Particle lattice aligned with the MPM box; the MPM grid origin shifted by a quarter of the
  particle spacing (dx / (4 sqrt(PPC))) off the lattice, as in ``benchmarks.rings``: with PPC 9
  sub-cell centres fall on half-integer grid coordinates, where the outermost B-spline weight
  vanishes.
- Time step dt = 1 s (the box's vertical period is about 4 h / sqrt(E / rho) = 0.6 s: backward
  Euler at dt = 1 s damps it within a few steps).
- Newton tolerance 1e-6 m/s (an increment below 1e-6 m at dt = 1 s), not the paper's 1e-9 m/s
  (a round-off floor; measured in ``benchmarks/records/refinement.md``). The cap is 1000 Newton
  iterations per step.
- Rest criterion: the MPM box's centre-of-mass height changes by less than ``rest_tol`` = 1e-6 m
  over ``rest_steps`` = 2 consecutive steps, at most ``max_steps`` = 60 steps; a resolution
  that does not come to rest is recorded (``at_rest`` false) and is not used in the fit.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

import bfemp
from benchmarks import catalogue
from benchmarks.common import figure, log_row
from benchmarks.runner import Benchmark, name_unless, register

log = logging.getLogger(__name__)

NAME = "refinement"
MPM_MATERIAL = dict(E=4e4, nu=0.4, density=1e3)  # Pa, -, kg/m^2
FEM_MATERIAL = dict(E=4e4, nu=0.4, density=1e2)  # Pa, -, kg/m^2
GRAVITY = 10.0  # m/s^2
MPM_BOX = (2.0, 1.0)  # m, width x height
FEM_BOX = ((-2.0, 0.0), (2.0, 1.0))  # m, lower and upper corners
KAPPA = 1e6  # Pa
PAPER = {"order_ppc16": 2.75, "tol_m_s": 1e-9}

SETTINGS = {
    "dt_s": 1.0,
    "tol_m_s": 1e-6,
    "max_newton_iterations": 1000,
    "rest_tol_m": 1e-6,
    "rest_steps": 2,
    "max_steps": 60,
    "transfer": "pic",
    "integrator": "backward_euler",
    "mu": 0.0,
}

MODES = {
    "full": {"ns": tuple(range(2, 21, 2)), "n_ref": 30, "ppcs": (4, 9, 16)},
    # the full series of the paper's target PPC only (what fits a 2-core machine)
    "ppc16": {"ns": tuple(range(2, 21, 2)), "n_ref": 30, "ppcs": (16,)},
    "quick": {"ns": (4, 8, 12), "n_ref": 16, "ppcs": (16,)},
}


def _scene(n: int, ppc: int) -> bfemp.Scene:
    """Both boxes at resolution dx = 1/n, the MPM box dx above the FEM box."""
    dx = 1.0 / n
    k = round(ppc**0.5)
    if k * k != ppc:
        raise ValueError(f"refinement: ppc must be a square (4, 9, 16, ...), got {ppc}")
    scene = bfemp.Scene(dim=2, gravity=(0.0, -GRAVITY))
    fem = bfemp.shapes.rectangle(*FEM_BOX, h=dx)
    bottom = fem.points[:, 1] < FEM_BOX[0][1] + 1e-9
    scene.add_fem(
        fem,
        material=bfemp.NeoHookean(**FEM_MATERIAL),
        prescribed=bfemp.motion.Fixed(),
        prescribed_nodes=bottom,
        name="fem_box",
    )
    width, height = MPM_BOX
    lower = (-0.5 * width, FEM_BOX[1][1] + dx)
    upper = (0.5 * width, lower[1] + height)
    particles, volumes = bfemp.sample.box(lower, upper, dx=dx, ppc=ppc, origin=lower)
    scene.add_mpm(particles, volumes, material=bfemp.NeoHookean(**MPM_MATERIAL), name="mpm_box")
    shift = dx / (4.0 * k)
    scene.set_grid(dx=dx, origin=(lower[0] + shift, lower[1] + shift))
    scene.set_contact(dhat=dx * dx, kappa=KAPPA, mu=SETTINGS["mu"])
    return scene


def settle(n: int, ppc: int, settings: dict = SETTINGS) -> dict:
    """Settle the boxes at resolution ``n`` and ``ppc``; the rest heights and the run's cost.

    Returns:
        ``y_all`` and ``y_mpm`` (m): centre-of-mass heights at rest of the whole domain and of
        the MPM box; ``at_rest`` (the rest criterion met), ``steps``, ``newton_iterations``,
        ``wall_s``, ``min_distance`` (m, last step), ``particles``, ``fem_nodes``, the
        ``StepError`` message in ``error`` and the per-step ``y_mpm`` history.
    """
    scene = _scene(n, ppc)
    sim = bfemp.Simulation(
        scene,
        integrator=settings["integrator"],
        transfer=settings["transfer"],
        dt=settings["dt_s"],
        tol=settings["tol_m_s"],
        max_newton_iterations=settings["max_newton_iterations"],
    )
    m_mpm, m_fem = sim.model.mpm_mass, sim.model.fem_mass
    total = m_mpm.sum() + m_fem.sum()

    def heights() -> tuple[float, float]:
        y_m = float(m_mpm @ sim.state.mpm_x[:, 1])
        y_f = float(m_fem @ sim.state.fem_x[:, 1])
        return (y_m + y_f) / total, y_m / m_mpm.sum()

    history, calm, iterations, error, min_distance = [heights()[1]], 0, 0, None, float("nan")
    started = time.perf_counter()
    while len(history) <= settings["max_steps"] and calm < settings["rest_steps"]:
        report, error = catalogue.step(sim, f"refinement N={n} PPC={ppc}")
        if error is not None:
            break
        iterations += report.newton_iterations
        min_distance = float(report.min_distance)
        history.append(heights()[1])
        calm = calm + 1 if abs(history[-1] - history[-2]) < settings["rest_tol_m"] else 0
    y_all, y_mpm = heights()
    wall = time.perf_counter() - started
    out = {
        "n": n,
        "ppc": ppc,
        "dx_m": 1.0 / n,
        "y_all": y_all,
        "y_mpm": y_mpm,
        "at_rest": calm >= settings["rest_steps"] and error is None,
        "steps": len(history) - 1,
        "newton_iterations": iterations,
        "wall_s": wall,
        "min_distance_m": min_distance,
        "particles": int(sim.model.n_particles),
        "fem_nodes": int(sim.model.n_fem_nodes),
        "error": error,
        "y_mpm_history": history,
    }
    log_row(log, f"{NAME} N={n} PPC={ppc}", out, "y_all y_mpm steps newton_iterations wall_s")
    return out


def fit_order(dx: np.ndarray, err: np.ndarray) -> float:
    """Least-squares slope of log(err) against log(dx) (NaN with fewer than two points)."""
    keep = np.isfinite(err) & (err > 0.0)
    if keep.sum() < 2:
        return float("nan")
    return float(np.polyfit(np.log(dx[keep]), np.log(err[keep]), 1)[0])


def _series(runs: list[dict], ref: dict) -> dict:
    """Errors of one PPC's runs against its reference, and the fitted orders."""
    use = [r for r in runs if r["at_rest"]]
    dx = np.array([r["dx_m"] for r in use])
    err = np.array([abs(r["y_all"] - ref["y_all"]) for r in use])
    err_mpm = np.array([abs(r["y_mpm"] - ref["y_mpm"]) for r in use])
    return {
        "ns": [r["n"] for r in use],
        "not_at_rest": [r["n"] for r in runs if not r["at_rest"]],
        "errors": err.tolist(),
        "errors_mpm": err_mpm.tolist(),
        "order": fit_order(dx, err),
        "order_mpm": fit_order(dx, err_mpm),
        "monotone": bool(np.all(np.diff(err) < 0.0)),
        "monotone_mpm": bool(np.all(np.diff(err_mpm) < 0.0)),
    }


def plot(payload: dict, path: Path) -> None:
    """Figure 14: error of the centre-of-mass height against dx, log-log, per PPC."""
    series = {int(k): v for k, v in payload["series"].items()}
    title = f"MPM box on FEM box: centre-of-mass height error ({payload['mode']} mode)"
    fig, ax = figure((6.4, 4.8), layout="constrained")
    for k, (ppc, s) in enumerate(series.items()):
        dx = 1.0 / np.array(s["ns"], dtype=float)
        ax.loglog(dx, s["errors"], "o-", color=f"C{k}", label=f"PPC {ppc}: order {s['order']:.2f}")
    all_dx = np.concatenate([1.0 / np.array(s["ns"], dtype=float) for s in series.values()])
    all_err = np.concatenate([np.array(s["errors"]) for s in series.values()])
    if all_dx.size:
        x = np.array([all_dx.min(), all_dx.max()])
        anchor = np.nanmax(all_err) if np.isfinite(all_err).any() else 1.0
        for order, style in ((1, "k:"), (2, "k--")):
            ax.loglog(x, anchor * (x / x.max()) ** order, style, lw=0.8, label=f"order {order}")
    ax.set(xlabel="dx = 1/N [m]", ylabel="|y_com(N) - y_com(N_ref)| [m]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small")
    ax.set_title(title, fontsize="medium")
    fig.savefig(path, dpi=110)


def measure(mode: str, cfg) -> dict:
    """Settle every resolution ``cfg["ns"]`` and its reference ``cfg["n_ref"]`` at each PPC of
    ``cfg["ppcs"]`` (``MODES``); ``series[ppc]`` holds the errors and fitted orders."""
    runs, series = {}, {}
    for ppc in cfg["ppcs"]:
        ref = settle(cfg["n_ref"], ppc)
        tests = [settle(n, ppc) for n in cfg["ns"]]
        runs[ppc] = {"reference": ref, "runs": tests}
        series[ppc] = {**_series(tests, ref), "reference_at_rest": ref["at_rest"]}
    return {
        "series": {str(k): v for k, v in series.items()},
        "paper": PAPER,
        "targets": {
            "full": "order >= 2 for PPC 16",
            "quick": "error decreases monotonically over N = 4, 8, 12",
        },
        "parameters": {
            **cfg,
            **SETTINGS,
            "mpm_material": {"model": "NeoHookean", **MPM_MATERIAL},
            "fem_material": {"model": "NeoHookean", **FEM_MATERIAL},
            "gravity_m_s2": GRAVITY,
            "mpm_box_m": MPM_BOX,
            "fem_box_m": FEM_BOX,
            "fem_held": "bottom row of nodes fixed",
            "kappa_Pa": KAPPA,
            "dhat": "1/N^2 m",
            "dx": "1/N m (MPM grid and FEM mesh size)",
            "initial_gap": "dx",
        },
        "runs": {str(k): v for k, v in runs.items()},
    }


BENCHMARK = register(
    Benchmark(NAME, __doc__, MODES, measure, plot=plot, record=name_unless("full", NAME))
)
run = BENCHMARK.run
