"""``lr_compression``: two blocks compressed by 10-15 % strain, LR paper sections 4.1-4.2 (Fig. 5).

Setup (explicit_strategies.md section 2.9): 2D plane strain, a 40 x 100 mm column cut into two
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
SMM-FLIP. LR-XPIC(5) and once + XPIC(5) run under ``WatchedLRStepper`` (unchanged, each pair's
contact state recorded), and the diagnostic ``lr_xpic5_dlr_forced`` (LR-XPIC(5) with d_LR < 0
forced: contact iff approaching) against SMM-XPIC(5).

Targets (T): max |error| of LR-FLIP < 1 %, of LR-XPIC(5) < 0.5 % (paper: 1 % and 0.24 %); LR
once above LR. The paper states d_LR < 0 strictly; whether a touching interface should tolerate
d_LR ~ 0 is a choice it leaves open, not taken here. The record also carries the time per step
split into P2G, LR fits, corrections and G2P (XPIC inside G2P), the share of contact nodes and the
LR / velocity-detector time ratio (the paper reports LR about 55 % slower). Measured results
and the cause of LR-XPIC(5)'s miss: ``benchmarks/records/lr_compression_quick.md``.

``lr_contact_time`` (Fig. 2B) uses the same column (``benchmarks.lr_contact_time``).
"""

from __future__ import annotations

import logging
import math
import time
from pathlib import Path

import numpy as np

import bfemp
from benchmarks._shared import StepCost
from benchmarks.common import figure
from benchmarks.runner import Benchmark, name_unless, register
from bfemp.contact import lr as lr_contact
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
#: carries no shear, and a frictional interface can match the bonded single material (the
#: sticky alternative and why the full run stops at 15 %: ``records/lr_compression_quick.md``)
TOP_KIND = "slip"


#: the detection rules of ``WatchedLRStepper``: ``"lr"`` is the paper's (contact iff approaching
#: and d_LR < 0, eqs. 14, 24 and section 4.2's "both"); ``"forced"`` takes d_LR < 0 at every
#: contact node (contact iff approaching, eq. 14 alone, with the LR normal): a diagnostic that
#: removes the release edge d_LR = 0, not a method (the paper rejects d_LR alone and uses both)
TOUCHING = ("lr", "forced")
#: the run with d_LR < 0 forced (LR-XPIC(5), two corrections): the diagnostic of the release edge
FORCED = "lr_xpic5_dlr_forced"
#: events (changes of the set of pairs in contact) kept per watched run
MAX_EVENTS = 100


class WatchedLRStepper(LRStepper):
    """``LRStepper`` that records, every step, each contact pair's state at the second
    correction (the one the particles receive, eq. 31): the benchmark's diagnostic of the
    release edge d_LR = 0 (LR sec. 3.1, eq. 24). Nothing of the step is changed unless
    ``touching="forced"`` (``TOUCHING``).

    After each ``step``, ``last`` holds, per pair (C rows): ``key (C, 2)`` int grid indices of
    the node, ``x (C, 2)`` its position in m, ``d_lr (C,)`` the measured separation in m (eq.
    24; negative = overlapping), ``in_contact (C,)`` bool (eqs. 14 and 24, as the law decided),
    ``v_n (C,)`` the pair's relative normal velocity (v_b - v_a) . n in m/s of the provisional
    fields p^+ / m (eq. 30, negative = approaching) and ``d_n (C,)`` the normal momentum change
    the law computes, Delta p(0) . n in kg m/s per m of thickness (applied where in contact).
    """

    def __init__(self, *args: object, touching: str = "lr", **kwargs: object) -> None:
        if touching not in TOUCHING:
            raise ValueError(
                f"WatchedLRStepper: touching must be one of {TOUCHING}, got {touching!r}"
            )
        super().__init__(*args, **kwargs)
        if self.n_materials != 2 or self.options.detector != "lr":
            raise ValueError("WatchedLRStepper: two MPM materials and detector='lr' only")
        self.touching = touching
        self.last: dict[str, np.ndarray] = {}
        self._seen: list = []

    def _pairs(self, pts, grid_x, mass):  # noqa: ANN001, ANN202 (LRStepper's signature)
        planes = super()._pairs(pts, grid_x, mass)
        measured = planes.separation.copy()
        if self.touching == "forced":
            planes.separation = np.full_like(measured, -self.model.grid.dx)
        self._seen = [planes, grid_x[planes.node], measured]
        return planes

    def _correct(self, planes, mass, mom, kinematic):  # noqa: ANN001, ANN202
        out = super()._correct(planes, mass, mom, kinematic)
        self._seen[3:] = [mass, mom]  # the last call of a step is the second correction
        return out

    def step(self, state: bfemp.State) -> tuple[bfemp.State, object]:
        new, report = super().step(state)
        planes, node_x, measured, mass, mom = self._seen
        node, a, b = planes.node, planes.a, planes.b
        m_a, m_b = mass[a, node], mass[b, node]
        p_a, p_b = mom[a, node], mom[b, node]
        _, in_contact = lr_contact.contact_momentum(
            m_a, m_b, p_a, p_b, planes.normal, planes.separation, mu=self.mu, law="coulomb"
        )
        dp0 = (m_a[:, None] * p_b - m_b[:, None] * p_a) / (m_a + m_b)[:, None]
        v_rel = p_b / m_b[:, None] - p_a / m_a[:, None]
        dx = self.model.grid.dx
        self.last = {
            "key": np.rint(node_x / dx).astype(np.int64),
            "x": node_x,
            "d_lr": measured,
            "in_contact": in_contact,
            "v_n": np.einsum("cd,cd->c", v_rel, planes.normal),
            "d_n": np.einsum("cd,cd->c", dp0, planes.normal),
        }
        return new, report


def _switch_event(step: int, strain: float, before: dict, after: dict, dx: float) -> dict | None:
    """The pairs whose contact state changed between two steps' ``WatchedLRStepper.last``
    (matched by grid node; pairs present in one step only are left out), with their d_LR in
    cells before and after, or None when none changed."""
    code_b = before["key"][:, 0] * 1_000_003 + before["key"][:, 1]
    code_a = after["key"][:, 0] * 1_000_003 + after["key"][:, 1]
    _, ib, ia = np.intersect1d(code_b, code_a, assume_unique=True, return_indices=True)
    changed = before["in_contact"][ib] != after["in_contact"][ia]
    if not changed.any():
        return None
    ib, ia = ib[changed], ia[changed]
    return {
        "step": step,
        "strain": strain,
        "pairs": int(code_a.size),
        "in_contact": int(after["in_contact"].sum()),
        "released": [bool(not c) for c in after["in_contact"][ia]],
        "node_x_mm": (1e3 * after["x"][ia]).tolist(),
        "d_lr_cells_before": (before["d_lr"][ib] / dx).tolist(),
        "d_lr_cells": (after["d_lr"][ia] / dx).tolist(),
        "v_n_m_s": after["v_n"][ia].tolist(),
        "d_n_kg_m_s": after["d_n"][ia].tolist(),
    }


def material() -> object:
    """The paper's eq. 18 law with K = 2450 MPa, G = 940 MPa, rho = 1200 kg/m^3."""
    return BulkShearHyperelastic(K=K_BULK, G=G_SHEAR, density=RHO)


def column_scene(
    *,
    v0: float,
    interface_y: float = 0.050,
    gap: float = 0.0,
    moving_top: bool = False,
    single: bool = False,
) -> bfemp.Scene:
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
    watch: str | None = None,
    **options: object,
) -> dict:
    """Run one column to ``strain`` (or to ``stop_at_contact`` s); stress history and timings.

    ``watch`` (one of ``TOUCHING``) runs ``WatchedLRStepper`` with that detection rule and adds
    ``"switches"``: the steps at which a pair's contact state changed (``_switch_event``, the
    first ``MAX_EVENTS``), their count, and the smallest |d_LR| in cells met at a pair in contact.
    """
    model = scene.build()
    lr_options = LROptions(**options)
    if watch is None:
        stepper = LRStepper(model, dt="auto", transfer=transfer, options=lr_options)
    else:
        stepper = WatchedLRStepper(
            model, dt="auto", transfer=transfer, options=lr_options, touching=watch
        )
    state = stepper.initialize(model.initial_state())
    events: list[dict] = []
    n_switch_steps = held_open = 0
    closest = math.inf  # smallest |d_LR| (m) at a pair in contact
    previous: dict = {}
    t_end = strain * HEIGHT / v0 if stop_at_contact is None else stop_at_contact
    n_steps = int(math.ceil(t_end / stepper.dt))
    every = max(1, n_steps // samples)
    hist_t, hist_s, hist_d = [], [], []
    cost, t_detect = StepCost(), None
    started = time.perf_counter()
    for k in range(n_steps):
        state, report = stepper.step(state)
        cost.add(report)
        if t_detect is None and report.contact_pairs > 0:
            t_detect = state.t
        if watch is not None:
            last = stepper.last
            held = last["in_contact"]
            if held.any():
                closest = min(closest, float(np.abs(last["d_lr"][held]).min()))
                held_open += bool((last["d_lr"][held] >= 0.0).any())
            event = previous and _switch_event(k + 1, v0 * state.t / HEIGHT, previous, last, DX)
            if event:
                n_switch_steps += 1
                if len(events) < MAX_EVENTS:
                    events.append(event)
            previous = last
        if (k + 1) % every == 0 or k + 1 == n_steps:
            hist_t.append(state.t)
            hist_s.append(mean_stress_yy(model, state))
            if watch is not None:
                inside = (stepper.last["x"][:, 0] >= 0.0) & (stepper.last["x"][:, 0] <= WIDTH)
                d_lr = stepper.last["d_lr"][inside] / DX
                hist_d.append((float(d_lr.mean()), float(d_lr.max())) if d_lr.size else (0.0, 0.0))
    wall = time.perf_counter() - started
    out = {
        "options": dict(options),
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
        **cost.summary(),
    }
    if watch is not None:
        out["switches"] = {
            "touching": watch,
            "steps_with_a_switch": n_switch_steps,
            "events": events,
            "closest_d_lr_in_contact_cells": closest / DX,
            "steps_held_at_d_lr_nonnegative": held_open,
            # per sample, over the pairs at nodes across the column (0 <= x <= WIDTH): the mean
            # and the largest measured d_LR in cells (the largest is the pair nearest release)
            "d_lr_mean_cells": [m for m, _ in hist_d],
            "d_lr_max_cells": [x for _, x in hist_d],
        }
    return out


def stress_error(case: dict, reference: dict) -> tuple[list[float], float]:
    """Per sample (sigma - sigma_ref) / sigma_ref in %, and its largest magnitude above 1 %."""
    s, r = np.asarray(case["stress"]), np.asarray(reference["stress"])
    strain = np.asarray(case["strain"])
    err = 100.0 * (s - r) / np.where(r != 0.0, r, np.nan)
    mask = strain > MIN_STRAIN
    return [float(e) for e in err], float(np.nanmax(np.abs(err[mask])))


#: the per-pair lists of a ``_switch_event``
_EVENT_PAIR_KEYS = ("node_x_mm", "d_lr_cells_before", "d_lr_cells", "v_n_m_s", "d_n_kg_m_s")


def _d_lr_released(event: dict) -> np.ndarray:
    """``(n,)`` bool over an event's pairs: released while approaching (d_n < 0), i.e. by
    d_LR >= 0 (eq. 24) and not by separation (eq. 14)."""
    return np.asarray(event["released"], dtype=bool) & (np.asarray(event["d_n_kg_m_s"]) < 0.0)


def release_cause(runs: dict, errors: dict) -> dict:
    """The measured cause of LR-XPIC(5)'s error step (issue 40, item 5): the d_LR releases.

    A release is a pair whose contact the law ends while the pair still approaches (d_n < 0):
    by eq. 24 alone, d_LR >= 0. The interface of this column starts touching (d_LR = 0) and,
    held by contact, stays within about 1e-6 cells of d_LR = 0, where the sign is set by the
    small mismatch of the particle positions and deformation gradients. For the step a pair is
    released, its two fields take the traction-free update (the compressed faces accelerate
    towards each other, |v_n| ~ sigma dx dt / m), the particles enter each other by that one
    step's travel, and the contact law (approach stopped, never pushed apart) keeps the overlap:
    the column is shorter by it and its stress lower. Per release after ``MIN_STRAIN``: the
    step, strain, the nodes (mm), d_LR in cells the step before and at release, the overlap
    (d_LR) when contact resumes, v_n and d_n (the normal momentum change withheld for one step),
    and the error at the samples around it. ``estimated_error_change_percent`` is the change of
    the mean d_LR over the nodes across the column between those samples, as a length over the
    column's shortening (strain x HEIGHT): the stress loss a rigid overlap of that size gives.
    ``variant``: the same run with d_LR < 0 forced (``WatchedLRStepper``, ``TOUCHING``).

    Why d_LR reaches 0 (``d_lr_drift``): ``benchmarks/records/lr_compression_quick.md``.
    """
    run = runs["lr_xpic5"]
    strain = np.asarray(run["strain"])
    err = np.asarray(run["error_percent"])
    steps = np.rint(np.asarray(run["t"]) / run["dt"]).astype(np.int64)
    d_mean = np.asarray(run["switches"]["d_lr_mean_cells"])
    events = run["switches"]["events"]
    releases = []
    for i, ev in enumerate(events):
        rel = _d_lr_released(ev)
        if ev["strain"] <= MIN_STRAIN or not rel.any():
            continue
        after = events[i + 1] if i + 1 < len(events) else None
        back = None
        if after is not None and not any(after["released"]):
            back = float(min(after["d_lr_cells"]))
        j = int(np.searchsorted(steps, ev["step"]))  # first sample at or after the release
        j = min(max(j, 1), steps.size - 1)
        pick = np.flatnonzero(rel)
        releases.append(
            {
                "step": ev["step"],
                "strain": ev["strain"],
                "nodes": int(rel.sum()),
                **{key: [ev[key][k] for k in pick] for key in _EVENT_PAIR_KEYS},
                "overlap_when_contact_resumes_cells": back,
                "sample_before": {
                    "strain": float(strain[j - 1]),
                    "error_percent": float(err[j - 1]),
                },
                "sample_after": {"strain": float(strain[j]), "error_percent": float(err[j])},
                "error_change_percent": float(err[j] - err[j - 1]),
                "estimated_error_change_percent": float(
                    100.0 * (d_mean[j] - d_mean[j - 1]) * DX / (strain[j] * HEIGHT)
                ),
            }
        )
    drift = {}
    for name in ("lr_xpic5", "lr_once_xpic5", FORCED):
        sw = runs[name]["switches"]
        drift[name] = {
            "largest_d_lr_cells": float(max(sw["d_lr_max_cells"])),
            "final_mean_d_lr_cells": float(sw["d_lr_mean_cells"][-1]),
            "d_lr_releases": sum(
                1 for ev in sw["events"] if ev["strain"] > MIN_STRAIN and _d_lr_released(ev).any()
            ),
            "steps_held_at_d_lr_nonnegative": sw["steps_held_at_d_lr_nonnegative"],
        }
    above = strain > MIN_STRAIN
    first = releases[0]["strain"] if releases else math.inf
    before = above & (strain < first)
    return {
        "releases": releases,
        "max_abs_error_before_first_release_percent": (
            float(np.nanmax(np.abs(err[before]))) if before.any() else None
        ),
        "max_abs_error_percent": errors["lr_xpic5"],
        "error_change_at_releases_percent": float(sum(r["error_change_percent"] for r in releases)),
        "variant": {
            "name": FORCED,
            "touching": "forced",
            "max_abs_error_percent": errors[FORCED],
        },
        # why the interface reaches d_LR = 0 with two corrections and not with one: per watched
        # run, the largest and the final mean d_LR (cells) across the column, the releases
        # after MIN_STRAIN, and the steps a pair was held in contact at d_LR >= 0 (forced only)
        "d_lr_drift": drift,
    }


def compression(mode: str) -> dict:
    """Fig. 5: the stress error of each detector against the single-material run."""
    frac, strain = MODES[mode]
    v0 = frac * C_K
    single = {"single": True}
    runs = {  # name -> (column_scene options, run_case options)
        "smm_flip": (single, {}),
        "smm_xpic5": (single, {"xpic_order": 5}),
        # the paper's two corrections (lr's default is one since issue 40)
        "lr_flip": ({}, {"corrections": 2}),
        "lr_xpic5": ({}, {"xpic_order": 5, "corrections": 2, "watch": "lr"}),
        "lr_once": ({}, {"corrections": 1}),
        "lr_once_xpic5": ({}, {"corrections": 1, "xpic_order": 5, "watch": "lr"}),
        "velocity": ({}, {"detector": "velocity", "corrections": 2}),
        "cp_0.8": ({}, {"detector": "cp", "cp_offset": 0.8, "corrections": 2}),
        # the diagnostic variant of the release edge (``TOUCHING``, ``release_cause``)
        FORCED: ({}, {"xpic_order": 5, "corrections": 2, "watch": "forced"}),
    }
    results = {}
    for name, (scene_kw, opts) in runs.items():
        log.info("lr_compression %s: %s", mode, name)
        results[name] = run_case(column_scene(v0=v0, **scene_kw), strain=strain, v0=v0, **opts)
    errors = {}
    for name, (scene_kw, opts) in runs.items():
        if scene_kw is not single:  # against the single material of the same particle update
            ref = results["smm_xpic5" if "xpic_order" in opts else "smm_flip"]
            results[name]["error_percent"], errors[name] = stress_error(results[name], ref)
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
        "cause": release_cause(results, errors),
    }


def plot(record: dict, path: Path) -> None:
    """Fig. 5: the stress error against strain per detector (all; the LR runs zoomed, with
    LR-XPIC(5)'s d_LR releases marked, ``release_cause``), and the stresses themselves."""
    fig, (ax, zx, bx) = figure((15, 4.4), 1, 3)
    comp = record["compression"]
    names = ("lr_flip", "lr_xpic5", "lr_once", "velocity", "cp_0.8", "lr_once_xpic5", FORCED)
    color = {name: f"C{k}" for k, name in enumerate(names)}
    for name in names[:5]:
        run = comp["runs"][name]
        ax.plot(100 * np.asarray(run["strain"]), run["error_percent"], label=name, c=color[name])
    ax.axhline(TOL_LR, color="k", lw=0.6, ls="--")
    ax.axhline(-TOL_LR, color="k", lw=0.6, ls="--")
    ax.set(xlabel="strain (%)", ylabel="stress error vs single material (%)", ylim=(-15, 15))
    ax.legend(fontsize=8)
    for name in ("lr_flip", "lr_once", "lr_xpic5", "lr_once_xpic5", FORCED):
        run = comp["runs"][name]
        label = "lr_xpic5, d_LR < 0 forced" if name == FORCED else name
        zx.plot(100 * np.asarray(run["strain"]), run["error_percent"], label=label, c=color[name])
    for k, rel in enumerate(comp["cause"]["releases"]):
        zx.axvline(100 * rel["strain"], color="r", lw=0.6, ls=":")
        zx.annotate(
            f"step {rel['step']}: {rel['nodes']} nodes released, d_LR "
            f"{max(rel['d_lr_cells']):+.1e} cells;\nerror {rel['error_change_percent']:+.2f} %, "
            f"overlap {rel['overlap_when_contact_resumes_cells'] or 0.0:.3f} cells",
            (100 * rel["strain"], rel["sample_after"]["error_percent"]),
            xytext=(0.03, 0.52 - 0.12 * (k % 4)),
            textcoords="axes fraction",
            fontsize=6.5,
            color="r",
            arrowprops={"arrowstyle": "->", "color": "r", "lw": 0.5},
        )
    zx.axhline(TOL_XPIC, color="k", lw=0.6, ls="--")
    zx.axhline(-TOL_XPIC, color="k", lw=0.6, ls="--")
    zx.set(xlabel="strain (%)", ylim=(-1.6, 0.6))
    zx.set_title("LR runs; dotted: LR-XPIC(5)'s d_LR releases", fontsize=9)
    zx.legend(fontsize=6.5, loc="lower right")
    for name, run_ in comp["runs"].items():
        bx.plot(100 * np.asarray(run_["strain"]), -1e-6 * np.asarray(run_["stress"]), label=name)
    bx.set(xlabel="strain (%)", ylabel="mean -sigma_yy (MPa)")
    bx.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def measure(mode: str, cfg: tuple) -> dict:
    """The column's setup and every run of ``mode`` (``compression``)."""
    return {
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
        },
        "compression": compression(mode),
    }


BENCHMARK = register(
    Benchmark(NAME, __doc__, MODES, measure, plot=plot, record=name_unless("full", NAME))
)
run = BENCHMARK.run
