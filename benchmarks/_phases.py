"""Per-Newton-iteration phase costs of an implicit step, shared by the perf benchmarks."""

from __future__ import annotations

import statistics
import time

import numpy as np

from solvers.assembly import TripletAssembler
from solvers.choice import make_linear_solver
from solvers.linear import cholmod_available


def median_time(fn, repeats: int = 3) -> float:
    """Median wall time of ``fn()`` over ``repeats`` calls, in s."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def newton_phases(
    stepper, state, solver_name: str = "cholmod", matrices: dict | None = None, name: str = ""
) -> dict:
    """Step once from ``state`` (timed), then time each phase at the start of that step.

    The floor ``factorize_s`` is the numeric factorisation (for ``cg_amg``: the CG solve with
    a kept hierarchy) of the Hessian at the start of the step by a fresh ``solver_name`` solver;
    ``newton_over_factorisation`` = time per Newton iteration / that floor (issue 13 target
    <= 1.5), ``linear_solves`` the factorisations the step made (the convergence test at the
    last iterate and rejected exact-Hessian tries included). With ``matrices`` the Hessian
    at the start of the step is stored there under ``name`` (for the BLAS side by side).
    """
    n_before = getattr(stepper.linear_solver, "n_numeric", None)
    start = time.perf_counter()
    _, report = stepper.step(state)
    step_wall = time.perf_counter() - start
    n_after = getattr(stepper.linear_solver, "n_numeric", None)
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
    if matrices is not None:
        matrices[name] = matrix
    out["triplets_to_csc_s"] = max(
        median_time(lambda: assembler.assemble(pot.hessian(y, psd=True))) - out["hessian_local_s"],
        0.0,
    )
    if n_before is not None:
        out["linear_solves"] = int(n_after - n_before)
        # one linear solve per iteration plus the convergence test at the last iterate (and
        # any rejected exact-Hessian try): the cost of one solve's worth of Newton work
        out["time_per_linear_solve_s"] = report.timings.get("total", step_wall) / max(
            out["linear_solves"], 1
        )
    out["linear_solver"] = solver_name
    if cholmod_available() or solver_name != "cholmod":
        solver = make_linear_solver(solver_name, block_size=stepper.model.dim)
        rhs = np.ones(y.size)
        solver.solve(matrix, rhs)
        out["analyze_s"] = solver.last_timings["analyze"]
        best = {"factorize": float("inf"), "solve": float("inf")}
        for _ in range(2):
            solver.solve(matrix, rhs)
            for key in best:
                best[key] = min(best[key], solver.last_timings[key])
        floor = best["factorize"] if solver_name != "cg_amg" else best["solve"]
        out["factorize_s"] = floor
        out["solve_s"] = best["solve"]
        out["newton_over_factorisation"] = out["time_per_newton_iteration_s"] / max(floor, 1e-12)
        if "time_per_linear_solve_s" in out:
            out["linear_solve_over_factorisation"] = out["time_per_linear_solve_s"] / max(
                floor, 1e-12
            )
        out["symbolic_saved_s"] = out["analyze_s"] * max(report.newton_iterations - 1, 0)
        out["assembly_below_factorisation"] = bool(out["assembly_s"] < out["factorize_s"])
    return out
