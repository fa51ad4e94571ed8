"""3D twist with friction (BFEMP paper, section 6.7, figures 16-17): a FEM spherical shell pressed
into the top of an MPM cube and twisted about z; friction makes the cube's top follow the shell
until it slips, later the larger mu.

Setup (paper): MPM cube of edge 1 m, grid dx = 0.0625 m, 90,929 particles, Neo-Hookean E = 1e8
Pa, nu = 0.4, rho = 100 kg/m^3; FEM spherical shell, radii 0.45 m to 0.5 m (1364 vertices, 3920
tetrahedra), E = 1e10 Pa, nu = 0.4, rho = 1e4 kg/m^3, placed d-hat above the cube. The top part
of the shell follows a rigid motion: down at 0.5 m/s for 1 s, then rotation about z at pi/5 rad/s
for 4.5 s. Barrier dhat = 1e-2 m, kappa = 1e7 Pa, eps_v = 1e-3 m/s; backward Euler, dt = 1e-2 s,
Newton tolerance 1e-3 m/s; mu = 0, 0.2, 0.5, 1.0. APIC transfer. Paper's result: slip at a
cube twist of about 0.1 pi (mu = 0, from the roughness of the particle-triangle interface),
0.3 pi (0.2), 0.7 pi (0.5), none at mu = 1.

Measures (the paper defines neither; ours):

- Twist angle of the cube's top centre, ``theta_cube(t)`` (rad): the angle of the least-squares
  rotation about the z axis (through the cube's centre) that takes the initial horizontal
  positions of the *top-centre region* to their current ones,
  ``atan2(sum (x0 x x)_z, sum x0 . x)`` over the region, unwrapped in time. The region: the
  particles of the topmost particle layer (initial z within half a particle spacing of the
  highest) whose initial distance to the z axis is below ``REGION_RADIUS`` = 0.2 m (12 particles
  in quick mode).
- The shell's angle ``theta_shell(t) = omega max(0, t - t_press)`` (the prescribed motion).
- Slip starts at the first time ``t_s`` in the twist from which the cube's top gains less than
  ``SLIP_RATE`` = 0.5 of the shell's rotation over the next ``SLIP_WINDOW_S`` = 0.05 s (the
  cube stalls; one quick-mode step, five full-mode steps); the *slip angle* is the cube's angle
  then, ``theta_cube(t_s)``: the twist the cube took while following the shell (partial slip,
  spreading in from the rim of the contact patch, lets it lag a little before). ``None`` when
  the cube follows the shell to the end of the run (no slip; larger than any angle for the
  ordering). Without friction the cube does not follow the shell at all, so its slip angle is
  its angle at the start of the twist.

Targets: full mode, slip angles within 0.1 pi of the paper's for each mu (mu = 1: no slip);
quick mode, the slip angle increases with mu (``None`` counted as the largest).

Choices where the paper is silent or contradicts itself (recorded in the JSON):

- Timeline: the text's (press 1 s at 0.5 m/s, i.e. 0.5 m as figure 16 (b) says, then twist
  4.5 s: 0.9 pi in all), not figure 17's caption (twist between 0.5 s and 5 s).
- The prescribed top part of the shell: its nodes at or above the centre's height (the upper
  hemisphere, equator included); the lower hemisphere is free (elastic, it carries the contact).
- The cube stands on a sticky level-set box (``z <= 0``, all MPM grid nodes on and below the
  cube's bottom face are held): its bottom cannot turn with the shell.
- Gravity -9.81 m/s^2 along z (negligible beside the press: the shell's 1.4 t against contact
  forces of order E times the contact area).
- Geometry: cube ``[-0.5, 0.5]^2 x [0, 1]`` on the grid (faces on grid planes), particles at
  sub-cell centres (``bfemp.sample.box``); shell centred on the z axis, its lowest node d-hat
  above the cube's top face (its centre at ``1 + dhat + 0.5`` m when the south pole is a node,
  as in every mode here; the top particle layer is half a particle spacing lower still), meshed
  by ``bfemp.shapes.spherical_shell`` (cubed sphere, one radial layer of hexahedra split into
  tetrahedra).
- Modes (``MODES``): full, the paper's dt and motion at dx = 0.0625 m with 27 particles per
  cell (110,592 particles; the paper's 90,929 is 22.2 per cell) and a shell of 1204 vertices /
  3600 tetrahedra (the paper's 1364 / 3920), its cost estimated from the full timing probe
  (``FULL_ESTIMATE``); partial and quick coarsen the grid, the shell and dt (quick also twists
  2x faster for half the time: the same 0.9 pi) and stop each case ``STOP_AFTER_SLIP_S`` after
  its slip starts (the slipping steps take many Newton iterations; mu = 1 runs to the end). The
  record is rewritten after every case, so a stopped run keeps the cases it finished.
- Timing probes (``PROBES``: the mu = 0.5 case cut at ``PROBE_BUDGET_S`` of wall time or at
  ``max_steps``, its kernels compiled first) record per-step wall and CPU time, Newton
  iterations, contact pairs and phases: measurements of cost, not results.
- Newton iteration cap 1000 per minimisation; lagged-friction loop capped at 20 updates (the
  default; a step that hits it logs "friction loop did not converge" and goes on, as the
  library does).

Measured results, with their commits: ``benchmarks/records/twist_quick.md`` (quick, partial,
the partial probe), ``benchmarks/records/twist_full_probe.md`` (the full probe and
the full mode's estimate).
"""

from __future__ import annotations

import logging
import math
import time
from pathlib import Path

import numpy as np

import bfemp
from benchmarks import catalogue
from benchmarks.common import cases_by_mu, figure, log_row, note_merge, save
from benchmarks.runner import Benchmark, name_unless, register, write_record
from geometry.mesh import TetMesh

log = logging.getLogger(__name__)

NAME = "twist"
CUBE_EDGE = 1.0  # m
CUBE = dict(E=1e8, nu=0.4, density=100.0)  # Pa, -, kg/m^3
SHELL_RADII = (0.45, 0.5)  # m
SHELL = dict(E=1e10, nu=0.4, density=1e4)  # Pa, -, kg/m^3
DHAT, KAPPA, EPS_V, TOL = 1e-2, 1e7, 1e-3, 1e-3  # m, Pa, m/s, m/s
PRESS_SPEED, PRESS_TIME = 0.5, 1.0  # m/s, s
GRAVITY = -9.81  # m/s^2 along z
REGION_RADIUS = 0.2  # m
SLIP_WINDOW_S, SLIP_RATE = 0.05, 0.5
STOP_AFTER_SLIP_S = 0.15  # s
MAX_NEWTON = 1000
PROGRESS_EVERY = 10  # steps between progress lines in the log
#: s of wall time per timing probe (the full mode's steps take minutes: the whole probe, last step
#: included, stays within a 10-minute slot)
PROBE_BUDGET_S = {"partial": 480.0, "full": 300.0}
#: phases of ``StepReport.timings`` kept per step (the probes' per-iteration split)
STEP_PHASES = ("hessian", "hessian_projection", "assemble", "analyze", "factorize", "solve")
WARM_UP_CONTACT_STEPS = 2  # quick-mode contact steps run before a probe (``_warm_up``)
PAPER = {
    "particles": 90929,
    "shell_vertices": 1364,
    "shell_tetrahedra": 3920,
    "slip_angle_pi": {"0.0": 0.1, "0.2": 0.3, "0.5": 0.7, "1.0": None},
}
PAPER_OMEGA, PAPER_TWIST_TIME = math.pi / 5.0, 4.5  # rad/s, s


def _mode(
    dx: float, ppc: int, shell_h: float, dt: float, speed: float = 1.0, stop_after_slip: bool = True
) -> dict:
    """A mode's parameters: grid spacing ``dx`` (m), particles per cell, the shell's edge
    ``shell_h`` (m), ``dt`` (s); the twist ``speed`` x the paper's angular velocity for 1/speed
    of its time (the same 0.9 pi); the four mu."""
    return dict(
        dx=dx,
        ppc=ppc,
        shell_h=shell_h,
        dt=dt,
        omega=speed * PAPER_OMEGA,
        twist_time=PAPER_TWIST_TIME / speed,
        mus=(0.0, 0.2, 0.5, 1.0),
        stop_after_slip=stop_after_slip,
    )


MODES = {
    "full": _mode(0.0625, 27, 0.08, 1e-2, stop_after_slip=False),
    "partial": _mode(0.125, 8, 0.1, 2e-2),
    "quick": _mode(0.25, 8, 0.15, 5e-2, speed=2.0),
}
#: the timing probes, modes of the runner beside ``MODES``: mode -> the mode probed
PROBES = {"partial_probe": "partial", "full_probe": "full"}
#: where the full mode's wall-time estimate is (the probe's numbers change with the code)
FULL_ESTIMATE = "see benchmarks/records/twist_full_probe.md (from the full timing probe)"


def shell_mesh(h: float) -> tuple[TetMesh, np.ndarray]:
    """The shell's tetrahedral mesh (target edge ``h`` in m) on the z axis, its lowest node
    ``DHAT`` above the cube's top face, and its centre ``(3,)`` in m."""
    center = np.array([0.0, 0.0, CUBE_EDGE + DHAT + SHELL_RADII[1]])
    mesh = bfemp.shapes.spherical_shell(tuple(center), *SHELL_RADII, h=h)
    # with an odd number of cubed-sphere cells per edge the south pole is not a node and the
    # lowest nodes sit higher: lower the mesh until they are d-hat above the cube
    drop = mesh.points[:, 2].min() - (CUBE_EDGE + DHAT)
    shift = np.array([0.0, 0.0, -drop])
    return TetMesh(mesh.points + shift, mesh.cells), center + shift


def shell_motion(omega: float) -> bfemp.motion.Motion:
    """The shell top's rigid motion: down at ``PRESS_SPEED`` for ``PRESS_TIME``, then rotation
    about the z axis at ``omega`` rad/s (counter-clockwise seen from above)."""
    return bfemp.motion.Sequence(
        segments=(
            (PRESS_TIME, bfemp.motion.Linear(velocity=(0.0, 0.0, -PRESS_SPEED))),
            (math.inf, bfemp.motion.Rotation(center=(0.0, 0.0, 0.0), angular_velocity=omega)),
        )
    )


def _simulation(cfg: dict, mu: float) -> bfemp.Simulation:
    """Cube on a sticky floor, the shell d-hat above it with its upper hemisphere scripted."""
    scene = bfemp.Scene(dim=3, gravity=(0.0, 0.0, GRAVITY))
    half = 0.5 * CUBE_EDGE
    x, vol = bfemp.sample.box(
        (-half, -half, 0.0), (half, half, CUBE_EDGE), dx=cfg["dx"], ppc=cfg["ppc"]
    )
    scene.add_mpm(x, vol, material=bfemp.NeoHookean(**CUBE), name="cube")
    shell, center = shell_mesh(cfg["shell_h"])
    scene.add_fem(
        shell,
        material=bfemp.NeoHookean(**SHELL),
        prescribed=shell_motion(cfg["omega"]),
        prescribed_nodes=shell.points[:, 2] >= center[2] - 1e-9,
        name="shell",
    )
    scene.set_grid(dx=cfg["dx"])
    floor = bfemp.levelset.Box(lower=(-2.0, -2.0, -1.0), upper=(2.0, 2.0, 0.0))
    scene.add_boundary(floor, kind="sticky")
    scene.set_contact(dhat=DHAT, kappa=KAPPA, mu=mu, eps_v=EPS_V)
    return catalogue.paper_simulation(scene, cfg["dt"], TOL, MAX_NEWTON)


class TopTwist:
    """Twist angle (rad) of the cube's top-centre region about the z axis.

    Args:
        mpm_x0: initial particle positions ``(p, 3)`` in m.
        spacing: particle spacing in m (the top layer is within half of it of the highest).
    """

    def __init__(self, mpm_x0: np.ndarray, spacing: float) -> None:
        z, r = mpm_x0[:, 2], np.hypot(mpm_x0[:, 0], mpm_x0[:, 1])
        self.region = np.flatnonzero((z > z.max() - 0.5 * spacing) & (r < REGION_RADIUS))
        if self.region.size == 0:
            raise ValueError("TopTwist: no particle in the top-centre region")
        self.xy0 = mpm_x0[self.region, :2].copy()

    def __call__(self, mpm_x: np.ndarray) -> float:
        """Least-squares rotation angle in rad, in (-pi, pi] (unwrap a time series)."""
        a, b = self.xy0, mpm_x[self.region, :2]
        cross = np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
        return math.atan2(cross, np.sum(a * b))


def slip_onset(t: np.ndarray, cube: np.ndarray, omega: float, t_press: float, dt: float):
    """Slip start (s) and slip angle (rad) of a twist series, ``(None, None)`` without slip.

    Args:
        t: times ``(n,)`` in s, every ``dt`` from 0.
        cube: the cube's unwrapped twist angle ``(n,)`` in rad.
        omega: the shell's angular velocity in rad/s; ``t_press``: when the twist starts (s).
    """
    lag = max(round(SLIP_WINDOW_S / dt), 1)
    window = lag * dt
    for k in range(lag, len(t)):
        if t[k - lag] < t_press - 1e-9:
            continue
        if cube[k] - cube[k - lag] < SLIP_RATE * omega * window:
            return float(t[k - lag]), float(cube[k - lag])
    return None, None


def _run_one(
    cfg: dict, mu: float, budget_s: float = math.inf, max_steps: int | None = None
) -> dict:
    """Press and twist at friction ``mu``; the cube's twist angle after every step.

    ``budget_s``: stop after the step that ends past this wall time in s, ``max_steps``: after
    that many steps (timing probes).
    """
    sim = _simulation(cfg, mu)
    measure = TopTwist(sim.state.mpm_x, cfg["dx"] / round(cfg["ppc"] ** (1.0 / 3.0)))
    steps = round((PRESS_TIME + cfg["twist_time"]) / cfg["dt"])
    steps = steps if max_steps is None else min(steps, max_steps)
    t, cube = [0.0], [0.0]
    friction_max, friction_unconverged, min_d, error = 0, 0, math.inf, None
    slip_t = slip_angle = None
    cut = False  # stopped by budget_s before the end of the run
    # per step (the record's series; step_phase_s and the Hessian split for the probes only)
    keys = ("step_wall_s", "step_cpu_s", "step_newton_iterations", "step_contact_pairs")
    series = {k: [] for k in (*keys, "step_hessian_phases_s")}
    phases: dict[str, float] = {}
    step_phases: dict[str, list[float]] = {k: [] for k in STEP_PHASES}
    started = time.perf_counter()
    for _ in range(steps):
        tick, cpu = time.perf_counter(), time.process_time()
        before = sim.stepper.potential.hessian_seconds()
        report, error = catalogue.step(sim, f"twist mu={mu:g}")
        if error is not None:
            break
        series["step_wall_s"].append(time.perf_counter() - tick)
        series["step_cpu_s"].append(time.process_time() - cpu)
        series["step_newton_iterations"].append(report.newton_iterations)
        series["step_contact_pairs"].append(report.contact_pairs)
        for name, seconds in report.timings.items():
            phases[name] = phases.get(name, 0.0) + seconds
        for name, values in step_phases.items():
            values.append(report.timings.get(name, 0.0))
        after = sim.stepper.potential.hessian_seconds()  # the Hessian split by term
        series["step_hessian_phases_s"].append(
            {k: v - before.get(k, 0.0) for k, v in after.items()}
        )
        friction_max = max(friction_max, report.friction_iterations)
        friction_unconverged += int(not report.friction_converged)
        if np.isfinite(report.min_distance):
            min_d = min(min_d, report.min_distance)
        t.append(sim.state.t)
        cube.append(cube[-1] + _wrap(measure(sim.state.mpm_x) - cube[-1]))
        if slip_t is None:
            slip_t, slip_angle = slip_onset(
                np.array(t), np.array(cube), cfg["omega"], PRESS_TIME, cfg["dt"]
            )
        elif cfg["stop_after_slip"] and sim.state.t >= slip_t + STOP_AFTER_SLIP_S - 1e-9:
            break
        if len(t) % PROGRESS_EVERY == 1:
            row = {"t": t[-1], "cube_pi": cube[-1] / math.pi, "s": time.perf_counter() - started}
            log_row(log, f"twist mu={mu:g}", row, "t cube_pi s")
        if time.perf_counter() - started > budget_s:
            cut = True
            break
    wall = time.perf_counter() - started
    log.info("twist mu=%g: slip angle %s, %d steps, %.1f s", mu, slip_angle, len(t) - 1, wall)
    step_wall = series["step_wall_s"]
    return {
        "mu": mu,
        "error": error,
        "steps": len(t) - 1,
        "t_end_s": t[-1],
        "cut_at_budget_s": budget_s if cut else None,
        "slip_time_s": slip_t,
        "slip_angle_rad": slip_angle,
        "slip_angle_pi": None if slip_angle is None else slip_angle / math.pi,
        "shell_angle_at_slip_pi": (
            None if slip_t is None else cfg["omega"] * (slip_t - PRESS_TIME) / math.pi
        ),
        "max_cube_angle_pi": max(cube) / math.pi,
        "newton_iterations": sum(series["step_newton_iterations"]),
        "friction_iterations_max": friction_max,
        "friction_unconverged_steps": friction_unconverged,
        "min_distance_m": min_d if math.isfinite(min_d) else None,
        "wall_s": wall,
        "phase_s": phases,
        "step_wall_s": {
            "mean": float(np.mean(step_wall)) if step_wall else None,
            "max": float(np.max(step_wall)) if step_wall else None,
        },
        "particles": int(sim.model.n_particles),
        "region_particles": int(measure.region.size),
        "shell_vertices": int(sim.model.n_fem_nodes),
        "shell_tetrahedra": int(sim.model.fem_cells.shape[0]),
        "final_mpm_x": sim.state.mpm_x,
        "series": {
            "t_s": t,
            "cube_angle_rad": cube,
            "shell_angle_rad": [cfg["omega"] * max(0.0, s - PRESS_TIME) for s in t],
            **series,
            "step_phase_s": step_phases,
        },
    }


def _wrap(a: float) -> float:
    """``a`` wrapped into (-pi, pi]."""
    return a - 2.0 * math.pi * math.floor((a + math.pi) / (2.0 * math.pi))


def slip_ordered(angles: list[float | None]) -> bool:
    """Whether slip angles increase strictly along ``angles`` (``None``: no slip, the largest;
    two ``None`` in a row are not ordered)."""
    key = [math.inf if a is None else a for a in angles]
    return all(a < b for a, b in zip(key[:-1], key[1:], strict=True))


def plot(payload: dict, path: Path) -> None:
    """Figure 17: the cube top's twist angle against time per mu, the shell's dashed."""
    if "_runs" not in payload:  # a timing probe: nothing to draw
        return
    runs = payload["_runs"]
    fig, ax = figure((8.0, 5.0), layout="constrained")
    longest = max(runs, key=lambda r: r["t_end_s"])["series"]
    ax.plot(longest["t_s"], longest["shell_angle_rad"], "k--", lw=1.0, label="shell")
    for k, run in enumerate(runs):
        slip = run["slip_angle_pi"]
        label = f"mu = {run['mu']:g}" + (
            " (no slip)" if slip is None else f" (slips at {slip:.2f} pi)"
        )
        ax.plot(run["series"]["t_s"], run["series"]["cube_angle_rad"], color=f"C{k}", label=label)
        if run["slip_time_s"] is not None:
            ax.plot(run["slip_time_s"], run["slip_angle_rad"], "o", color=f"C{k}", ms=5)
    ax.set(xlabel="time [s]", ylabel="twist angle of the cube's top centre [rad]")
    ax.set_title(f"Shell pressed and twisted on an MPM cube ({payload['mode']} mode)")
    save(fig, path, [ax])


def per_newton_iteration(series: dict, steps: np.ndarray) -> tuple[dict, dict]:
    """Seconds per Newton iteration over the ``steps`` (bool mask over the run's steps): of each
    phase of ``series["step_phase_s"]`` and of each part of the Hessian split
    (``series["step_hessian_phases_s"]``), summed over those steps and divided by their Newton
    iterations (None without any)."""
    its = int(np.sum(np.array(series["step_newton_iterations"])[steps]))
    phases = {
        name: float(np.sum(np.array(values)[steps]) / its) if its else None
        for name, values in series["step_phase_s"].items()
    }
    split = [series["step_hessian_phases_s"][i] for i in np.flatnonzero(steps)]
    parts = sorted({k for step in split for k in step})
    hessian = {
        k: float(sum(step.get(k, 0.0) for step in split) / its) if its else None for k in parts
    }
    return phases, hessian


def _warm_up(mu: float) -> float:
    """Compile (or load from numba's cache) every kernel a contact step runs, on the quick mode's
    steps up to its ``WARM_UP_CONTACT_STEPS``-th in contact: a probe's first contact step then
    measures the step, not the compiler (on a cold cache the contact kernels compile in the
    first contact step; see ``records/twist_full_probe.md``). Returns the wall time in s."""
    started = time.perf_counter()
    cfg = MODES["quick"]
    sim, in_contact = _simulation(cfg, mu), 0
    for _ in range(round(PRESS_TIME / cfg["dt"])):
        report, error = catalogue.step(sim, f"twist warm-up mu={mu:g}")
        in_contact += error is None and report.contact_pairs > 0
        if error is not None or in_contact >= WARM_UP_CONTACT_STEPS:
            break
    return time.perf_counter() - started


def probe(mode: str, mu: float = 0.5, max_steps: int | None = None, budget_s=None) -> dict:
    """Timing probe (not a result): the first ``PROBE_BUDGET_S[mode]`` s of wall time of ``mode``'s
    ``mu`` case (or its first ``max_steps`` steps, whichever ends first: a shorter probe of the
    same scene); the record (``twist_<mode>_probe.json``) holds the per-step wall time, Newton
    iterations, contact pairs, Hessian and factorisation time per Newton iteration (the Hessian
    split by term and the elasticity terms' dP/dF projection), the peak memory, and a naive
    estimate of the whole mode. ``budget_s`` replaces the mode's wall budget (a loaded machine).
    The kernels are compiled first (``_warm_up``); ``step_cpu_s``, the process's CPU time per
    step (all threads), is the measure least moved by other processes on the machine."""
    cfg = MODES[mode]
    warm_up_s = _warm_up(mu)
    started = time.perf_counter()
    budget = PROBE_BUDGET_S[mode] if budget_s is None else float(budget_s)
    case = _run_one(cfg, mu, budget_s=budget, max_steps=max_steps)
    s = case["series"]
    wall, cpu, newton, pairs = (
        np.array(s[k])
        for k in ("step_wall_s", "step_cpu_s", "step_newton_iterations", "step_contact_pairs")
    )
    steps_per_case = round((PRESS_TIME + cfg["twist_time"]) / cfg["dt"])
    # the first step builds what later steps reuse: it is left out of the rates
    later = np.arange(wall.size) > 0
    contact = later & (pairs > 0)
    twisting = later & (np.array(s["t_s"][1:]) > PRESS_TIME + 1e-9)

    def mean(values: np.ndarray, mask: np.ndarray) -> float | None:
        return float(np.mean(values[mask])) if np.any(mask) else None

    rate = mean(wall, contact)
    per_iteration, hessian_split = per_newton_iteration(s, contact)
    hessian, factorize = per_iteration["hessian"], per_iteration["factorize"]
    return {
        "kind": "TIMING PROBE, not a result: the first steps of one case, cut at the wall budget",
        "probe_mu": mu,
        "budget_s": budget,
        "max_steps": max_steps,
        "steps_done": case["steps"],
        "t_reached_s": case["t_end_s"],
        "steps_per_case": steps_per_case,
        "cases": len(cfg["mus"]),
        **{k: case[k] for k in ("particles", "shell_vertices", "shell_tetrahedra")},
        "warm_up_s": warm_up_s,
        "first_step_s": float(wall[0]) if wall.size else None,
        "phase_s": case["phase_s"],
        "mean_step_s_in_contact": rate,
        "mean_step_cpu_s_in_contact": mean(cpu, contact),
        "mean_newton_per_step_in_contact": mean(newton, contact),
        "per_newton_iteration_in_contact_s": per_iteration,
        "hessian_split_per_iteration_in_contact_s": hessian_split,
        "hessian_over_factorisation": (
            hessian / factorize if hessian is not None and factorize else None
        ),
        "min_distance_m": case["min_distance_m"],
        "max_cube_angle_pi": case["max_cube_angle_pi"],
        "final_particle_centroid_m": case["final_mpm_x"].mean(axis=0).tolist(),
        "twist_steps_done": int(np.count_nonzero(twisting)),
        "mean_step_s_twisting": mean(wall, twisting),
        "mean_newton_per_step_twisting": mean(newton, twisting),
        "per_step": {
            "wall_s": wall.tolist(),
            "cpu_s": cpu.tolist(),
            "newton_iterations": newton.tolist(),
            "contact_pairs": pairs.tolist(),
            "phase_s": s["step_phase_s"],
        },
        "naive_estimate_h": (
            None if rate is None else rate * steps_per_case * len(cfg["mus"]) / 3600.0
        ),
        "estimate_note": (
            "mean step in contact (press phase only, unless the probe reached the twist) x "
            "steps per case x cases; a lower bound: slipping steps took 5-20x more Newton "
            "iterations than sticking ones in quick mode"
        ),
        "wall_s": time.perf_counter() - started,
        "parameters": dict(cfg),
    }


def _checkpoint(out: Path, mode: str, payload: dict) -> None:
    """The record of ``mode`` so far (and its plot), written before the runner's final one: a
    long run that is stopped keeps what it finished."""
    write_record(out, BENCHMARK.stem(mode), {"benchmark": NAME, "mode": mode, **payload}, plot)


def measure(mode: str, cfg: dict, out: Path, mus=None, budget_s=None, **probe_options) -> dict:
    """Press and twist at each mu of ``mode`` (``"full"``: the paper's resolution, ``"partial"``
    or ``"quick"``), or a timing probe (``PROBES``: ``probe``).

    Args:
        mus: friction coefficients to run instead of the mode's (the quick-mode test runs two).
        budget_s: wall time in s after which each case stops (its record then says
            ``cut_at_budget_s`` and ends at ``t_end_s``: "no slip" means none up to there); in a
            probe, its wall budget.
        probe_options: ``mu`` and ``max_steps`` of ``probe``.
    """
    if mode in PROBES:
        return probe(PROBES[mode], budget_s=budget_s, **probe_options)
    cfg = dict(cfg, mus=cfg["mus"] if mus is None else tuple(float(m) for m in mus))
    started, runs = time.perf_counter(), []
    for mu in cfg["mus"]:
        runs.append(_run_one(cfg, mu, budget_s=math.inf if budget_s is None else budget_s))
        payload = {**_payload(cfg, runs, time.perf_counter() - started), "_runs": runs}
        _checkpoint(out, mode, payload)
    return payload


#: per-step series of ``_run_one`` kept by the timing probes only (not in a mode's record)
PROBE_SERIES = ("step_phase_s", "step_hessian_phases_s")


def _case_record(run: dict) -> dict:
    """A case of a mode's record: ``run`` without its final positions and probe-only series."""
    out = {k: v for k, v in run.items() if k != "final_mpm_x"}
    out["series"] = {k: v for k, v in run["series"].items() if k not in PROBE_SERIES}
    return out


def _payload(cfg: dict, runs: list[dict], wall_s: float) -> dict:
    """The record of a mode after the finished ``runs`` (one per mu, in ``cfg["mus"]`` order)."""
    complete = all(r["error"] is None for r in runs)
    return {
        "cases_done": len(runs),
        "cases_planned": len(cfg["mus"]),
        "slip_angle_pi": {str(r["mu"]): r["slip_angle_pi"] for r in runs},
        "slip_increases_with_mu": bool(
            complete and slip_ordered([r["slip_angle_rad"] for r in runs])
        ),
        "failed_cases": [r["mu"] for r in runs if r["error"] is not None],
        "cases": [_case_record(r) for r in runs],
        "wall_s": wall_s,
        "paper": PAPER,
        "targets": {
            "full": "slip angle within 0.1 pi of the paper's per mu; no slip at mu = 1",
            "quick": "slip angle increases with mu (no slip counts as the largest)",
        },
        "full_mode_estimate": FULL_ESTIMATE,
        "parameters": {
            **cfg,
            "cube_edge_m": CUBE_EDGE,
            "cube_material": {"model": "NeoHookean", **CUBE},
            "shell_radii_m": SHELL_RADII,
            "shell_material": {"model": "NeoHookean", **SHELL},
            "shell_center_m": shell_mesh(cfg["shell_h"])[1].tolist(),
            "shell_prescribed": "nodes with z >= the centre's (upper hemisphere)",
            "press_speed_m_s": PRESS_SPEED,
            "press_time_s": PRESS_TIME,
            "floor": "sticky level-set box z <= 0 under the cube",
            "gravity_m_s2": GRAVITY,
            "dhat_m": DHAT,
            "kappa_Pa": KAPPA,
            "eps_v_m_s": EPS_V,
            "tol_m_s": TOL,
            "max_newton_iterations": MAX_NEWTON,
            "friction_iterations": 20,
            "integrator": "backward_euler",
            "transfer": "apic",
            "region_radius_m": REGION_RADIUS,
            "region": "top particle layer, initial distance to the z axis < region_radius_m",
            "slip_window_s": SLIP_WINDOW_S,
            "slip_rate": SLIP_RATE,
            "stop_after_slip_s": STOP_AFTER_SLIP_S if cfg["stop_after_slip"] else None,
            **{k: runs[0][k] for k in ("particles", "shell_vertices", "shell_tetrahedra")},
        },
    }


def merge(records: list[str | Path], out: str | Path = "results") -> dict:
    """One record (``twist_MODE.json`` and ``.png`` in ``out``, ``twist.json`` in full mode) from
    records of the same mode whose cases ran in separate processes (one mu each, run side by
    side to fit a slot), cases sorted by mu; ``wall_s`` is the sum of the cases' wall times,
    ``merged_from`` lists the inputs with their own wall time."""
    mode, loaded, runs = cases_by_mu(records)
    cfg = dict(MODES[mode], mus=tuple(r["mu"] for r in runs))
    payload = _payload(cfg, runs, sum(r["wall_s"] for r in runs))
    payload = {"benchmark": NAME, "mode": mode, **note_merge(payload, records, loaded)}
    payload["environment"] = loaded[0]["environment"]
    return write_record(out, BENCHMARK.stem(mode), {**payload, "_runs": runs}, plot)


# the records of modes other than full carry the mode in their names
BENCHMARK = register(
    Benchmark(
        NAME,
        __doc__,
        {**MODES, **{m: {} for m in PROBES}},
        measure,
        plot=plot,
        record=name_unless("full", NAME),
        needs_out=True,
    )
)
run = BENCHMARK.run
