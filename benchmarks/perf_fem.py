"""Per-Newton-iteration cost of the implicit FEM core on large meshes (issue: implicit FEM core).

Cases (full mode): a 3D box of ~50k tetrahedra and a 2D rectangle of ~100k triangles, Neo-Hookean,
bottom face clamped, under gravity, one backward-Euler step with a large dt so that Newton takes
several iterations of large deformation. Quick mode uses ~8k tets / ~16k triangles.

Recorded per case:
- ``assembly``: value + gradient + projected Hessian (local blocks) + triplet-to-CSC build, at one
  iterate, median of repeats; ``factorize``: CHOLMOD numeric factorisation of the same matrix;
  ``analyze``: CHOLMOD symbolic analysis; ``solve``: triangular solves;
- the Newton step's own timing split (assemble, factorize, line search, ...) and iteration count;
- ``symbolic_saved_s``: symbolic analyses avoided by reuse times the analysis cost.
Target: assembly < factorisation.
"""

from __future__ import annotations

from pathlib import Path

from benchmarks import catalogue
from benchmarks._phases import (
    PERF_TIMINGS,
    cases_and_blas,
    newton_phases,
    plot_phases,
    warm_stepper,
)
from benchmarks.runner import Benchmark, name_unless, register

CASES = {
    "full": {"3d": dict(n=(32, 16, 16)), "2d": dict(n=(448, 112))},
    "quick": {"3d": dict(n=(16, 8, 8)), "2d": dict(n=(160, 40))},
}


def _measure(name: str, matrices: dict, dim: int, n: tuple[int, ...]) -> dict:
    model = catalogue.fem_block_scene(dim, n).build()
    stepper, state = warm_stepper(model, dt=0.05, tol=1e-5)
    out = {"dim": dim, "cells": int(model.fem_cells.shape[0]), "nodes": int(model.n_fem_nodes)}
    out.update(newton_phases(stepper, state, matrices=matrices, name=name, step_repeats=3))
    return out


def measure(mode: str, cases: dict) -> dict:
    """Both cases of ``mode``, and CHOLMOD on each case's Hessian per BLAS."""
    return cases_and_blas(cases, _measure)


def plot(payload: dict, png: Path) -> None:
    """Seconds of assembly and CHOLMOD per Newton iteration, per case."""
    title = "Per Newton iteration: assembly vs CHOLMOD"
    plot_phases(payload, png, ("assembly", "factorize", "analyze"), "cells", title)


QUICK_RECORD = name_unless("full", "perf_fem")
BENCHMARK = register(
    Benchmark(
        "perf_fem", __doc__, CASES, measure, plot=plot, record=QUICK_RECORD, timings=PERF_TIMINGS
    )
)
run = BENCHMARK.run
