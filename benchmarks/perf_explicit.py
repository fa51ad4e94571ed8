"""Throughput of the explicit engine (issue 11): particle-steps per second against Taichi.

Scene (both libraries, f64): a 2D Neo-Hookean block (E = 1e5 Pa, nu = 0.3, rho = 1000 kg/m^3)
of n x n cells of size dx = 1 / n at 4 particles per cell (full mode: n = 91 and 181, 33,124 and
131,044 particles; quick: n = 20), spinning at 0.5 rad/s and falling under gravity toward a slip
floor (y = 0.2 m), APIC transfers, dt = the stable step of ``single_field`` (0.4 dx / (c_p + |v|)).

- bfemp: ``SingleFieldStepper`` steps; per-phase shares from the step reports: P2G (stencils +
  the fused scatter of mass, momentum and internal force), force (the first Piola stresses P(F)
  of the particles; their scatter is fused into P2G), G2P, and the rest (CFL check, grid update,
  level-set constraints).
- Taichi (optional ``bench`` extra; its column is skipped when absent): a small MLS-MPM of the
  same particles, dx, law, dt and floor on a dense grid, ``ti.init(arch=ti.cpu,
  cpu_max_num_threads=THREADS, default_fp=ti.f64)``. MLS-MPM (Hu et al. 2018) is APIC with the
  force of the MLS gradient (4 / dx^2) w_ip (x_i - x_p) in place of grad w_ip. Both conserve
  momentum, so their centres of mass must agree to round-off while no particle reaches the floor
  (``com_difference_m``, a check that the two run the same scene).
- ``term_route_s``: the MPM forces by the implicit path's term (``MpmElasticityTerm.begin_step``
  + ``gradient`` at the start positions) against the fused kernel, on the first scene.
- ``single_field_vs_barrier``: time per step of ``single_field`` at its stable dt against one
  ``barrier`` step (``bfemp.Simulation``, backward Euler, dt = 1e-2 s, tol 1e-4 m/s; the second
  step is timed) on the same scene, and the wall time per simulated second of each.

Target (issue 43): bfemp at least 1.5x Taichi's throughput with 2 threads, at both sizes. The
two run in alternating rounds (``rounds`` of ``steps`` steps each) and each keeps its best round,
since the machine is shared; every round is recorded (``seconds_per_step_rounds``). Timings are
recorded, never asserted.
"""

# no "from __future__ import annotations": Taichi reads the kernels' annotations as objects

import math
import time

import numba
import numpy as np

import bfemp
from benchmarks._phases import barrier_stepper, timed, wall_times
from benchmarks.runner import Benchmark, register
from bfemp.steppers.single_field import SingleFieldStepper

try:  # optional: benchmark-only reference
    import taichi as ti
except ImportError:  # pragma: no cover - depends on the environment
    ti = None

THREADS = 2
MATERIAL = dict(E=1e5, nu=0.3, density=1000.0)
FLOOR_Y = 0.1
SPIN = 0.5  # rad/s
BARRIER_DT = 1e-2

CASES = {
    "full": dict(cells=(91, 181), steps=20, rounds=8),
    "quick": dict(cells=(20,), steps=5, rounds=1),
}


def _scene(cells: int) -> bfemp.Scene:
    dx = 1.0 / cells
    lower = (0.25, 0.25)
    x, vol = bfemp.sample.box(lower, (lower[0] + 1.0, lower[1] + 1.0), dx=dx, ppc=4)
    centre = np.array(lower) + 0.5
    r = x - centre
    v = SPIN * np.stack([-r[:, 1], r[:, 0]], axis=1)
    scene = bfemp.Scene(dim=2, gravity=(0.0, -9.81))
    scene.add_mpm(x, vol, material=bfemp.NeoHookean(**MATERIAL), velocity=v, name="block")
    scene.set_grid(dx=dx)
    floor = bfemp.levelset.HalfPlane(point=(0.0, FLOOR_Y), normal=(0.0, 1.0))
    scene.add_boundary(floor, "slip")
    return scene


class _BfempCase:
    """``single_field`` on the scene: timed rounds of ``steps`` steps from the initial state."""

    def __init__(self, model) -> None:
        self.model = model
        self.stepper = SingleFieldStepper(
            model, integrator="symplectic_euler", transfer="apic", dt="auto"
        )
        self.start = self.stepper.initialize(model.initial_state())
        self.stepper.step(self.start)  # warm-up (numba kernels are compiled or loaded)
        self.walls: list[float] = []
        self.phases: dict[str, float] = {}
        self.steps_done = 0

    def round(self, steps: int) -> None:
        state = self.start
        t0 = time.perf_counter()
        for _ in range(steps):
            state, report = self.stepper.step(state)
            for key, value in report.timings.items():
                self.phases[key] = self.phases.get(key, 0.0) + value
        self.walls.append(time.perf_counter() - t0)
        self.steps_done += steps
        self.state = state

    def summary(self, steps: int) -> dict:
        phases, total = self.phases, self.phases["step"]
        shares = {
            "p2g": (phases.get("stencils", 0.0) + phases["p2g"]) / total,
            "force": phases["stress"] / total,
            "g2p": phases["g2p"] / total,
        }
        shares["other"] = 1.0 - sum(shares.values())
        wall = min(self.walls)
        m = self.model.mpm_mass
        return {
            "dt_s": self.stepper.dt,
            "seconds_per_step": wall / steps,
            "seconds_per_step_rounds": [w / steps for w in self.walls],
            "particle_steps_per_s": self.model.n_particles * steps / wall,
            "shares": shares,
            "phase_seconds_per_step": {k: v / self.steps_done for k, v in phases.items()},
            "com": (m @ self.state.mpm_x / m.sum()).tolist(),
            "steps": steps,
            "numba_threads": numba.get_num_threads(),
        }


# --------------------------------------------------------------------------- Taichi MLS-MPM
def _taichi_solver(n_particles: int, n_grid: int):
    """A data-oriented MLS-MPM (APIC, Neo-Hookean) of the scene on a dense n_grid^2 grid."""

    @ti.data_oriented
    class MlsMpm:
        def __init__(self) -> None:
            self.x = ti.Vector.field(2, ti.f64, n_particles)
            self.v = ti.Vector.field(2, ti.f64, n_particles)
            self.C = ti.Matrix.field(2, 2, ti.f64, n_particles)
            self.F = ti.Matrix.field(2, 2, ti.f64, n_particles)
            self.grid_v = ti.Vector.field(2, ti.f64, (n_grid, n_grid))
            self.grid_m = ti.field(ti.f64, (n_grid, n_grid))

        @ti.kernel
        def substep(
            self, dt: ti.f64, dx: ti.f64, p_vol: ti.f64, p_mass: ti.f64, mu: ti.f64, lam: ti.f64
        ):
            inv_dx = 1.0 / dx
            for i, j in self.grid_m:
                self.grid_v[i, j] = ti.Vector([0.0, 0.0])
                self.grid_m[i, j] = 0.0
            for p in self.x:  # P2G (atomic scatter)
                base = (self.x[p] * inv_dx - 0.5).cast(int)
                fx = self.x[p] * inv_dx - base.cast(ti.f64)
                w = [0.5 * (1.5 - fx) ** 2, 0.75 - (fx - 1.0) ** 2, 0.5 * (fx - 0.5) ** 2]
                F = self.F[p]
                J = F.determinant()
                # Kirchhoff stress P F^T = mu (F F^T - I) + lam log J I (Neo-Hookean, eq. 7)
                tau = mu * (F @ F.transpose() - ti.Matrix.identity(ti.f64, 2)) + lam * ti.log(
                    J
                ) * ti.Matrix.identity(ti.f64, 2)
                stress = -dt * p_vol * 4.0 * inv_dx * inv_dx * tau
                affine = stress + p_mass * self.C[p]
                for i, j in ti.static(ti.ndrange(3, 3)):
                    offset = ti.Vector([i, j])
                    dpos = (offset.cast(ti.f64) - fx) * dx
                    weight = w[i][0] * w[j][1]
                    self.grid_v[base + offset] += weight * (p_mass * self.v[p] + affine @ dpos)
                    self.grid_m[base + offset] += weight * p_mass
            for i, j in self.grid_m:  # grid update, slip floor
                if self.grid_m[i, j] > 0:
                    self.grid_v[i, j] = self.grid_v[i, j] / self.grid_m[i, j]
                    self.grid_v[i, j][1] -= dt * 9.81
                    if j * dx <= FLOOR_Y:
                        self.grid_v[i, j][1] = 0.0
            for p in self.x:  # G2P
                base = (self.x[p] * inv_dx - 0.5).cast(int)
                fx = self.x[p] * inv_dx - base.cast(ti.f64)
                w = [0.5 * (1.5 - fx) ** 2, 0.75 - (fx - 1.0) ** 2, 0.5 * (fx - 0.5) ** 2]
                new_v = ti.Vector.zero(ti.f64, 2)
                new_C = ti.Matrix.zero(ti.f64, 2, 2)
                for i, j in ti.static(ti.ndrange(3, 3)):
                    offset = ti.Vector([i, j])
                    dpos = (offset.cast(ti.f64) - fx) * dx
                    g_v = self.grid_v[base + offset]
                    weight = w[i][0] * w[j][1]
                    new_v += weight * g_v
                    new_C += 4.0 * inv_dx * inv_dx * weight * g_v.outer_product(dpos)
                self.v[p] = new_v
                self.C[p] = new_C
                self.x[p] += dt * new_v
                self.F[p] = (ti.Matrix.identity(ti.f64, 2) + dt * new_C) @ self.F[p]

    return MlsMpm()


class _TaichiCase:
    """The Taichi MLS-MPM of the scene: timed rounds of ``steps`` steps from the initial state."""

    def __init__(self, model, dt: float) -> None:
        ti.init(arch=ti.cpu, cpu_max_num_threads=THREADS, default_fp=ti.f64, log_level=ti.ERROR)
        self.model = model
        dx = model.grid.dx
        self.n_grid = int(math.ceil(1.6 / dx)) + 4
        mat = model.mpm_bodies[0].material
        self.solver = _taichi_solver(model.n_particles, self.n_grid)
        vol, mass = float(model.mpm_volume[0]), float(model.mpm_mass[0])
        assert np.allclose(model.mpm_volume, vol) and np.allclose(model.mpm_mass, mass)
        self.args = (dt, dx, vol, mass, mat.mu, mat.lam)
        self._reset()
        self.solver.substep(*self.args)  # compile
        ti.sync()
        self.walls: list[float] = []

    def _reset(self) -> None:
        n = self.model.n_particles
        self.solver.x.from_numpy(self.model.mpm_X)
        self.solver.v.from_numpy(self.model.mpm_v0)
        self.solver.C.from_numpy(np.zeros((n, 2, 2)))
        self.solver.F.from_numpy(np.tile(np.eye(2), (n, 1, 1)))

    def round(self, steps: int) -> None:
        self._reset()
        ti.sync()
        t0 = time.perf_counter()
        for _ in range(steps):
            self.solver.substep(*self.args)
        ti.sync()
        self.walls.append(time.perf_counter() - t0)

    def summary(self, steps: int) -> dict:
        wall = min(self.walls)
        return {
            "seconds_per_step": wall / steps,
            "seconds_per_step_rounds": [w / steps for w in self.walls],
            "particle_steps_per_s": self.model.n_particles * steps / wall,
            "com": self.solver.x.to_numpy().mean(axis=0).tolist(),
            "threads": THREADS,
            "version": ".".join(str(v) for v in ti.__version__),
            "grid": [self.n_grid, self.n_grid],
        }


def _throughput(model, steps: int, rounds: int) -> tuple[dict, dict | None]:
    """bfemp and (when installed) Taichi in alternating rounds; each keeps its best round (the
    machine is shared: alternating exposes both to the same load)."""
    ours = _BfempCase(model)
    theirs = _TaichiCase(model, ours.stepper.dt) if ti is not None else None
    for _ in range(rounds):
        ours.round(steps)
        if theirs is not None:
            theirs.round(steps)
    return ours.summary(steps), None if theirs is None else theirs.summary(steps)


# --------------------------------------------------------------------------- other figures
def _term_route(model) -> dict:
    """MPM forces by the implicit term vs the fused kernel, at the start of one step."""
    stepper = barrier_stepper(model, BARRIER_DT, 1e-4)
    state = model.initial_state()
    phases = stepper.phases(state)  # warm-up
    term = next(t for t in phases.potential.potentials if hasattr(t, "particles"))
    _, begin = timed(lambda: term.begin_step(phases.context))
    x = stepper.phases(state).x0
    _, gradient = timed(lambda: (term.solution_changed(x), term.gradient(x)))
    return {"begin_step_s": begin, "gradient_s": gradient, "total_s": begin + gradient}


def _barrier_step(scene) -> dict:
    """Two barrier steps; the second is timed (the first may load or compile kernels)."""
    sim = bfemp.Simulation(scene, dt=BARRIER_DT, tol=1e-4)
    reports = []
    first, wall = wall_times(lambda: reports.append(sim.step()), 2)
    report = reports[-1]
    return {
        "dt_s": BARRIER_DT,
        "first_step_s": first,
        "seconds_per_step": wall,
        "newton_iterations": report.newton_iterations,
        "seconds_per_simulated_second": wall / BARRIER_DT,
    }


def measure(mode: str, cfg: dict) -> dict:
    """Every case of ``mode``."""
    cases = {}
    for k, cells in enumerate(cfg["cells"]):
        scene = _scene(cells)
        model = scene.build()
        case = {"cells": cells, "dx": model.grid.dx, "particles": int(model.n_particles)}
        case["bfemp"], case["taichi"] = _throughput(model, cfg["steps"], cfg["rounds"])
        if case["taichi"] is not None:
            diff = np.subtract(case["bfemp"]["com"], case["taichi"]["com"])
            case["com_difference_m"] = float(np.abs(diff).max())
            case["bfemp_over_taichi"] = (
                case["bfemp"]["particle_steps_per_s"] / case["taichi"]["particle_steps_per_s"]
            )
        explicit = case["bfemp"]
        if k == 0:
            case["term_route_s"] = _term_route(model)
            phases = explicit["phase_seconds_per_step"]
            case["fused_route_s"] = phases["stress"] + phases["p2g"]
        barrier = _barrier_step(scene)
        case["single_field_vs_barrier"] = {
            "single_field": {
                "dt_s": explicit["dt_s"],
                "seconds_per_step": explicit["seconds_per_step"],
                "seconds_per_simulated_second": explicit["seconds_per_step"] / explicit["dt_s"],
            },
            "barrier": barrier,
            "barrier_step_over_single_field_step": barrier["seconds_per_step"]
            / explicit["seconds_per_step"],
        }
        cases[str(case["particles"])] = case
    return {
        "parameters": {
            "material": MATERIAL,
            "ppc": 4,
            "spin_rad_s": SPIN,
            "floor_y_m": FLOOR_Y,
            "transfer": "apic",
            "taichi_threads": THREADS,
            "barrier_dt_s": BARRIER_DT,
        },
        "cases": cases,
    }


BENCHMARK = register(Benchmark("perf_explicit", __doc__, CASES, measure, timings=r"_s$|per_s"))
run = BENCHMARK.run
