"""3D at scale (issue 13): an MPM block on a FEM plate, with contact and friction, per solver.

Scene: a Neo-Hookean MPM block (8 particles per cell) resting on a steel-like FEM plate whose
bottom face is clamped; the block's lowest particles start inside the barrier's activation
distance, so contact and lagged friction (mu = 0.3) are active from the first step; gravity,
backward Euler, dt = 4 ms. Full mode: ~100k particles (25 x 25 x 20 cells); quick mode: 1,152.

For each linear solver installed (``cholmod``, ``pardiso``, ``cg_amg``) one warm-up step
(numba compilation, symbolic analysis) and one timed step; recorded per solver: step wall time,
Newton iterations, linear solves, the step's phase split, time per Newton iteration, the floor
(numeric factorisation, or the CG solve, of the Hessian at the start of the step) and the ratio
of the two, peak memory. Full mode runs each solver in its own process (its own peak memory);
quick mode runs them in this process (``peak_memory_mb`` is then the process's). Besides:
CHOLMOD's factorisation of the same Hessian on the reference BLAS and on the default one, each in
its own process (``blas_side_by_side``). Target (issue 13): one step in under a minute on 2
cores; Newton iteration <= 1.5 x the factorisation.

Measured results: ``benchmarks/records/perf_3d_full.md``.
"""

from __future__ import annotations

import time
from pathlib import Path

import bfemp
from benchmarks._blas_switch import factorisation_by_blas
from benchmarks._phases import (
    MACHINE_NOTE,
    PERF_TIMINGS,
    barrier_stepper,
    newton_phases,
    warm_stepper,
)
from benchmarks._shared import child_json
from benchmarks.common import peak_memory_mb, write_json
from benchmarks.runner import Benchmark, register
from solvers.choice import linear_algebra, make_linear_solver

CASES = {
    "full": dict(cells=(25, 25, 20), dx=0.02),
    "quick": dict(cells=(6, 6, 4), dx=0.05),
}
SOLVERS = ("cholmod", "pardiso", "cg_amg")
DHAT, KAPPA, MU, DT, TOL = 1e-3, 1e5, 0.3, 4e-3, 1e-4


def _scene(cells: tuple[int, int, int], dx: float) -> bfemp.Scene:
    size = [c * dx for c in cells]
    lower = (-0.5 * size[0], -0.5 * size[1], 0.6 * DHAT - 0.25 * dx)  # first layer at 0.6 dhat
    upper = (0.5 * size[0], 0.5 * size[1], lower[2] + size[2])
    x, vol = bfemp.sample.box(lower, upper, dx=dx, ppc=8)
    scene = bfemp.Scene(dim=3, gravity=(0.0, 0.0, -9.81))
    jelly = bfemp.NeoHookean(E=2e5, nu=0.3, density=1000.0)
    scene.add_mpm(x, vol, material=jelly, velocity=(0.0, 0.0, -0.2), name="block")
    half, thick = 0.8 * size[0], 2.0 * dx
    plate = bfemp.shapes.box((-half, -half, -thick), (half, half, 0.0), h=2.0 * dx)
    scene.add_fem(
        plate,
        material=bfemp.NeoHookean(E=2e8, nu=0.3, density=8000.0),
        prescribed=bfemp.motion.Fixed(),
        prescribed_nodes=plate.points[:, 2] < -thick + 1e-9,
        name="plate",
    )
    scene.set_grid(dx=dx)
    scene.set_contact(dhat=DHAT, kappa=KAPPA, mu=MU)
    return scene


def _measure(mode: str, solver: str, matrices: dict | None = None) -> dict:
    """One warm-up and one timed step of ``mode``'s scene with ``solver``."""
    cfg = CASES[mode]
    model = _scene(cfg["cells"], cfg["dx"]).build()
    start = time.perf_counter()
    linear_solver = make_linear_solver(solver, block_size=3)
    stepper, state = warm_stepper(model, DT, TOL, linear_solver=linear_solver)
    out = {
        "solver": solver,
        "particles": int(model.n_particles),
        "fem_nodes": int(model.n_fem_nodes),
        "warmup_step_s": time.perf_counter() - start,
    }
    out.update(newton_phases(stepper, state, solver, matrices, name=mode))
    out["peak_memory_mb"] = peak_memory_mb()
    return out


#: ``_measure(mode, solver)`` in a child process (its own peak memory): its record on stdout
_CHILD = (
    "import json, sys; from benchmarks.perf_3d import _measure; "
    "print(json.dumps(_measure(*sys.argv[1:]), default=float))"
)


def measure(mode: str, cfg: dict, out: Path) -> dict:
    """Every installed solver on ``mode``'s scene (full mode: each in its own process, their
    results saved to ``out/perf_3d_solvers.json`` before the BLAS comparison)."""
    matrices: dict = {}
    installed = [name for name in SOLVERS if linear_algebra()["solvers"][name]]
    results = {}
    for name in installed:
        if mode == "quick":
            results[name] = _measure(mode, name, matrices if name == "cholmod" else None)
        else:
            results[name] = {"solver": name} | child_json(_CHILD, mode, name, timeout=1800)
    if not matrices:  # full mode: the Hessian for the BLAS comparison, from a fresh model
        stepper = barrier_stepper(_scene(cfg["cells"], cfg["dx"]).build(), DT)
        newton_phases(
            stepper, stepper.initialize(stepper.model.initial_state()), "cholmod", matrices, mode
        )
    if mode != "quick":  # the solvers' hour of work is on disk before the BLAS comparison
        write_json(out, "perf_3d_solvers", {"mode": mode, "solvers": results})
    ok = {k: v for k, v in results.items() if "error" not in v}
    return {
        "parameters": {**cfg, "dhat": DHAT, "kappa": KAPPA, "mu": MU, "dt": DT, "tol": TOL},
        "solvers": results,
        "fastest_step": min(ok, key=lambda k: ok[k]["step_wall_s"]) if ok else None,
        "blas_side_by_side": factorisation_by_blas(matrices),
        "machine_note": MACHINE_NOTE,
    }


# the committed records carry the mode in their names (perf_3d_quick, perf_3d_full)
BENCHMARK = register(
    Benchmark(
        "perf_3d",
        __doc__,
        CASES,
        measure,
        record=lambda mode, _: f"perf_3d_{mode}",
        timings=PERF_TIMINGS + "|^fastest_step$",  # the fastest solver: a timing result
        needs_out=True,
    )
)
run = BENCHMARK.run
