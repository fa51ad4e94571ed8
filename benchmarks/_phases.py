"""Per-Newton-iteration phase costs of an implicit step, shared by the perf benchmarks."""

from __future__ import annotations

import statistics
import time

import numpy as np

from solvers.assembly import TripletAssembler
from solvers.linear import CholmodSolver, cholmod_available


def median_time(fn, repeats: int = 3) -> float:
    """Median wall time of ``fn()`` over ``repeats`` calls, in s."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def newton_phases(stepper, state) -> dict:
    """Step once from ``state`` (timed), then time each phase at the start of that step."""
    start = time.perf_counter()
    _, report = stepper.step(state)
    step_wall = time.perf_counter() - start
    x = stepper.begin_step(state)
    pot = stepper.potential
    y = pot.to_unknowns(x)
    assembler = TripletAssembler(y.size)

    def assemble() -> None:
        pot.solution_changed(y)
        pot.value(y)
        pot.gradient(y)
        assembler.assemble(pot.hessian(y, psd=True))

    assemble()
    out = {
        "dofs": int(y.size),
        "assembly_s": median_time(assemble),
        "newton_iterations": report.newton_iterations,
        "step_wall_s": step_wall,
        "step_phases_s": dict(report.timings),
        "time_per_newton_iteration_s": report.timings.get("total", step_wall)
        / max(report.newton_iterations, 1),
    }
    pot.solution_changed(y)
    out["value_s"] = median_time(lambda: pot.value(y))
    out["gradient_s"] = median_time(lambda: pot.gradient(y))
    out["hessian_local_s"] = median_time(lambda: pot.hessian(y, psd=True))
    matrix = assembler.assemble(pot.hessian(y, psd=True))
    out["nnz"] = int(matrix.nnz)
    out["triplets_to_csc_s"] = max(
        median_time(lambda: assembler.assemble(pot.hessian(y, psd=True))) - out["hessian_local_s"],
        0.0,
    )
    if cholmod_available():
        solver = CholmodSolver()
        rhs = np.ones(y.size)
        solver.solve(matrix, rhs)
        out["analyze_s"] = solver.last_timings["analyze"]
        solver.solve(matrix, rhs)
        out["factorize_s"] = solver.last_timings["factorize"]
        out["solve_s"] = solver.last_timings["solve"]
        out["symbolic_saved_s"] = out["analyze_s"] * max(report.newton_iterations - 1, 0)
        out["assembly_below_factorisation"] = bool(out["assembly_s"] < out["factorize_s"])
    return out
