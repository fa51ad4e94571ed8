"""``lr_compression``: two blocks compressed by 10-15 % strain, LR paper sections 4.1-4.2 (Fig. 5).

Setup (EXPLICIT_STRATEGIES.md section 2.9): 2D plane strain, a 40 x 100 mm column cut into two
40 x 50 mm blocks (the interface on a grid line, y = 50 mm, or mid-cell, y = 52.5 mm: the lower
block then is 52.5 mm high), the paper's hyperelastic law (eq. 18: K = 2450 MPa, G = 940 MPa;
rho = 1200 kg/m^3, pitfall L-P1), 5 mm cells, 2 x 2 particles per cell (bfemp's quadratic
B-splines; LR used GIMP), Coulomb mu = 0.2 between the blocks. The bottom grid nodes are fixed
(a sticky half-plane y <= 0); the top nodes move down at v0 with v_x free (a slip half-plane
moving at -v0; see ``TOP_KIND`` for why the full run stops at 15 %). v0 is a fraction of the
bulk wave speed c_K = sqrt(K / rho) (pitfall L-P2):
0.05 % (0.714 m/s, full) or 0.5 % (quick). The column is compressed to 15 % (full; the paper
20 %) or 10 % (quick) nominal strain u / 100 mm; dt = 0.4 dx / (c_p + |v|) (``dt="auto"``).

Metric: sigma = the volume-weighted mean particle Cauchy stress sigma_yy (current volumes
J V_p^0), error = (sigma_MM - sigma_SMM) / sigma_SMM in % against the strain; SMM is the same
particles as one material (one body) run with the same transfer. The error is taken over the
strains above 1 % (below, both stresses are a wave front's noise around zero: the compression
wave needs 57 us to cross the column, 0.4 % strain at the quick speed).

Runs (LR-FLIP, LR-XPIC(5) and the detectors with the paper's two corrections, ``corrections=2``;
lr's default is one since issue 40): LR-FLIP and "LR once" (``corrections=1``) against SMM-FLIP;
LR-XPIC(5) against
SMM-XPIC(5); the comparison detectors "velocity" (mass-gradient normals, contact when
approaching) and "cp" (constant offset 0.8 cells, GIMP-calibrated, pitfall L-P3) against
SMM-FLIP.

Targets (T): max |error| of LR-FLIP < 1 %, of LR-XPIC(5) < 0.5 % (paper: 1 % and 0.24 %); LR
once above LR. Measured (records, up to issue 40, with Uintah's contact-node threshold
``mass_fraction = 1e-8``): LR-FLIP 0.13 % (quick) and 1.00 % (full, to 15 %), LR once
0.37 / 1.63 %; LR-XPIC(5) 0.78 / 3.18 %. With LR's contact node (any mass, the default since
issue 40): quick LR-FLIP 0.33 %, LR once 0.36 %, LR-XPIC(5) 0.91 %, once + XPIC(5) 0.15 %
(the quick rate is 10x the paper's and does not test its claim); full (the paper's rate, to
15 %) LR-FLIP 0.112 %, LR once 0.107 % (so the paper's "once is worse" is not reproduced
here), LR-XPIC(5) 1.21 %, once + XPIC(5) 0.239 % (the paper's LR-XPIC(5): 0.24 %), velocity
9.9 %, cp 40 %. LR-XPIC(5) stays above its target (its step near 9 % strain is a d_LR
release, the audit of issue 40), while XPIC(5) with one correction is within it: with
B-spline stencils the first correction and the
multimaterial projection of eq. 37 do not combine as in the paper's GIMP runs (not resolved;
re-imposing the contact law on the projected field, NairnMPM's later form approximated, made it
worse: 1.9 %). The record also carries the time per step split into P2G, LR fits, corrections
and G2P (XPIC inside G2P), the share of contact nodes and the LR / velocity-detector time ratio
(the paper reports LR about 55 % slower).

``lr_contact_time`` (Fig. 2B) uses the same column (``benchmarks.lr_contact_time``).
"""

from __future__ import annotations

import logging
import math
import time
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

import bfemp
from benchmarks.common import environment, peak_memory_mb, write_json
from bfemp.materials import BulkShearHyperelastic
from bfemp.motion import Linear
from bfemp.steppers.lr import LROptions, LRStepper
from geometry.levelset import HalfPlane

log = logging.getLogger(__name__)

NAME = "lr_compression"
WIDTH, HEIGHT = 0.040, 0.100  # m
DX = 0.005  # m
PPC = 4  # 2 x 2
K_BULK, G_SHEAR, RHO = 2450e6, 940e6, 1200.0
MU = 0.2
C_K = math.sqrt(K_BULK / RHO)
#: mode -> (v0 / c_K, final strain)
MODES = {"quick": (0.005, 0.10), "full": (0.0005, 0.15)}
TOL_LR, TOL_XPIC = 1.0, 0.5  # % (T)
MIN_STRAIN = 0.01
#: the top nodes move down at v0 with v_x free (slip, the spec's reading): the interface then
#: carries no shear, and a frictional interface can match the bonded single material. Measured
#: alternative: held sideways (sticky), the column barrels, the mu = 0.2 interface slips where the
#: bonded column cannot, and LR-FLIP differs by 2.6 % at 20 % (full), a difference of physics.
#: With v_x free the column is fixed-free (Euler stress pi^2 E w^2 / (48 L^2) = 82 MPa, reached
#: at 3 % strain): the single-material column buckled at 18 % in the full run (mean stress
#: 521 -> 51 MPa), so the full run stops at 15 %.
TOP_KIND = "slip"


def material() -> object:
    """The paper's eq. 18 law with K = 2450 MPa, G = 940 MPa, rho = 1200 kg/m^3."""
    return BulkShearHyperelastic(K=K_BULK, G=G_SHEAR, density=RHO)


def column_scene(
    *, v0: float, interface_y: float = 0.050, gap: float = 0.0, moving_top: bool = False,
    single: bool = False,
) -> bfemp.Scene:  # fmt: skip
    """The two blocks (or one body when ``single``) with the fixed bottom and the moving top."""
    scene = bfemp.Scene(dim=2)
    law = material()
    top = HEIGHT + gap
    lower = bfemp.sample.box((0.0, 0.0), (WIDTH, interface_y), dx=DX, ppc=PPC)
    upper = bfemp.sample.box((0.0, interface_y + gap), (WIDTH, top), dx=DX, ppc=PPC)
    v_up = (0.0, -v0) if moving_top else (0.0, 0.0)
    if single:
        x = np.concatenate([lower[0], upper[0]])
        vol = np.concatenate([lower[1], upper[1]])
        vel = np.zeros_like(x)
        vel[lower[0].shape[0] :] = v_up
        scene.add_mpm(x, vol, material=law, velocity=vel, name="column")
    else:
        scene.add_mpm(*lower, material=law, name="lower")
        scene.add_mpm(*upper, material=law, velocity=v_up, name="upper")
    scene.add_boundary(HalfPlane(point=(0.0, 0.0), normal=(0.0, 1.0)), kind="sticky")
    scene.add_boundary(
        HalfPlane(point=(0.0, top), normal=(0.0, -1.0)),
        kind=TOP_KIND,
        motion=Linear(velocity=(0.0, -v0)),
    )
    scene.set_grid(dx=DX)
    scene.set_contact(dhat=1e-3, mu=MU)  # read by lr for mu; dhat is barrier's only
    return scene


def mean_stress_yy(model: bfemp.Model, state: bfemp.State) -> float:
    """Volume-weighted mean particle Cauchy sigma_yy in Pa (current volumes J V_p^0)."""
    F = state.mpm_F
    J = np.linalg.det(F)
    law = model.mpm_bodies[0].material
    sigma_yy = law.law.cauchy_stress(F, law.mu, law.lam)[:, 1, 1]
    vol = J * model.mpm_volume
    return float(sigma_yy @ vol / vol.sum())


def run_case(
    scene: bfemp.Scene,
    *,
    strain: float,
    v0: float,
    transfer: str = "flip",
    samples: int = 200,
    stop_at_contact: float | None = None,
    **options: object,
) -> dict:
    """Run one column to ``strain`` (or to ``stop_at_contact`` s); stress history and timings."""
    model = scene.build()
    stepper = LRStepper(model, dt="auto", transfer=transfer, options=LROptions(**options))
    state = stepper.initialize(model.initial_state())
    t_end = strain * HEIGHT / v0 if stop_at_contact is None else stop_at_contact
    n_steps = int(math.ceil(t_end / stepper.dt))
    every = max(1, n_steps // samples)
    hist_t, hist_s = [], []
    phases: dict[str, float] = {}
    contact_nodes = 0.0
    t_detect = None
    started = time.perf_counter()
    for k in range(n_steps):
        state, report = stepper.step(state)
        for name, value in report.timings.items():
            phases[name] = phases.get(name, 0.0) + value
        contact_nodes += report.extra["contact_nodes"]
        if t_detect is None and report.contact_pairs > 0:
            t_detect = state.t
        if (k + 1) % every == 0 or k + 1 == n_steps:
            hist_t.append(state.t)
            hist_s.append(mean_stress_yy(model, state))
    wall = time.perf_counter() - started
    return {
        "options": {k: v for k, v in options.items()},
        "transfer": transfer,
        "dt": stepper.dt,
        "steps": n_steps,
        "wall_s": wall,
        # LRStepper's run totals: the first and second corrections' sum |dp| (kg m/s) over the
        # steps with contact, and the windows given the LR_FIRST_CORRECTION note
        "first_correction_impulse": stepper.first_correction_impulse,
        "second_correction_impulse": stepper.second_correction_impulse,
        "first_correction_windows": stepper.first_correction_windows,
        "t": hist_t,
        "strain": [v0 * t / HEIGHT for t in hist_t],
        "stress": hist_s,
        "t_detect": t_detect,
        "ms_per_step": {k: 1e3 * v / n_steps for k, v in phases.items()},
        "mean_contact_nodes": contact_nodes / n_steps,
    }


def stress_error(case: dict, reference: dict) -> tuple[list[float], float]:
    """Per sample (sigma - sigma_ref) / sigma_ref in %, and its largest magnitude above 1 %."""
    s, r = np.asarray(case["stress"]), np.asarray(reference["stress"])
    strain = np.asarray(case["strain"])
    err = 100.0 * (s - r) / np.where(r != 0.0, r, np.nan)
    mask = strain > MIN_STRAIN
    return [float(e) for e in err], float(np.nanmax(np.abs(err[mask])))


def compression(mode: str) -> dict:
    """Fig. 5: the stress error of each detector against the single-material run."""
    frac, strain = MODES[mode]
    v0 = frac * C_K
    runs = {
        "smm_flip": (dict(single=True), "flip", {}),
        "smm_xpic5": (dict(single=True), "flip", {"xpic_order": 5}),
        # the paper's two corrections (lr's default is one since issue 40)
        "lr_flip": ({}, "flip", {"corrections": 2}),
        "lr_xpic5": ({}, "flip", {"xpic_order": 5, "corrections": 2}),
        "lr_once": ({}, "flip", {"corrections": 1}),
        "lr_once_xpic5": ({}, "flip", {"corrections": 1, "xpic_order": 5}),
        "velocity": ({}, "flip", {"detector": "velocity", "corrections": 2}),
        "cp_0.8": ({}, "flip", {"detector": "cp", "cp_offset": 0.8, "corrections": 2}),
    }
    results = {}
    for name, (scene_kw, transfer, opts) in runs.items():
        log.info("lr_compression %s: %s", mode, name)
        scene = column_scene(v0=v0, **scene_kw)
        results[name] = run_case(scene, strain=strain, v0=v0, transfer=transfer, **opts)
    errors = {}
    for name, ref in (("lr_flip", "smm_flip"), ("lr_once", "smm_flip"), ("velocity", "smm_flip"),
                      ("cp_0.8", "smm_flip"), ("lr_xpic5", "smm_xpic5"),
                      ("lr_once_xpic5", "smm_xpic5")):  # fmt: skip
        series, worst = stress_error(results[name], results[ref])
        results[name]["error_percent"] = series
        errors[name] = worst
    ratio = results["lr_flip"]["wall_s"] / results["velocity"]["wall_s"]
    return {
        "v0": v0,
        "v0_over_cK": frac,
        "final_strain": strain,
        "runs": results,
        "max_abs_error_percent": errors,
        "lr_over_velocity_wall": ratio,
        "targets": {
            "lr_flip_below_1pct": errors["lr_flip"] < TOL_LR,
            "lr_xpic5_below_0.5pct": errors["lr_xpic5"] < TOL_XPIC,
            "lr_once_above_lr": errors["lr_once"] > errors["lr_flip"],
        },
    }


def plot(record: dict, path: Path) -> None:
    """Fig. 5: the stress error against strain per detector, and the stresses themselves."""
    fig = Figure(figsize=(11, 4.2))
    FigureCanvasAgg(fig)
    ax, bx = fig.subplots(1, 2)
    comp = record["compression"]
    for name in ("lr_flip", "lr_xpic5", "lr_once", "velocity", "cp_0.8"):
        run = comp["runs"][name]
        ax.plot(100 * np.asarray(run["strain"]), run["error_percent"], label=name)
    ax.axhline(TOL_LR, color="k", lw=0.6, ls="--")
    ax.axhline(-TOL_LR, color="k", lw=0.6, ls="--")
    ax.set_ylim(-15, 15)
    ax.set_xlabel("strain (%)")
    ax.set_ylabel("stress error vs single material (%)")
    ax.legend(fontsize=8)
    for name, run_ in comp["runs"].items():
        bx.plot(100 * np.asarray(run_["strain"]), -1e-6 * np.asarray(run_["stress"]), label=name)
    bx.set_xlabel("strain (%)")
    bx.set_ylabel("mean -sigma_yy (MPa)")
    bx.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def run(mode: str, out: Path) -> dict:
    """Writes ``out/lr_compression[_quick].json`` and the PNG."""
    started = time.perf_counter()
    record = {
        "benchmark": NAME,
        "mode": mode,
        "setup": {
            "width": WIDTH,
            "height": HEIGHT,
            "dx": DX,
            "ppc": PPC,
            "K": K_BULK,
            "G": G_SHEAR,
            "rho": RHO,
            "mu": MU,
            "c_K": C_K,
            "min_strain_for_error": MIN_STRAIN,
        },  # fmt: skip
        "compression": compression(mode),
    }
    record["wall_s"] = time.perf_counter() - started
    record["peak_memory_mb"] = peak_memory_mb()
    record["environment"] = environment()
    name = NAME if mode == "full" else f"{NAME}_{mode}"
    path = write_json(out, name, record)
    plot(record, Path(out) / f"{name}.png")
    return {"json": str(path), **record}
