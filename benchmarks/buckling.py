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
  crown) with ``scene.set_friction("plate", "outer_ring", PLATE_MU)`` and the rings at mu.
  Measured (``records/buckling_plate_quick.json``, rerun at b49aa3b with the friction loop's
  stall rule, 610 s on 2 loaded cores): the plate touches only the top 4 crown nodes at
  u = 0.2 m (the 2 m thick ring does not flatten like a Hertz contact) and holds them (0 m of
  slip, against 6 mm frictionless); the detachment at u = 3 m is 0.162 m (mu = 0) and 0.144 m
  (0.2) against 0.330 and 0.315 m with the cap, at 11x and 16x the Newton iterations (5354 and
  14859 against 481 and 916); mu = 0.5 stops with MAX_ITERATIONS at its last step, u = 2.95 m
  (||p|| / dt = 8.2 m/s after 500 iterations). Hence the cap. Before, at d3e77a1, mu = 0.5
  stopped at u = 1.45 m (6.0 m/s); that stall went with a solver change between d3e77a1 and
  30a3b59, not singled out (restarted from a checkpoint at u = 1.40 m, that step converged in
  144 iterations). The stall at u = 2.95 m is not examined. ``--mode plate_partial`` (the
  partial discretisation to u = 7 m with the plate, Newton cap 2000;
  ``records/buckling_plate_partial.json`` / ``.png``, run at 30a3b59, before the stall rule,
  and not rerun since: one mu per process on 2 cores, 340 s, 1193 s and 1343 s, 13785, 63217
  and 71330 Newton iterations, 286 MB peak) shows the paper's picture more clearly than the cap: the
  inner ring snaps through at u = 4.8-5 m for mu = 0 and 0.2 (detachment 0.24 m at u = 4 m, 1.42 m
  at 6 m for mu = 0; 0.21 and 0.87 m for mu = 0.2) and runs to 2.24 and 1.48 m at u = 7 m, while at
  mu = 0.5 it stays flatter and peaks at 0.51 m near u = 6 m, then 0.40 m at 6.5 m and 0.47 m at 7
  m. By the measure above u_buckle = 5.00, 5.15 and 5.85 m: mu = 0.5 crosses the threshold by 0.01 m
  for about 0.3 m of travel, so it still counts as buckled. Full mode with the plate
  (``--mode plate_full``: the full discretisation, dt and travel with the plate, Newton cap
  2000 as in partial mode) is the paper's experiment itself. It takes hours per mu on 2 cores,
  so its cases are resumable: ``python -m benchmarks buckling --mode plate_full --mu 0.5
  --budget-s 7200 --resumable --out DIR`` checkpoints the case in ``DIR/cases/`` every
  ``CHECKPOINT_EVERY`` steps and at the budget, and the same command goes on from there, in a
  later session too when ``DIR`` is kept (``benchmarks._case_checkpoint``; the segments
  together equal one uninterrupted run bit for bit, ``tests/benchmarks/test_buckling_resume.py``);
  ``merge`` joins the per-mu records. Recorded (``benchmarks/records/buckling_plate_full/``,
  merged from ``records/buckling_plate_full_runs/mu<mu>/``, one mu per process on 2 cores, 1
  BLAS thread each, CHOLMOD on OpenBLAS; every segment's seconds in the case's
  ``progress.json``): u_buckle = 5.24 m (mu = 0), 5.57 m (mu = 0.2) and none for mu = 0.5,
  whose detachment peaks at 0.41 m (u = 7.48 m) and ends at 0.35 m: the paper's result, mu = 0
  first, 0.2 later, 0.5 not at all. Detachment at u = 4, 5, 6, 7 and 8 m: 0.21, 0.37, 1.08,
  2.12 and 1.60 m (mu = 0, peak 2.54 m at 7.28); 0.16, 0.27, 0.72, 1.11 and 1.48 m (0.2); 0.07,
  0.19, 0.36, 0.40 and 0.35 m (0.5). Case time 6616 s (mu = 0, three segments), 19,181 s
  (0.2, three) and 25,232 s (0.5, five), 51,029 s in all; 98,155, 234,931 and 312,532 Newton
  iterations; closest approach 0.96-0.97 mm (dhat 1 mm); 444 MB peak. The segments are not all
  of one commit: from 25a03e5 the friction loop stops when it stalls
  (``bfemp.steppers._barrier_solve.stalled``) instead of running to its cap of 20, which
  changes the steps where it does not converge; before it, at mu = 0 from u = 3.2 m on, the
  loop reached its cap on most steps (20 minimisations, up to 902 Newton iterations a step).
  Steps 0-440 of mu = 0 and 0-380 of mu = 0.5 ran on 9cd6176, the rest of them and all of mu =
  0.2 on 25a03e5's library code, so the record is not one run bit for bit. Cost per step,
  measured: mu = 0 took 58-113 s from u = 4.2 to 4.4 m (the loop at its cap), then 4.3 s to
  4.6 m and about 1.3 s to the end (on 25a03e5; the state got cheaper, not only the loop: the
  stall rule replayed from the u = 4.2 m checkpoint cut three steps from 902 to 245-422 Newton
  iterations, while the steps from u = 4.4 m took 76 and fewer). mu = 0.5 takes 30-45 s a step
  from u = 2.8 m (435-650 Newton iterations), 36-54 s from u = 5 m (420-700) and 42 s on
  average from 6.62 m to the end; mu = 0.2 12-15 s to u = 3 m, 20-46 s from there to 5.45 m
  and 28 s on average from 5.45 m to the end (it did not get cheaper after buckling as mu = 0
  did). In the last segments the loop stopped on its stall rule in 61 of mu = 0.5's 138 steps
  and in 81 of mu = 0.2's 255, never at its cap. In mu = 0.5's steps the loop converges in 5-6
  re-lags (to u = 3.8 m); the cost is the step's first solve, 235-336 Newton iterations at
  step sizes 1e-7 to 0.1 (Armijo backtracking, 3-19 trials, below CCD bounds of 0.02-0.7). Its
  steepest components are grid nodes of 1e-9 of the largest node mass, but holding every
  unknown below 1e-4 of it fixed left the count as it was (409, 244 and 331 against 297, 243
  and 263 for the three steps from u = 2.8 m): the cause is not found.
- Feet: the outer ring's nodes on y = 0 are fixed (level sets act on MPM grid nodes only); the
  inner ring's feet are held by two sticky level-set boxes ``9 <= |x| <= 13, -2 <= y <= 0``; a
  slip box ``|x| <= 9, -2 <= y <= 0`` lies under the middle. One scripted motion serves the cap
  and the fixed feet (``_CapAndFeet``).
- Particles: ``bfemp.sample.mesh`` of a fine inner-ring mesh at the grid's sub-cell centres,
  PPC 9 in full mode (9898 particles; the paper's 10261 at dx = 0.25 m is 9.3 per cell); the
  MPM grid origin shifted by a quarter of the particle spacing (see ``benchmarks.rings``).
- Full mode: dx = 0.25 m, PPC 9, FEM mesh size ``FULL_FEM_H`` (close to the paper's 2714
  vertices), the paper's dt, run to u = 8 m (800 steps per mu). Recorded
  (``benchmarks/records/buckling.json`` / ``.png``, at fdead73, one mu per process, the three
  side by side on 2 cores, one thread each; 757 MB peak): every case reaches u = 8 m with the
  rings never closer than 9.7e-4 m (< dhat: in contact, never touching). u_buckle = 3.52 m
  (mu = 0), 3.73 m (0.2) and 4.00 m (0.5); the detachment at u = 8 m is 2.04, 1.36 and
  0.86 m. So mu 0 buckles first and 0.2 later, as in the paper, but by this measure mu = 0.5
  buckles too, 0.27 m after mu = 0.2, where the paper's does not buckle at all: its inner ring
  ends in a flatter shape than the others (the figure) with a detachment that stops growing
  near 0.8 m after u = 6 m. Cost: 537 s, 1735 s and 2370 s of case time; 3925, 17160 and
  23856 Newton iterations; the lagged-friction loop stops at its cap of 20 in 59 (mu = 0.2)
  and 67 (mu = 0.5) of the 800 steps.
- Quick mode: dx = 0.5 m, PPC 4 (1104 particles), FEM h = 0.5 m (537 vertices), dt = 5e-2 s
  (5 cm of push per step; the loading is quasi-static: waves cross the ring in 0.1 s), to
  u = 3 m. (Before eed4f00 the mu = 0.5 run stopped with MAX_ITERATIONS at u = 3.9 m, hence
  u = 3 m; it now reaches 7 m, see partial mode.)
- Partial mode (``--mode partial``): the quick discretisation and dt pressed to u = 7 m, with a
  Newton cap of 2000, for u_buckle at a coarse resolution. At dt = 2e-2 s, mu = 0 buckles at
  u = 3.92 m; the friction cases stopped with MAX_ITERATIONS at u = 0.34 m and 0.36 m at
  cc5084f (the 2-cycle below); mu = 0.2 now passes u = 1.2 m (checked, 60 steps).
  Recorded (``benchmarks/records/buckling_partial.json``, 85 s on 2 loaded cores, rerun at
  b49aa3b with the friction loop's stall rule): every case reaches u = 7 m; u_buckle = 3.95 m
  (mu = 0), 4.05 m (mu = 0.2) and 4.35 m (mu = 0.5), and the detachment at u = 7 m is 1.97,
  1.35 and 0.77 m: the full mode's ordering at this coarse resolution (before the stall rule,
  at 10db032: the same u_buckle, 1.97, 1.35 and 0.73 m, and 1316, 3165 and 5180 Newton
  iterations against 1319, 2312 and 3266 now). (Before eed4f00, a Newton 2-cycle of the
  near-solution rule stopped mu = 0.2 at u = 6.65 m and mu = 0.5 at u = 3.85 m with MAX_ITERATIONS.)
- Newton iteration cap 500 (partial mode 2000); lagged-friction loop capped at 20 iterations
  (the default). The loop stops earlier when it stalls (``bfemp.steppers._barrier_solve``):
  quick mode logs "friction loop stalled" in 7 of its 120 friction steps and goes on, as the
  library does, and never reaches the cap (before the stall rule it did, on about 10 steps).
"""

from __future__ import annotations

import argparse
import logging
import math
import time
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

import bfemp
from benchmarks._case_checkpoint import CaseCheckpoint
from benchmarks.common import cases_by_mu, environment, note_merge, peak_memory_mb, write_json
from benchmarks.runner import Benchmark, register

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
    if cfg.get("pusher", "cap") == "plate":
        scene.add_fem(
            outer,
            material=material,
            prescribed=bfemp.motion.Fixed(),
            prescribed_nodes=feet,
            name="outer_ring",
        )
        # the plate starts half d-hat above the crown's arc (radius OUTER_RADII[1]) and at least
        # half d-hat clear of the barrier of the mesh's highest node: the full mesh has no node
        # on the crown's top, its highest two are 0.33 mm below the arc (0.83 mm from the plate,
        # inside d-hat = 1 mm, which the scene refuses at the start); the quick mesh's highest
        # is 1.9 mm below it, where the first rule holds
        bottom = max(OUTER_RADII[1] + 0.5 * DHAT, p[:, 1].max() + 1.5 * DHAT)
        plate = bfemp.shapes.rectangle(
            (-PLATE_HALF_WIDTH, bottom),
            (PLATE_HALF_WIDTH, bottom + PLATE_THICKNESS),
            h=cfg["fem_h"],
        )
        down = bfemp.motion.Linear(velocity=(0.0, -SPEED))
        scene.add_fem(plate, material=material, prescribed=down, name="plate")
    else:
        cap = (np.linalg.norm(p, axis=1) > OUTER_RADII[1] - 1e-6) & (
            np.abs(p[:, 0]) <= CAP_HALF_WIDTH
        )
        # the cap's lowest node is far above the feet: split the two at half the inner radius
        scene.add_fem(
            outer,
            material=material,
            prescribed=_CapAndFeet(SPEED, 0.5 * OUTER_RADII[0]),
            prescribed_nodes=feet | cap,
            name="outer_ring",
        )
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
    if cfg.get("pusher", "cap") == "plate":
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
    sim = bfemp.Simulation(
        _scene(cfg, mu),
        integrator="backward_euler",
        transfer="apic",
        dt=cfg["dt"],
        tol=TOL,
        max_newton_iterations=cfg["max_newton"],
    )
    measure = Detachment(sim.state.mpm_x, sim.state.fem_x, cfg["dx"])
    steps = round(cfg["u_end"] / (SPEED * cfg["dt"]))
    progress = {
        "u": [0.0],
        "detach": [0.0],
        "angle": [90.0],
        "newton": 0,
        "friction_max": 0,
        "min_d": None,
        "error": None,
        "segments_s": [],
    }
    if checkpoint is not None and checkpoint.exists():
        progress = checkpoint.restore(sim)
    u, detach, angle = progress["u"], progress["detach"], progress["angle"]
    newton, friction_max = progress["newton"], progress["friction_max"]
    min_d = math.inf if progress["min_d"] is None else progress["min_d"]
    error, cut = progress["error"], False
    segments, first_step = progress["segments_s"], sim.state.step
    started = time.perf_counter()

    def save(done_segments: list[float] | None = None) -> None:
        if checkpoint is not None:
            checkpoint.save(
                sim,
                {
                    "u": u,
                    "detach": detach,
                    "angle": angle,
                    "newton": newton,
                    "friction_max": friction_max,
                    "min_d": min_d if math.isfinite(min_d) else None,
                    "error": error,
                    "segments_s": done_segments or [*segments, time.perf_counter() - started],
                },
            )

    for k in range(sim.state.step, steps if error is None else 0):
        try:
            report = sim.step()
        except bfemp.StepError as err:
            error = str(err)
            log.warning("buckling mu=%g: %s", mu, err)
            break
        newton += report.newton_iterations
        friction_max = max(friction_max, report.friction_iterations)
        if np.isfinite(report.min_distance):
            min_d = min(min_d, report.min_distance)
        d, a = measure(sim.state.mpm_x, sim.state.fem_x)
        u.append(SPEED * sim.state.t)
        detach.append(d)
        angle.append(a)
        elapsed = time.perf_counter() - started
        if (k + 1) % PROGRESS_EVERY == 0:
            log.info(
                "buckling mu=%g: step %d/%d, u = %.2f m, detachment %.4f m, %d Newton, %.0f s",
                mu,
                k + 1,
                steps,
                u[-1],
                d,
                newton,
                elapsed,
            )
        if elapsed > budget_s and k + 1 < steps:
            cut = True
            log.warning(
                "buckling mu=%g: cut at the budget of %.0f s, u = %.2f m", mu, budget_s, u[-1]
            )
            break
        if (k + 1) % checkpoint_every == 0 and k + 1 < steps:
            save()
    if sim.state.step > first_step or error != progress["error"]:  # this process ran steps
        segments = [*segments, time.perf_counter() - started]
        save(segments)
    wall = sum(segments)
    threshold = BUCKLE_FRACTION * (INNER_RADII[1] - INNER_RADII[0])
    over = np.flatnonzero(np.array(detach) > threshold)
    log.info(
        "buckling mu=%g: detachment %.4f m at u = %.2f m, %d steps, %.1f s",
        mu,
        detach[-1],
        u[-1],
        len(u) - 1,
        wall,
    )
    return {
        "mu": mu,
        "error": error,
        "cut_at_budget_s": budget_s if cut else None,
        "steps": len(u) - 1,
        "u_end_m": u[-1],
        "detachment_end_m": detach[-1],
        "u_buckle_m": float(u[over[0]]) if over.size else None,
        "newton_iterations": newton,
        "friction_iterations_max": friction_max,
        "min_distance_m": min_d if math.isfinite(min_d) else None,
        "wall_s": wall,
        "segments_s": segments,
        "particles": int(sim.model.n_particles),
        "fem_vertices": int(sim.model.n_fem_nodes),
        "fem_triangles": int(sim.model.fem_cells.shape[0]),
        "final_mpm_x": sim.state.mpm_x.tolist(),
        "final_fem_x": sim.state.fem_x.tolist(),
        "series": {"u_m": u, "detachment_m": detach, "angle_deg": angle},
    }


def _plot(runs: list[dict], cfg: dict, path: Path, title: str) -> None:
    """Detachment against plate displacement per mu, and each run's final shape."""
    fig = Figure(figsize=(12.0, 8.0), layout="constrained")
    FigureCanvasAgg(fig)
    grid = fig.add_gridspec(2, len(runs))
    ax = fig.add_subplot(grid[0, :])
    threshold = BUCKLE_FRACTION * (INNER_RADII[1] - INNER_RADII[0])
    for k, run in enumerate(runs):
        s = run["series"]
        label = f"mu = {run['mu']:g}"
        if run["u_buckle_m"] is not None:
            label += f" (buckles at u = {run['u_buckle_m']:.2f} m)"
        ax.plot(s["u_m"], s["detachment_m"], color=f"C{k}", label=label)
    ax.axhline(threshold, color="k", ls=":", lw=0.8, label="buckling threshold")
    ax.set_xlabel("plate displacement u [m]")
    ax.set_ylabel("detachment of the inner ring [m]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    for k, run in enumerate(runs):
        sub = fig.add_subplot(grid[1, k])
        fem, mpm = np.array(run["final_fem_x"]), np.array(run["final_mpm_x"])
        sub.plot(fem[:, 0], fem[:, 1], ".", ms=1.0, color="C0")
        sub.plot(mpm[:, 0], mpm[:, 1], ".", ms=1.0, color="C1")
        sub.set_aspect("equal")
        sub.set_title(f"mu = {run['mu']:g}, u = {run['u_end_m']:.2f} m", fontsize="medium")
    fig.suptitle(title)
    fig.savefig(path, dpi=110)


def run(
    mode: str = "full",
    out: str | Path = "results",
    mus: tuple[float, ...] | None = None,
    budget_s: float = math.inf,
    resumable: bool = False,
) -> dict:
    """Press the rings at each mu; write ``buckling.json``, ``buckling.png`` and the final
    shapes ``buckling_final.npz`` (``mpm_<mu>``, ``fem_<mu>``: positions in m) to ``out``.

    Args:
        mode: ``"full"`` (the paper's resolution and dt, to u = 8 m), ``"partial"`` (coarse,
            to u = 7 m), ``"quick"`` (coarse, to u = 3 m), ``"plate_quick"`` or
            ``"plate_partial"`` (quick or partial with the paper's FEM plate instead of the
            scripted cap).
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
        ``{"json": path, "png": path, **payload}``; ``payload["cases"]`` per mu. The record
        and the figure are rewritten after every case, so a stopped run keeps the cases done.
    """
    if mode not in MODES:
        raise ValueError(f"mode must be one of {sorted(MODES)}, got {mode!r}")
    cfg = MODES[mode]
    mus = MUS if mus is None else tuple(float(m) for m in mus)
    env = environment()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    runs: list[dict] = []
    for mu in mus:
        folder = out / "cases" / f"{mode}_mu{mu:g}"
        checkpoint = CaseCheckpoint(folder) if resumable else None
        runs.append(_run_one(cfg, mu, budget_s=budget_s, checkpoint=checkpoint))
        payload = _payload(mode, cfg, mus, runs, time.perf_counter() - started, env)
        path = write_json(out, NAME, payload)
        _save_shapes(runs, out / f"{NAME}_final.npz")
        png = out / f"{NAME}.png"
        _plot(runs, cfg, png, f"Semicircular rings pressed at the crown ({mode} mode)")
    return {"json": str(path), "png": str(png), **payload}


def _save_shapes(runs: list[dict], path: Path) -> None:
    arrays = {}
    for r in runs:
        arrays[f"mpm_{r['mu']:g}"] = np.asarray(r["final_mpm_x"])
        arrays[f"fem_{r['mu']:g}"] = np.asarray(r["final_fem_x"])
    np.savez_compressed(path, **arrays)


def _payload(
    mode: str, cfg: dict, mus: tuple[float, ...], runs: list[dict], wall_s: float, env: dict
) -> dict:
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
        "peak_memory_mb": peak_memory_mb(),
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
        "environment": env,
    }


def merge(records: list[str | Path], out: str | Path = "results") -> dict:
    """One record (``buckling.json``, ``.png``, ``_final.npz`` in ``out``) from records of the
    same mode whose cases ran in separate processes (each with its ``buckling_final.npz``
    beside it), cases sorted by mu; ``wall_s`` is the sum of the cases' wall times."""
    mode, loaded, runs = cases_by_mu(records, _with_shapes)
    mus = tuple(r["mu"] for r in runs)
    cfg = MODES[mode]
    payload = _payload(
        mode, cfg, mus, runs, sum(r["wall_s"] for r in runs), loaded[0]["environment"]
    )
    note_merge(payload, records, loaded)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    path = write_json(out, NAME, payload)
    _save_shapes(runs, out / f"{NAME}_final.npz")
    png = out / f"{NAME}.png"
    _plot(runs, cfg, png, f"Semicircular rings pressed at the crown ({mode} mode)")
    return {"json": str(path), "png": str(png), **payload}


def _with_shapes(path: Path, case: dict) -> dict:
    """``case`` with its final shapes from the ``buckling_final.npz`` beside its record."""
    key = f"{case['mu']:g}"
    with np.load(path.with_name(f"{NAME}_final.npz")) as shapes:
        return {**case, "final_mpm_x": shapes[f"mpm_{key}"], "final_fem_x": shapes[f"fem_{key}"]}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``--mu`` (repeatable), ``--budget-s`` and ``--resumable`` (see ``run``)."""
    group = parser.add_argument_group("buckling")
    group.add_argument(
        "--mu", type=float, action="append", help="friction between the rings (repeatable)"
    )
    group.add_argument(
        "--budget-s", type=float, default=math.inf, help="wall-time budget of each case in s"
    )
    group.add_argument(
        "--resumable",
        action="store_true",
        help="checkpoint each case in OUT/cases/ and go on from a checkpoint found there",
    )


def main_from_args(args: argparse.Namespace) -> int:
    if not args.budget_s >= 0.0:
        raise ValueError(f"--budget-s must be >= 0, got {args.budget_s}")
    summary = run(
        args.mode or "full",
        args.out,
        mus=tuple(args.mu) if args.mu else None,
        budget_s=args.budget_s,
        resumable=args.resumable,
    )
    print(f"buckling: wrote {summary['json']}")
    return 0


BENCHMARK = register(Benchmark(NAME, __doc__, MODES, None, own_run=run))
