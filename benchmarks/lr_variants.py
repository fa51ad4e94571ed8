"""``lr_variants``: which of lr's settings holds on which kind of contact (issue 17).

lr's update variants (``VARIANTS``: ``LROptions`` over the scene's own) side by side on three
scenes, each a different kind of contact: where each one breaks (why it was asked:
``benchmarks/records/lr_variants.md``). ``flip_c1`` is the paper's (FLIP, two corrections,
f^{C,1}, eq. 33), ``flip_c0`` takes f^{C,0}, ``once`` is "LR once" (Fig. 5; lr's default since
issue 40, ``LROptions.corrections``), ``pic`` PIC (eq. 38) and ``xpic5`` XPIC(5), the paper's
validation setting.

Scenes:

- ``slope``: the trade study's lr slope point (``_tradeoff_runs.slope_physics``: the box of
  ``two_stage_slope`` softened to E = 1e5 Pa, on the 1 cm thick FEM slope meshed at dx / 2,
  gravity tilted, mu = 0.1, dt = 5e-5 s, dx = 5 mm, PPC 4). It settles frictionless against a
  stop, then slides; error = |a_fit - a| / a against eq. 40. Also recorded: the mean normal
  velocity of the box's bottom particle row at release (m/s; negative = into the slope), the
  landing velocity the particles still carry.
- ``rings``: the trade study's quick lr point (dx = 0.5 m, PPC 4, the FEM ring meshed at
  dx / 2 as a material, frictionless, dt = "auto", to 0.3 s); error = the trade study's
  max(|L - L_ref| / L_ref, |T - T_ref| / T_ref) of the energy loss L and contact duration T
  against the barrier reference run of that discretisation (run here); also the particles found
  inside the FEM ring at any step (``catalogue.RingsPenetration``).
- ``compression``: ``lr_compression``'s column; error = the largest |stress error| in % past
  1 % strain against the single-material run with the same particle update
  (``_SMM_REFERENCE``).

Per run also the wall time and ``LRStepper``'s run totals (``_totals``): the first and second
corrections' sum |dp| over the steps with contact, their ratio, and the windows of 100 contact
steps given the ``LR_FIRST_CORRECTION`` note (``bfemp.steppers.lr.FIRST_CORRECTION_RATIO``).
Modes (``MODES``, ``_SLOPE``): ``smoke`` (the tests), ``quick``, ``full`` (the slope at the full
trade study's times; rings as quick: the full rings discretisation costs hours per explicit
run). No (T) target: the record says where each variant holds.
"""

from __future__ import annotations

import logging
import math
import time
from pathlib import Path

import numpy as np

from benchmarks import catalogue
from benchmarks.common import figure
from benchmarks.runner import Benchmark, name_unless, register

log = logging.getLogger(__name__)

NAME = "lr_variants"
VARIANTS = {
    "flip_c1": {"corrections": 2},
    "flip_c0": {"contact_force": "c0", "corrections": 2},
    "once": {"corrections": 1},
    "pic": {"xpic_order": 1, "corrections": 2},
    "xpic5": {"xpic_order": 5, "corrections": 2},
}
#: the single-material reference of each variant's particle update (compression)
_SMM_REFERENCE = {"flip_c1": {}, "flip_c0": {}, "once": {}, "pic": {"xpic_order": 1}}
_SMM_REFERENCE["xpic5"] = {"xpic_order": 5}
_SLOPE = {"smoke": (0.02, 0.03, 0.01), "quick": (0.02, 0.03, 0.01), "full": (0.1, 0.2, 0.05)}
MODES = {
    "smoke": {"variants": ("flip_c1", "flip_c0", "once"), "scenes": ("slope", "compression")},
    "quick": {"variants": tuple(VARIANTS), "scenes": ("slope", "rings", "compression")},
    "full": {"variants": tuple(VARIANTS), "scenes": ("slope", "rings", "compression")},
}
_COMPRESSION_MODE = {"smoke": "quick", "quick": "quick", "full": "full"}


def _totals(run: object) -> dict:
    """``LRStepper``'s first/second correction totals of a run: from the stepper, or from
    ``lr_compression.run_case``'s result (a dict with the same keys)."""
    get = run.get if isinstance(run, dict) else lambda key: getattr(run, key)
    first, second = get("first_correction_impulse"), get("second_correction_impulse")
    return {
        "first_correction_impulse": first,
        "second_correction_impulse": second,
        "first_over_second": first / second if second > 0.0 else None,
        "first_correction_windows": get("first_correction_windows"),
    }


def slope_case(mode: str, options: dict) -> dict:
    """The settle-and-slide slope case with lr ``options`` (module docstring)."""
    from benchmarks import _tradeoff_runs

    settle_s, release_s, fit_start_s = _SLOPE[mode]
    s = dict(strategy="lr", dt=5e-5, options=options, transfer="flip", dx=5e-3, ppc=4)
    s |= dict(dhat=1e-3, eps_v=1e-5, mu=0.1, settle_s=settle_s, release_s=release_s)
    s["fit_start_s"] = fit_start_s
    p, variant = _tradeoff_runs.slope_physics(s)
    seen: dict[str, object] = {}

    def keep(sim: object, _report: object) -> None:
        seen["stepper"] = sim.stepper

    started = time.perf_counter()
    settled, _ = catalogue.settle_slope(variant, round(settle_s / s["dt"]), p, on_step=keep)
    settle_totals = _totals(seen["stepper"])
    # tilted gravity: the slope is the plane y = 0, its normal +y; the bottom row of the lattice
    spacing = s["dx"] / math.sqrt(s["ppc"])
    y = settled.mpm_x[:, 1]
    bottom = y < y.min() + 0.5 * spacing
    steps = round(release_s / s["dt"])
    case = catalogue.release_slope(variant, s["mu"], settled, steps, fit_start_s, p, on_step=keep)
    return {
        "error": case["accel_rel_error"],
        "accel_m_s2": case["accel"],
        "accel_analytic_m_s2": case["accel_analytic"],
        "bottom_row_normal_velocity_m_s": float(settled.mpm_v[bottom, 1].mean()),
        "box_normal_velocity_m_s": float(settled.mpm_v[:, 1].mean()),
        "settle": settle_totals,
        "slide": _totals(seen["stepper"]),
        "failure": case["error"],
        "wall_s": time.perf_counter() - started,
    }


def _rings_settings(strategy: str, label: str) -> dict:
    from benchmarks.tradeoff import plan

    (point,) = [p for p in plan("quick", "rings", strategies=strategy) if p["label"] == label]
    return dict(point["settings"])


def rings_reference() -> dict:
    """The barrier reference run of the quick rings (the trade study's, at its settings)."""
    from benchmarks import _tradeoff_runs

    started = time.perf_counter()
    out = _tradeoff_runs.rings_point(_rings_settings("barrier", "reference"))
    return {k: out[k] for k in ("energy_loss_pct", "contact_duration_s", "failure")} | {
        "wall_s": time.perf_counter() - started
    }


def rings_case(options: dict, reference: dict) -> dict:
    """The quick rings lr point with ``options`` added; error against ``reference``."""
    from benchmarks import _tradeoff_runs

    s = _rings_settings("lr", "base")
    s["options"] = dict(s["options"]) | options
    seen: dict[str, object] = {}
    started = time.perf_counter()
    out = _tradeoff_runs.rings_point(s, on_done=lambda sim: seen.update(stepper=sim.stepper))
    parts = [
        abs(out[k] - reference[k]) / reference[k]
        for k in ("energy_loss_pct", "contact_duration_s")
        if out[k] is not None and reference[k]
    ]
    return {
        "error": max(parts) if len(parts) == 2 else None,
        "energy_loss_pct": out["energy_loss_pct"],
        "contact_duration_s": out["contact_duration_s"],
        "particles_inside_fem_ring": out["penetrations"],
        "run": _totals(seen["stepper"]),
        "failure": out["failure"],
        "wall_s": time.perf_counter() - started,
    }


def compression_case(v0: float, strain: float, options: dict, reference: dict) -> dict:
    """``lr_compression``'s column pressed at ``v0`` m/s to ``strain`` with ``options``; error
    against the ``reference`` run."""
    from benchmarks import lr_compression as lc

    started = time.perf_counter()
    case = lc.run_case(lc.column_scene(v0=v0), strain=strain, v0=v0, **options)
    _, worst = lc.stress_error(case, reference)
    return {"error_pct": worst, "run": _totals(case), "wall_s": time.perf_counter() - started}


def _compression(mode: str, variants: tuple[str, ...]) -> dict:
    from benchmarks import lr_compression as lc

    cmode = _COMPRESSION_MODE[mode]
    frac, strain = lc.MODES[cmode]
    v0 = frac * lc.C_K
    references, runs = {}, {}
    for name in variants:
        key = tuple(sorted(_SMM_REFERENCE[name].items()))
        if key not in references:
            scene = lc.column_scene(v0=v0, single=True)
            references[key] = lc.run_case(scene, strain=strain, v0=v0, **_SMM_REFERENCE[name])
        log.info("lr_variants compression %s: %s", cmode, name)
        runs[name] = compression_case(v0, strain, VARIANTS[name], references[key])
    return {"mode": cmode, "v0_m_s": v0, "final_strain": strain, "runs": runs}


def measure(mode: str, cfg: dict) -> dict:
    """Every variant of ``mode`` on each of its scenes."""
    variants, scenes = cfg["variants"], cfg["scenes"]
    payload: dict = {
        "variants": {v: VARIANTS[v] for v in variants},
    }
    if "slope" in scenes:
        payload["slope"] = {"settle_release_fit_s": _SLOPE[mode], "runs": {}}
        for name in variants:
            log.info("lr_variants slope: %s", name)
            payload["slope"]["runs"][name] = slope_case(mode, VARIANTS[name])
    if "rings" in scenes:
        reference = rings_reference()
        payload["rings"] = {"reference": reference, "runs": {}}
        for name in variants:
            log.info("lr_variants rings: %s", name)
            payload["rings"]["runs"][name] = rings_case(VARIANTS[name], reference)
    if "compression" in scenes:
        payload["compression"] = _compression(mode, variants)
    return payload


def _error(scene: str, run_: dict) -> float | None:
    if scene == "compression":
        return run_["error_pct"] / 100.0
    return run_["error"]


def _title(scene: str, payload: dict) -> str:
    if scene == "slope":
        settle, slide, _ = payload["slope"]["settle_release_fit_s"]
        return f"slope: settle {settle:g} s, slide {slide:g} s"
    if scene == "rings":
        return "rings: quick discretisation, to 0.3 s"
    return f"compression: lr_compression {payload['compression']['mode']}"


def plot(payload: dict, path: Path) -> None:
    """Bars: each variant's error per scene (log scale), the first/second ratio above them."""
    scenes = [s for s in ("slope", "rings", "compression") if s in payload]
    variants = list(payload["variants"])
    fig, axes = figure((3.6 * len(scenes), 3.8), 1, len(scenes), squeeze=False)
    axes = axes[0]
    for ax, scene in zip(axes, scenes, strict=True):
        runs = payload[scene]["runs"]
        errors = [_error(scene, runs[v]) for v in variants]
        heights = [e if e is not None and e > 0 else np.nan for e in errors]
        ax.bar(range(len(variants)), heights, color=[f"C{k}" for k in range(len(variants))])
        ax.set_yscale("log")
        ax.set_xticks(range(len(variants)), variants, rotation=30, fontsize=8)
        for k, v in enumerate(variants):
            totals = runs[v].get("slide") or runs[v].get("run") or {}
            ratio = totals.get("first_over_second")
            if ratio is not None and np.isfinite(heights[k]):
                ax.annotate(f"{ratio:.2g}", (k, heights[k]), ha="center", va="bottom", fontsize=7)
        label = "stress error (fraction)" if scene == "compression" else "relative error"
        ax.set_ylabel(label)
        ax.set_title(_title(scene, payload), fontsize=9)
    fig.suptitle(
        "lr variants: error (bars) and first/second correction impulse (labels)", fontsize=9
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110)


BENCHMARK = register(
    Benchmark(NAME, __doc__, MODES, measure, plot=plot, record=name_unless("full", NAME))
)
run = BENCHMARK.run
