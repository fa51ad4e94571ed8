"""Buckling under friction (BFEMP paper, section 6.6, figure 15): a semicircular MPM ring inside a
semicircular FEM ring, the outer ring pressed down at its crown; friction between the rings
delays the inner ring's buckling.

Setup (paper): outer semicircular FEM ring, radii 12 m to 14 m; inner semicircular MPM ring,
radii 10 m to 11.99 m, grid dx = 0.25 m; both Neo-Hookean, E = 1e6 Pa, nu = 0.3,
rho = 100 kg/m^2; no gravity. The outer ring is pressed down at 1 m/s at its crown; the feet of
both rings are held (no-slip); a slip boundary lies under the middle. Barrier dhat = 1e-3 m,
kappa = 1e5 Pa, eps_v = 1e-5 m/s; backward Euler, dt = 1e-2 s, Newton tolerance 1e-4 m/s;
mu between the rings 0, 0.2 and 0.5. APIC transfer.

Buckling measure. The inner ring buckles by snapping through inwards: its crown runs ahead of
the outer ring and separates from it (measured: with mu = 0 the separation grows slowly to
u = 4 m, then fast). ``detachment(u)`` is, at plate displacement u (m), the largest increase
over the inner ring's outer-rim particles (those within 0.3 dx of the largest initial radius)
of the distance from the particle to the outer ring's deformed inner boundary (the polyline
through its inner-surface nodes), relative to the same distance at t = 0. The buckling
displacement ``u_buckle`` is the first u at which the detachment exceeds ``BUCKLE_FRACTION`` =
0.25 of the inner ring's thickness (1.99 m), None when it does not within the run.

Targets: full mode, u_buckle(0) < u_buckle(0.2) and mu = 0.5 not buckled (None) or later still;
quick mode, the ordering of the measure at a fixed displacement: detachment(mu = 0) >
detachment(0.2) > detachment(0.5) at the end of the run (u = 3 m).

Choices where the paper is silent or the library forces a change (recorded in the JSON):

- The plate. The paper presses a FEM plate with mu = 10 to the outer ring, "a BFEMP based
  no-slip boundary condition". By default the no-slip push is applied directly instead: the
  outer ring's outer-surface nodes with ``|x| <= CAP_HALF_WIDTH`` = 4 m (the plate's contact
  half-width sqrt(2 R u) at u = 0.6 m) are scripted down at 1 m/s (the "cap"). Beyond u = 0.6 m
  a flat plate would flatten a wider crown. ``--mode plate_quick`` runs the paper's plate
  (``PLATE_HALF_WIDTH`` x ``PLATE_THICKNESS``, scripted down at 1 m/s, half d-hat above the
  crown) with ``scene.set_friction("plate", "outer_ring", PLATE_MU)`` and the rings at mu; it
  costs 11x to 16x the Newton iterations of the cap, hence the cap. ``plate_partial`` and
  ``plate_full`` run the plate at the partial and full discretisations; ``--resumable`` (see
  ``measure``) lets a case run over several sessions, and ``merge`` joins per-mu records.
- Feet: the outer ring's nodes on y = 0 are fixed (level sets act on MPM grid nodes only); the
  inner ring's feet are held by two sticky level-set boxes ``9 <= |x| <= 13, -2 <= y <= 0``; a
  slip box ``|x| <= 9, -2 <= y <= 0`` lies under the middle. One scripted motion serves the cap
  and the fixed feet (``_CapAndFeet``).
- Particles: ``bfemp.sample.mesh`` of a fine inner-ring mesh at the grid's sub-cell centres,
  PPC 9 in full mode (9898 particles; the paper's 10261 at dx = 0.25 m is 9.3 per cell); the
  MPM grid origin shifted by a quarter of the particle spacing (see ``benchmarks.rings``).
- Modes (``MODES``): full at the paper's grid and dt (FEM mesh ``FULL_FEM_H``, close to the
  paper's 2714 vertices) to u = 8 m; quick coarsens grid, mesh and dt (5 cm of push per step:
  the loading is quasi-static, waves cross the ring in 0.1 s) to u = 3 m; partial presses the
  quick discretisation to u = 7 m for u_buckle. The lagged-friction loop stops at 20 iterations
  (the default) or earlier when it stalls (``bfemp.steppers._barrier_solve``).

Measured results, with the commits they ran on: ``benchmarks/records/buckling.md``.
"""

from __future__ import annotations

import argparse
import logging
import math
import time
from pathlib import Path

import numpy as np

import bfemp
from benchmarks import catalogue
from benchmarks._case_checkpoint import CaseCheckpoint
from benchmarks.common import cases_by_mu, figure, log_row, note_merge, save
from benchmarks.runner import Benchmark, name_unless, register, write_record

log = logging.getLogger(__name__)

NAME = "buckling"
OUTER_RADII = (12.0, 14.0)  # m
INNER_RADII = (10.0, 11.99)  # m
MATERIAL = dict(E=1e6, nu=0.3, density=100.0)  # Pa, -, kg/m^2
SPEED = 1.0  # m/s, the plate
DHAT, KAPPA, EPS_V = 1e-3, 1e5, 1e-5  # m, Pa, m/s
TOL = 1e-4  # m/s
CAP_HALF_WIDTH = 4.0  # m
BUCKLE_FRACTION = 0.25  # of the inner ring's thickness
MUS = (0.0, 0.2, 0.5)
PAPER = {
    "outer_vertices": 2714,
    "outer_triangles": 5067,
    "inner_particles": 10261,
    "result": "mu 0 buckles first, 0.2 later, 0.5 not at all",
}
FULL_FEM_H = 0.2  # m: 2772 vertices, 5093 triangles (paper 2714 / 5067)

MODES = {
    "full": dict(dx=0.25, ppc=9, fem_h=FULL_FEM_H, dt=1e-2, u_end=8.0, max_newton=500),
    # the quick discretisation at a smaller dt, pressed far enough for u_buckle
    "partial": dict(dx=0.5, ppc=4, fem_h=0.5, dt=5e-2, u_end=7.0, max_newton=2000),
    "quick": dict(dx=0.5, ppc=4, fem_h=0.5, dt=5e-2, u_end=3.0, max_newton=500),
}
# the paper's pusher: a FEM plate at mu = PLATE_MU (scene.set_friction), quick discretisation
MODES["plate_quick"] = dict(MODES["quick"], pusher="plate")
MODES["plate_partial"] = dict(MODES["partial"], pusher="plate")
# the paper's experiment: full resolution with the plate, hours per mu on 2 cores (resumable)
MODES["plate_full"] = dict(MODES["full"], pusher="plate", max_newton=2000)
PLATE_MU = 10.0  # the paper's plate-ring friction ("a BFEMP based no-slip boundary condition")
PLATE_HALF_WIDTH, PLATE_THICKNESS = 6.0, 1.0  # m
PROGRESS_EVERY = 20  # steps between progress lines in the log
CHECKPOINT_EVERY = 20  # steps between a resumable case's checkpoints


class _CapAndFeet(bfemp.motion.Motion):
    """Scripted nodes of the outer ring: those above ``y_split`` (the cap) move down at ``speed``
    (m/s), the others (the feet) stay fixed. Positions and velocities ``(n, d)``."""

    def __init__(self, speed: float, y_split: float) -> None:
        self.speed, self.y_split = float(speed), float(y_split)

    def __repr__(self) -> str:  # by value: the model fingerprint of a checkpoint reads it
        return f"_CapAndFeet(speed={self.speed!r}, y_split={self.y_split!r})"

    def positions(self, x0: np.ndarray, tau: float) -> np.ndarray:
        x = np.array(x0, dtype=np.float64, copy=True)
        x[x[:, 1] > self.y_split, 1] -= self.speed * tau
        return x

    def velocities(self, x0: np.ndarray, tau: float) -> np.ndarray:
        x0 = np.asarray(x0, dtype=np.float64)
        v = np.zeros_like(x0)
        v[x0[:, 1] > self.y_split, 1] = -self.speed
        return v


def _scene(cfg: dict, mu: float) -> bfemp.Scene:
    """Both rings about the origin, feet on y = 0, the cap of the outer ring scripted (or, with
    ``cfg["pusher"] == "plate"``, a scripted FEM plate at mu = ``PLATE_MU`` on the crown)."""
    material = bfemp.NeoHookean(**MATERIAL)
    scene = bfemp.Scene(dim=2)
    outer = bfemp.shapes.semicircular_ring((0.0, 0.0), *OUTER_RADII, h=cfg["fem_h"])
    p = outer.points
    feet = p[:, 1] < 1e-9
    plate = cfg.get("pusher", "cap") == "plate"
    if plate:
        motion, held = bfemp.motion.Fixed(), feet
    else:
        cap = (np.linalg.norm(p, axis=1) > OUTER_RADII[1] - 1e-6) & (
            np.abs(p[:, 0]) <= CAP_HALF_WIDTH
        )
        # the cap's lowest node is far above the feet: split the two at half the inner radius
        motion, held = _CapAndFeet(SPEED, 0.5 * OUTER_RADII[0]), feet | cap
    scene.add_fem(
        outer, material=material, prescribed=motion, prescribed_nodes=held, name="outer_ring"
    )
    if plate:
        # the plate starts half d-hat above the crown's arc (radius OUTER_RADII[1]) and at least
        # half d-hat clear of the barrier of the mesh's highest node: the full mesh has no node
        # on the crown's top, its highest two are 0.33 mm below the arc (0.83 mm from the plate,
        # inside d-hat = 1 mm, which the scene refuses at the start); the quick mesh's highest
        # is 1.9 mm below it, where the first rule holds
        bottom = max(OUTER_RADII[1] + 0.5 * DHAT, p[:, 1].max() + 1.5 * DHAT)
        plate_mesh = bfemp.shapes.rectangle(
            (-PLATE_HALF_WIDTH, bottom),
            (PLATE_HALF_WIDTH, bottom + PLATE_THICKNESS),
            h=cfg["fem_h"],
        )
        down = bfemp.motion.Linear(velocity=(0.0, -SPEED))
        scene.add_fem(plate_mesh, material=material, prescribed=down, name="plate")
    dx, ppc = cfg["dx"], cfg["ppc"]
    shape = bfemp.shapes.semicircular_ring((0.0, 0.0), *INNER_RADII, h=0.25 * dx)
    particles, volumes = bfemp.sample.mesh(shape, dx=dx, ppc=ppc)
    scene.add_mpm(particles, volumes, material=material, name="inner_ring")
    shift = dx / (4.0 * round(math.sqrt(ppc)))
    scene.set_grid(dx=dx, origin=(shift, shift))
    box = bfemp.levelset.Box
    scene.add_boundary(box(lower=(9.0, -2.0), upper=(13.0, 0.0)), kind="sticky")
    scene.add_boundary(box(lower=(-13.0, -2.0), upper=(-9.0, 0.0)), kind="sticky")
    scene.add_boundary(box(lower=(-9.0, -2.0), upper=(9.0, 0.0)), kind="slip")
    scene.set_contact(dhat=DHAT, kappa=KAPPA, mu=mu, eps_v=EPS_V)
    if plate:
        scene.set_friction("plate", "outer_ring", PLATE_MU)
    return scene


class Detachment:
    """The buckling measure: largest increase of the rim-to-outer-ring distance (m).

    Args:
        mpm_x0: initial particle positions ``(p, 2)`` in m.
        fem_x0: initial FEM node positions ``(n, 2)`` in m.
        dx: MPM grid spacing in m (the rim is the particles within 0.3 dx of the largest radius).
    """

    def __init__(self, mpm_x0: np.ndarray, fem_x0: np.ndarray, dx: float) -> None:
        r = np.linalg.norm(mpm_x0, axis=1)
        self.rim = np.flatnonzero(r > r.max() - 0.3 * dx)
        inner = np.flatnonzero(np.linalg.norm(fem_x0, axis=1) < OUTER_RADII[0] + 1e-6)
        self.inner = inner[np.argsort(np.arctan2(fem_x0[inner, 1], fem_x0[inner, 0]))]
        self.d0 = self.distances(mpm_x0, fem_x0)

    def distances(self, mpm_x: np.ndarray, fem_x: np.ndarray) -> np.ndarray:
        """Distance ``(k,)`` in m of each rim particle to the outer ring's inner polyline."""
        q = mpm_x[self.rim][:, None, :]
        a, b = fem_x[self.inner[:-1]][None], fem_x[self.inner[1:]][None]
        ab = b - a
        t = np.clip(((q - a) * ab).sum(-1) / (ab * ab).sum(-1), 0.0, 1.0)
        return np.linalg.norm(q - (a + t[..., None] * ab), axis=-1).min(axis=1)

    def __call__(self, mpm_x: np.ndarray, fem_x: np.ndarray) -> tuple[float, float]:
        """The detachment (m) and the polar angle (degrees) of the rim particle where it is."""
        growth = self.distances(mpm_x, fem_x) - self.d0
        k = int(np.argmax(growth))
        x, y = mpm_x[self.rim[k]]
        return float(growth[k]), math.degrees(math.atan2(y, x))


def _run_one(
    cfg: dict,
    mu: float,
    budget_s: float = math.inf,
    checkpoint: CaseCheckpoint | None = None,
    checkpoint_every: int = CHECKPOINT_EVERY,
) -> dict:
    """Press the rings to ``u_end`` at friction ``mu``; the detachment after every step.
    Stops after the step that ends past ``budget_s`` of wall time (s); the case then says
    ``cut_at_budget_s`` and ends at ``u_end_m``. With ``checkpoint`` the case is saved there
    every ``checkpoint_every`` steps, at the cut and at the end, and a checkpoint found there
    is resumed (``_case_checkpoint``): ``wall_s`` is then the sum of the ``segments_s`` of
    every process that ran the case, and ``budget_s`` bounds this process's segment."""
    sim = catalogue.paper_simulation(_scene(cfg, mu), cfg["dt"], TOL, cfg["max_newton"])
    measure = Detachment(sim.state.mpm_x, sim.state.fem_x, cfg["dx"])
    steps = round(cfg["u_end"] / (SPEED * cfg["dt"]))
    # the case's series and counters: what a checkpoint saves and a resumed run goes on from
    p = {"u": [0.0], "detach": [0.0], "angle": [90.0], "newton": 0, "friction_max": 0}
    p |= {"min_d": None, "error": None, "segments_s": []}
    if checkpoint is not None and checkpoint.exists():
        p = checkpoint.restore(sim)
    error_before, segments, first_step, cut = p["error"], p["segments_s"], sim.state.step, False
    started = time.perf_counter()

    def save(done_segments: list[float] | None = None) -> None:
        if checkpoint is not None:
            done = done_segments or [*segments, time.perf_counter() - started]
            checkpoint.save(sim, {**p, "segments_s": done})

    for k in range(sim.state.step, steps if p["error"] is None else 0):
        report, p["error"] = catalogue.step(sim, f"buckling mu={mu:g}")
        if p["error"] is not None:
            break
        p["newton"] += report.newton_iterations
        p["friction_max"] = max(p["friction_max"], report.friction_iterations)
        if np.isfinite(report.min_distance):
            known = math.inf if p["min_d"] is None else p["min_d"]
            p["min_d"] = min(known, report.min_distance)
        d, a = measure(sim.state.mpm_x, sim.state.fem_x)
        p["u"].append(SPEED * sim.state.t)
        p["detach"].append(d)
        p["angle"].append(a)
        elapsed = time.perf_counter() - started
        if (k + 1) % PROGRESS_EVERY == 0:
            log_row(log, f"buckling mu={mu:g} step {k + 1}/{steps}", {**p, "d": d}, "d newton")
        if elapsed > budget_s and k + 1 < steps:
            cut = True
            log.warning(
                "buckling mu=%g: cut at the budget of %.0f s, u = %.2f m", mu, budget_s, p["u"][-1]
            )
            break
        if (k + 1) % checkpoint_every == 0 and k + 1 < steps:
            save()
    if sim.state.step > first_step or p["error"] != error_before:  # this process ran steps
        segments = [*segments, time.perf_counter() - started]
        save(segments)
    u, detach, error = p["u"], p["detach"], p["error"]
    wall = sum(segments)
    threshold = BUCKLE_FRACTION * (INNER_RADII[1] - INNER_RADII[0])
    over = np.flatnonzero(np.array(detach) > threshold)
    log.info("buckling mu=%g: detachment %.4f m at u = %.2f m", mu, detach[-1], u[-1])
    return {
        "mu": mu,
        "error": error,
        "cut_at_budget_s": budget_s if cut else None,
        "steps": len(u) - 1,
        "u_end_m": u[-1],
        "detachment_end_m": detach[-1],
        "u_buckle_m": float(u[over[0]]) if over.size else None,
        "newton_iterations": p["newton"],
        "friction_iterations_max": p["friction_max"],
        "min_distance_m": p["min_d"],
        "wall_s": wall,
        "segments_s": segments,
        "particles": int(sim.model.n_particles),
        "fem_vertices": int(sim.model.n_fem_nodes),
        "fem_triangles": int(sim.model.fem_cells.shape[0]),
        "final_mpm_x": sim.state.mpm_x.tolist(),
        "final_fem_x": sim.state.fem_x.tolist(),
        "series": {"u_m": u, "detachment_m": detach, "angle_deg": p["angle"]},
    }


def plot(payload: dict, path: Path) -> None:
    """Detachment against plate displacement per mu, and each run's final shape."""
    runs = payload["_runs"]
    fig, axes = figure((12.0, 8.0), 2, len(runs), layout="constrained", squeeze=False)
    for top in axes[0]:  # one panel across the top row
        top.remove()
    ax = fig.add_subplot(axes[1, 0].get_gridspec()[0, :])
    threshold = BUCKLE_FRACTION * (INNER_RADII[1] - INNER_RADII[0])
    for k, run in enumerate(runs):
        s = run["series"]
        label = f"mu = {run['mu']:g}"
        if run["u_buckle_m"] is not None:
            label += f" (buckles at u = {run['u_buckle_m']:.2f} m)"
        ax.plot(s["u_m"], s["detachment_m"], color=f"C{k}", label=label)
    ax.axhline(threshold, color="k", ls=":", lw=0.8, label="buckling threshold")
    ax.set(xlabel="plate displacement u [m]", ylabel="detachment of the inner ring [m]")
    for k, run in enumerate(runs):
        sub = axes[1, k]
        fem, mpm = np.array(run["final_fem_x"]), np.array(run["final_mpm_x"])
        sub.plot(fem[:, 0], fem[:, 1], ".", ms=1.0, color="C0")
        sub.plot(mpm[:, 0], mpm[:, 1], ".", ms=1.0, color="C1")
        sub.set_aspect("equal")
        sub.set_title(f"mu = {run['mu']:g}, u = {run['u_end_m']:.2f} m", fontsize="medium")
    save(fig, path, [ax], f"Semicircular rings pressed at the crown ({payload['mode']} mode)")


def measure(
    mode: str,
    cfg: dict,
    out: Path,
    mus: tuple[float, ...] | None = None,
    budget_s: float = math.inf,
    resumable: bool = False,
) -> dict:
    """Press the rings at each mu of ``mode`` (``MODES``); the final shapes go to
    ``out/STEM_final.npz`` (``mpm_<mu>``, ``fem_<mu>``: positions in m).

    Args:
        mode, cfg: a key of ``MODES`` and its value.
        out: output folder.
        mus: friction coefficients between the rings instead of ``MUS`` (one per process, to
            run the full mode's cases side by side; ``merge`` joins their records).
        budget_s: wall time in s after which each case stops (its record then says
            ``cut_at_budget_s``; "not buckled" then means not up to its ``u_end_m``).
        resumable: checkpoint each case in ``out/cases/<mode>_mu<mu>/`` (every
            ``CHECKPOINT_EVERY`` steps, at a cut and at the end) and go on from a checkpoint
            found there: a case longer than a session runs as several budgeted segments,
            in later sessions too when the folder is kept (``_case_checkpoint``).

    Returns:
        The payload; ``payload["cases"]`` per mu. The record and the figure are written after
        every case, so a stopped run keeps the cases done.
    """
    if not budget_s >= 0.0:
        raise ValueError(f"budget_s / --budget-s must be >= 0, got {budget_s}")
    mus = MUS if mus is None else tuple(float(m) for m in mus)
    stem = BENCHMARK.stem(mode)
    out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    runs: list[dict] = []
    for mu in mus:
        checkpoint = CaseCheckpoint(out / "cases" / f"{mode}_mu{mu:g}") if resumable else None
        runs.append(_run_one(cfg, mu, budget_s=budget_s, checkpoint=checkpoint))
        payload = _payload(mode, cfg, mus, runs, time.perf_counter() - started)
        _save_shapes(runs, out / f"{stem}_final.npz")
        if len(runs) < len(mus):  # the runner writes the last one
            write_record(out, stem, payload, plot)
    return payload


def _save_shapes(runs: list[dict], path: Path) -> None:
    arrays = {}
    for r in runs:
        arrays[f"mpm_{r['mu']:g}"] = np.asarray(r["final_mpm_x"])
        arrays[f"fem_{r['mu']:g}"] = np.asarray(r["final_fem_x"])
    np.savez_compressed(path, **arrays)


def _payload(mode: str, cfg: dict, mus: tuple[float, ...], runs: list[dict], wall_s: float) -> dict:
    """The record of ``mode`` after the finished ``runs`` (in ``mus`` order)."""
    end = [r["detachment_end_m"] for r in runs]
    complete = all(r["error"] is None and r.get("cut_at_budget_s") is None for r in runs) and len(
        runs
    ) == len(MUS)
    return {
        "benchmark": NAME,
        "mode": mode,
        "cases_done": len(runs),
        "cases_planned": len(mus),
        "detachment_end_m": {str(r["mu"]): r["detachment_end_m"] for r in runs},
        "u_buckle_m": {str(r["mu"]): r["u_buckle_m"] for r in runs},
        "ordered_at_end": bool(complete and end[0] > end[1] > end[2]),
        "failed_cases": [r["mu"] for r in runs if r["error"] is not None],
        "cut_cases": [r["mu"] for r in runs if r.get("cut_at_budget_s") is not None],
        "cases": [{k: v for k, v in r.items() if not k.startswith("final_")} for r in runs],
        "wall_s": wall_s,
        "paper": PAPER,
        "targets": {
            "full": "u_buckle(0) < u_buckle(0.2); mu = 0.5 later still or not at all",
            "quick": "detachment at u_end: mu 0 > mu 0.2 > mu 0.5",
        },
        "parameters": {
            **cfg,
            "mus": mus,
            "outer_radii_m": OUTER_RADII,
            "inner_radii_m": INNER_RADII,
            "material": {"model": "NeoHookean", **MATERIAL},
            "speed_m_s": SPEED,
            "dhat_m": DHAT,
            "kappa_Pa": KAPPA,
            "eps_v_m_s": EPS_V,
            "tol_m_s": TOL,
            "integrator": "backward_euler",
            "transfer": "apic",
            "cap_half_width_m": CAP_HALF_WIDTH,
            "buckle_fraction": BUCKLE_FRACTION,
            "particles": runs[0]["particles"],
            "fem_vertices": runs[0]["fem_vertices"],
            "fem_triangles": runs[0]["fem_triangles"],
        },
        "_runs": runs,
    }


def merge(records: list[str | Path], out: str | Path = "results") -> dict:
    """One record (``buckling.json``, ``.png``, ``_final.npz`` in ``out``) from records of the
    same mode whose cases ran in separate processes (each with its ``STEM_final.npz`` beside
    it), cases sorted by mu; ``wall_s`` is the sum of the cases' wall times."""
    mode, loaded, runs = cases_by_mu(records, _with_shapes)
    mus = tuple(r["mu"] for r in runs)
    payload = _payload(mode, MODES[mode], mus, runs, sum(r["wall_s"] for r in runs))
    payload["environment"] = loaded[0]["environment"]
    note_merge(payload, records, loaded)
    Path(out).mkdir(parents=True, exist_ok=True)
    _save_shapes(runs, Path(out) / f"{NAME}_final.npz")
    return write_record(out, NAME, payload, plot)


def _with_shapes(path: Path, case: dict) -> dict:
    """``case`` with its final shapes from the ``STEM_final.npz`` beside its record."""
    key = f"{case['mu']:g}"
    with np.load(path.with_name(f"{path.stem}_final.npz")) as shapes:
        return {**case, "final_mpm_x": shapes[f"mpm_{key}"], "final_fem_x": shapes[f"fem_{key}"]}


def _arguments(group: argparse._ActionsContainer) -> None:
    """``--mu`` (repeatable), ``--budget-s`` and ``--resumable`` (see ``measure``)."""
    friction = "friction between the rings (repeatable)"
    group.add_argument("--mu", type=float, action="append", dest="mus", help=friction)
    group.add_argument("--budget-s", type=float, help="wall-time budget of each case in s")
    group.add_argument(
        "--resumable",
        action="store_true",
        help="checkpoint each case in OUT/cases/ and go on from a checkpoint found there",
    )


# the committed records of modes other than full carry the mode in their names
BENCHMARK = register(
    Benchmark(
        NAME,
        __doc__,
        MODES,
        measure,
        plot,
        record=name_unless("full", NAME),
        arguments=_arguments,
        needs_out=True,
    )
)
run = BENCHMARK.run
