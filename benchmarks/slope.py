"""Critical value of the friction coefficient: a stiff MPM box on a fixed FEM slope (paper 6.4).

Setup (paper section 6.4, figures 11 and 12): a 2D MPM box 0.1 m x 0.02 m of 369 particles
(a 41 x 9 lattice of spacing dx / 2 with the box edges included; each particle carries 1/369 of
the box area), grid dx = 0.005 m, Neo-Hookean rho = 100 kg/m^2, E = 4e12 Pa, nu = 0.2, on a fixed
FEM slope with tan(theta) = 0.2 under g = 5.10 m/s^2; dhat = 1e-3 m, kappa = 1e6 Pa,
eps_v = 1e-5 m/s, backward Euler, dt = 1e-3 s, Newton tolerance 1e-8 m/s, lagged friction
iterated until a minimisation under fresh friction data needs no Newton step (cap 100).

Procedure, as in the paper: the box is placed dhat away from the slope and dhat away from an
extra fixed FEM plane perpendicular to the slope on its downhill side, and settles without
friction (full mode: 2 s, the paper's settling period; quick mode: 0.02 s, the box is static
after ~10 steps). The settled state is then continued, for each mu in (0, 0.1, 0.1999, 0.2), in
a scene without the extra plane (full mode: 1 s, the paper's release period 2 s to 3 s; quick
mode: 0.06 s). The settled state is carried over as it is (``sim.state`` is replaced, as a
checkpoint restore does); the box is released with its residual settling velocity (~1e-7 m/s).

Geometry: ``"tilted_gravity"`` lays the slope along the x axis and tilts gravity by theta,
g = g (-sin theta, -cos theta), so the box and slope are aligned with the MPM grid;
``"rotated_slope"`` rotates every mesh and the particle lattice by theta about the origin and keeps
g = (0, -g). Both are the same continuum problem. The slope is a fixed FEM block 1 m x 0.5 m
(x in [-0.8, 0.2] m, top face y = 0) meshed like the paper's rigid plates: 4 vertices and
2 triangles, so its top face is one segment and the box never meets a slope vertex. Variants
(each settled and released on its own):

- ``tilted_gravity`` (the reported ``cases``; quick and full mode);
- ``rotated_slope`` (full mode);
- ``fine_slope``: tilted gravity on the slope meshed with h = 0.1 m, whose top vertices sit every
  0.1 m, two of them under the box's corner particle columns at release (quick mode: mu = 0.1999
  only; full mode: every mu). It checks that friction near FEM boundary vertices counts each
  contact once, as the barrier does (eq. 31).

Metric: the centre-of-mass displacement s(t) down the slope is fitted by least squares with a
quadratic s0 + v0 tau + a tau^2 / 2 over the release window tau >= ``fit_start`` (0.1 s full,
0.02 s quick; the free v0 absorbs the short start-up where the sliding speed is below eps_v and
the mollified friction is weaker); ``accel`` = a against the analytic acceleration
g (sin theta - mu cos theta) (eq. 40; 0 for mu >= tan theta). For mu = 0.2 = tan theta the
relative error is undefined (null) and the speed is the metric: the mollified static friction
lets the box creep up to eps_v, where full Coulomb friction balances gravity exactly.

A step that fails (``StepError``) ends its case; the error is kept in the case's ``error`` and in
``failed_cases``, and the fit uses the steps before it (known limits:
``benchmarks/records/slope.md``).
"""

from __future__ import annotations

import logging
import math
from pathlib import Path

import numpy as np

from benchmarks.catalogue import SLOPE_PHYSICS as PHYSICS
from benchmarks.catalogue import SLOPE_VARIANTS as VARIANTS
from benchmarks.catalogue import release_slope, settle_slope
from benchmarks.common import figure, log_row
from benchmarks.runner import Benchmark, register

log = logging.getLogger(__name__)

NAME = "slope"


MODES = {
    "full": {
        "settle_steps": 2000,
        "release_steps": 1000,
        "fit_start_s": 0.1,
        "variants": {"tilted_gravity": None, "rotated_slope": None, "fine_slope": None},
    },
    "quick": {
        "settle_steps": 20,
        "release_steps": 60,
        "fit_start_s": 0.02,
        # variant -> the mus it runs (None: all)
        "variants": {"tilted_gravity": None, "fine_slope": (0.1999,)},
    },
}


_STYLES = {"tilted_gravity": "-", "rotated_slope": "-.", "fine_slope": ":"}


def plot_cases(results: dict, path: Path, title: str) -> None:
    """Speed down the slope and per-step acceleration error against time since release.

    Colours are the friction coefficients, line styles the variants; thin dashed lines are the
    analytic speeds g (sin theta - mu cos theta) t. The error panel shows the reported
    (``tilted_gravity``) cases only.
    """
    p = PHYSICS
    theta = math.atan(p["tan_theta"])
    g_sin = p["g_m_s2"] * math.sin(theta)
    colors = {mu: f"C{k}" for k, mu in enumerate(p["mus"])}
    fig, (ax_v, ax_a) = figure((12.0, 4.6), 1, 2)
    for variant, result in results.items():
        for case in result["cases"]:
            tau = np.array(case["series"]["tau_s"])
            v = np.array(case["series"]["speed_along_m_s"])
            color, style = colors[case["mu"]], _STYLES[variant]
            rel = case["accel_rel_error"]
            label = f"{variant}, mu = {case['mu']:g}"
            fit = f"{label} (fit: {rel:.1e})" if rel is not None else label
            if case["error"] is not None:
                fit += " (step failed)"
            ax_v.plot(tau[1:], np.abs(v[1:]), style, color=color, label=fit)
            if variant != "tilted_gravity":
                continue
            if case["accel_analytic"] > 0:
                ax_v.plot(tau[1:], case["accel_analytic"] * tau[1:], "--", color="k", lw=0.6)
            err = np.abs(np.diff(v) / np.diff(tau) - case["accel_analytic"]) / g_sin
            ax_a.plot(tau[1:], np.maximum(err, 1e-16), style, color=color, label=label, lw=0.8)
    ax_v.axhline(p["eps_v_m_s"], color="k", lw=0.8, ls=":", label="eps_v")
    ax_v.set(yscale="log", xlabel="time since release (s)", ylabel="COM speed down the slope (m/s)")
    ax_v.set_title("COM speed (thin dashed: analytic; fit: relative error of a)", fontsize=9)
    ax_v.legend(fontsize=6, loc="lower right")
    ax_a.set(yscale="log", xlabel="time since release (s)")
    ax_a.set_ylabel("|a_n - a_analytic| / (g sin theta)")
    ax_a.set_title("per-step COM acceleration error (tilted gravity)", fontsize=9)
    ax_a.legend(fontsize=7)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)


def _run_variant(variant: str, mus: tuple[float, ...], cfg: dict) -> dict:
    """Settle once, release at each mu; the variant's settle record and cases."""
    settled, settle = settle_slope(variant, cfg["settle_steps"])
    log_row(log, f"{variant} settled", settle, "wall_s com_speed_at_release_m_s")
    cases = []
    for mu in mus:
        case = release_slope(variant, mu, settled, cfg["release_steps"], cfg["fit_start_s"])
        log_row(log, f"{variant} mu={mu:g}", case, "accel accel_analytic max_speed wall_s")
        cases.append(case)
    frame, slope_h = VARIANTS[variant]
    return {"frame": frame, "slope_h_m": slope_h, "settle": settle, "cases": cases}


def _strip(cases: list[dict]) -> list[dict]:
    return [{k: v for k, v in c.items() if k != "series"} for c in cases]


def point_physics(settings: dict) -> dict:
    """``PHYSICS`` with a trade-study point's knobs applied (``_tradeoff_runs.slope_physics``):
    time step ``dt`` (s), grid ``dx`` (m), particles per cell ``ppc`` (a square), barrier ``dhat``
    (m), friction ``eps_v`` (m/s), Newton ``tol`` (m/s) and the library's ``strategy`` name.

    The particle lattice keeps the box edges: ``k = sqrt(ppc)`` particles per cell and axis at
    spacing ``dx / k``, i.e. ``(round(0.1 k / dx) + 1) x (round(0.02 k / dx) + 1)`` particles
    (41 x 9 at the paper's dx = 0.005 m, ppc = 4); the box starts ``dhat (1 + 1e-6)`` from the
    slope and the stop plane, as in ``PHYSICS``.
    """
    k = round(math.sqrt(settings["ppc"]))
    if k < 1 or k * k != settings["ppc"]:
        raise ValueError(
            f"slope: settings.ppc must be a square (1, 4, 9, ...), got {settings['ppc']}"
        )
    lx, ly = PHYSICS["box_size_m"]
    spacing = settings["dx"] / k
    return {
        **PHYSICS,
        "dt_s": settings["dt"],
        "dx_m": settings["dx"],
        "particle_lattice": (round(lx / spacing) + 1, round(ly / spacing) + 1),
        "dhat_m": settings["dhat"],
        "initial_gap_m": settings["dhat"] * (1.0 + 1e-6),
        "eps_v_m_s": settings["eps_v"],
        "tol_m_s": settings["tol"],
        "strategy": settings["strategy"],
    }


def measure(mode: str, cfg: dict) -> dict:
    """Settle, release at each mu, fit the accelerations: ``"full"`` (the paper's settling and
    release periods, every variant) or ``"quick"`` (short periods; the ``fine_slope`` variant at
    mu = 0.1999 only). ``cases`` are the ``tilted_gravity`` results, ``variants`` those of every
    variant."""
    results = {
        name: _run_variant(name, PHYSICS["mus"] if mus is None else mus, cfg)
        for name, mus in cfg["variants"].items()
    }
    primary = results["tilted_gravity"]
    everything = [c for r in results.values() for c in r["cases"]]
    steps = sum(r["settle"]["steps"] for r in results.values())
    newton = sum(r["settle"]["newton_iterations"] for r in results.values())
    return {
        "frame": primary["frame"],
        "cases": _strip(primary["cases"]),
        "settle": primary["settle"],
        "variants": {
            name: {**{k: v for k, v in r.items() if k != "cases"}, "cases": _strip(r["cases"])}
            for name, r in results.items()
        },
        "failed_cases": [
            f"{name} mu={c['mu']:g}: {c['error']}"
            for name, r in results.items()
            for c in r["cases"]
            if c["error"] is not None
        ],
        "steps": steps + sum(c["steps"] for c in everything),
        "newton_iterations": newton + sum(c["newton_iterations"] for c in everything),
        "parameters": {**PHYSICS, **cfg, "variant_specs": VARIANTS},
        "paper": {"accel_rel_error": 1e-4, "mu_0.2_speed": "around eps_v"},
        "series": {str(c["mu"]): c["series"] for c in primary["cases"]},
        "_results": results,
    }


def plot(payload: dict, png: Path) -> None:
    """``plot_cases`` of every variant."""
    title = f"MPM box on a FEM slope, tan theta = 0.2 ({payload['mode']} mode, dt = 1e-3 s)"
    plot_cases(payload["_results"], png, title)


BENCHMARK = register(Benchmark(NAME, __doc__, MODES, measure, plot=plot))
run = BENCHMARK.run
