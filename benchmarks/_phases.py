"""Per-Newton-iteration phase costs of an implicit step, shared by the perf benchmarks."""

from __future__ import annotations

import statistics
import time

import numpy as np

from benchmarks._blas_switch import factorisation_by_blas
from benchmarks.runner import Benchmark, name_unless, register
from solvers.assembly import TripletAssembler
from solvers.choice import make_linear_solver
from solvers.linear import cholmod_available

#: the keys of the perf records that hold times or ratios of times (``runner.verify``)
PERF_TIMINGS = r"_s$|over_factorisation|below_factorisation|fraction_of_iteration"
MACHINE_NOTE = "2 shared cores, loaded by other work: compare ratios within this run"


def newton_benchmark(
    name: str, doc: str, cases: dict, measure_one, phases: tuple, size: str, title: str
):
    """Register the per-Newton-iteration benchmark ``name`` (``perf_fem``, ``perf_mpm``): each
    case of a mode measured by ``measure_one(name, matrices, dim, **parameters)`` (dim 2 for the
    case ``"2d"``, else 3), which adds the case's Hessian to ``matrices``; then CHOLMOD's
    factorisation of each Hessian on the reference and the default BLAS (per process). Its plot:
    bars of the seconds per Newton iteration of ``phases`` (record keys ``PHASE_s``) per case,
    each labelled with its ``size`` key, under ``title``. Records: ``name.json`` (full mode),
    ``name_MODE.json``."""

    def measure(mode: str, cfg: dict) -> dict:
        matrices: dict = {}
        measured = {
            case: measure_one(case, matrices, 2 if case == "2d" else 3, **parameters)
            for case, parameters in cfg.items()
        }
        blas = factorisation_by_blas(matrices)
        return {"cases": measured, "blas_side_by_side": blas, "machine_note": MACHINE_NOTE}

    def plot(payload: dict, png) -> None:
        from bfemp.plotting import plot_bars

        cases = payload["cases"]
        labels = [f"{k} ({c[size]} {size})" for k, c in cases.items()]
        groups = {p: [c.get(f"{p}_s", np.nan) for c in cases.values()] for p in phases}
        plot_bars(labels, groups, png, ylabel="seconds", title=title)

    measure.__module__ = measure_one.__module__  # the module of the entry (runner.Benchmark)
    record = name_unless("full", name)
    return register(
        Benchmark(name, doc, cases, measure, plot=plot, record=record, timings=PERF_TIMINGS)
    )


def barrier_stepper(model, dt: float, tol: float | None = None, **options):
    """A barrier stepper (backward Euler, step ``dt`` s, Newton tolerance ``tol`` m/s or the
    default one, other ``BarrierOptions`` fields from ``options``) on ``model``."""
    from bfemp.integrators import BACKWARD_EULER
    from bfemp.steppers.barrier import BarrierOptions, BarrierStepper

    options = BarrierOptions(**options, **({} if tol is None else {"tol": tol}))
    return BarrierStepper(model, integrator=BACKWARD_EULER, dt=dt, options=options)


def warm_stepper(model, dt: float, tol: float, **options):
    """``barrier_stepper(model, dt, tol, **options)`` and the state after one step (the warm-up
    that compiles the numba kernels): ``(stepper, state)``."""
    stepper = barrier_stepper(model, dt, tol, **options)
    state, _ = stepper.step(stepper.initialize(model.initial_state()))
    return stepper, state


def timed(fn):
    """``(fn(), its wall time in s)``."""
    start = time.perf_counter()
    value = fn()
    return value, time.perf_counter() - start


def wall_times(fn, repeats: int) -> list[float]:
    """Wall times in s of ``repeats`` consecutive calls of ``fn()``."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return times


def median_time(fn, repeats: int = 3) -> float:
    """Median wall time of ``fn()`` over ``repeats`` calls, in s."""
    return statistics.median(wall_times(fn, repeats))


def newton_phases(
    stepper,
    state,
    solver_name: str = "cholmod",
    matrices: dict | None = None,
    name: str = "",
    step_repeats: int = 1,
) -> dict:
    """Step from ``state`` (timed), then time each phase at the start of that step.

    With ``step_repeats`` > 1 the same step is taken that many times and the one of median
    Newton time is reported (``step_times_s`` lists them all): on shared cores one step's
    factorisations vary by +-20 % (measured on perf_mpm 2D: 0.30 to 0.45 s in one run).

    The floor ``factorize_s`` is the numeric factorisation (for ``cg_amg``: the CG solve with
    a kept hierarchy) of the Hessian at the start of the step by a fresh ``solver_name`` solver;
    ``newton_over_factorisation`` = time per Newton iteration / that floor (issue 13 target
    <= 1.5), ``linear_solves`` the factorisations the step made (the convergence test at the
    last iterate and rejected exact-Hessian tries included). With ``matrices`` the Hessian
    at the start of the step is stored there under ``name`` (for the BLAS side by side).
    """
    if not (isinstance(step_repeats, int) and step_repeats >= 1):
        raise ValueError(f"step_repeats must be an int >= 1, got {step_repeats!r}")
    steps = []  # (Newton time, wall time, report, factorisations made) per repeat
    for _ in range(step_repeats):
        n_before = getattr(stepper.linear_solver, "n_numeric", None)
        start = time.perf_counter()
        _, report = stepper.step(state)
        wall = time.perf_counter() - start
        made = None if n_before is None else int(stepper.linear_solver.n_numeric - n_before)
        steps.append((report.timings.get("total", wall), wall, report, made))
    newton_s, step_wall, report, n_made = sorted(steps, key=lambda s: s[0])[(step_repeats - 1) // 2]
    phases = stepper.phases(state)
    pot = phases.potential
    y = pot.to_unknowns(phases.x0)
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
        "time_per_newton_iteration_s": newton_s / max(report.newton_iterations, 1),
        "step_times_s": [s[0] for s in steps],
    }
    pot.solution_changed(y)
    out["value_s"] = median_time(lambda: pot.value(y))
    out["gradient_s"] = median_time(lambda: pot.gradient(y))
    out["hessian_local_s"] = median_time(lambda: pot.hessian(y, psd=True))
    matrix = assembler.assemble(pot.hessian(y, psd=True))
    out["nnz"] = int(matrix.nnz)
    if matrices is not None:
        matrices[name] = matrix
    csc_s = median_time(lambda: assembler.assemble(pot.hessian(y, psd=True)))
    out["triplets_to_csc_s"] = max(csc_s - out["hessian_local_s"], 0.0)
    if n_made is not None:
        # one linear solve per iteration plus the convergence test at the last iterate (and
        # any rejected exact-Hessian try): the cost of one solve's worth of Newton work
        out["linear_solves"] = n_made
        out["time_per_linear_solve_s"] = newton_s / max(n_made, 1)
    out["linear_solver"] = solver_name
    if cholmod_available() or solver_name != "cholmod":
        solver = make_linear_solver(solver_name, block_size=stepper.model.dim)
        rhs = np.ones(y.size)
        solver.solve(matrix, rhs)
        out["analyze_s"] = solver.last_timings["analyze"]
        runs = []
        for _ in range(3):
            solver.solve(matrix, rhs)
            runs.append(dict(solver.last_timings))
        factorize = [r["factorize"] for r in runs]
        out["factorize_median_s"] = statistics.median(factorize)
        out["solve_s"] = min(r["solve"] for r in runs)
        floor = out["solve_s"] if solver_name == "cg_amg" else min(factorize)
        out["factorize_s"] = floor
        out["newton_over_factorisation"] = out["time_per_newton_iteration_s"] / max(floor, 1e-12)
        if n_made is not None:
            out["linear_solve_over_factorisation"] = out["time_per_linear_solve_s"] / max(
                floor, 1e-12
            )
        out["symbolic_saved_s"] = out["analyze_s"] * max(report.newton_iterations - 1, 0)
        out["assembly_below_factorisation"] = bool(out["assembly_s"] < floor)
    return out
