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

from benchmarks import catalogue
from benchmarks._phases import newton_benchmark, newton_phases, warm_stepper

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


PHASES = ("assembly", "factorize", "analyze")
TITLE = "Per Newton iteration: assembly vs CHOLMOD"
BENCHMARK = newton_benchmark("perf_fem", __doc__, CASES, _measure, PHASES, "cells", TITLE)
run = BENCHMARK.run
