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

import bfemp
from benchmarks._blas_switch import factorisation_by_blas
from benchmarks._phases import newton_phases
from benchmarks.runner import Benchmark, name_unless, register
from bfemp.integrators import BACKWARD_EULER
from bfemp.plotting import plot_bars
from bfemp.steppers.barrier import BarrierOptions, BarrierStepper

CASES = {
    "full": {"3d": dict(n=(32, 16, 16)), "2d": dict(n=(448, 112))},
    "quick": {"3d": dict(n=(16, 8, 8)), "2d": dict(n=(160, 40))},
}


def _scene(dim: int, n: tuple[int, ...]) -> bfemp.Scene:
    h = 1.0 / n[-1]
    upper = tuple(k * h for k in n)
    lower = (0.0,) * dim
    mesh = (
        bfemp.shapes.rectangle(lower, upper, h=h)
        if dim == 2
        else bfemp.shapes.box(lower, upper, h=h)
    )
    g = (0.0,) * (dim - 1) + (-9.81,)
    scene = bfemp.Scene(dim=dim, gravity=g)
    scene.add_fem(
        mesh,
        material=bfemp.NeoHookean(E=1e5, nu=0.3, density=1000.0),
        prescribed=bfemp.motion.Fixed(),
        prescribed_nodes=mesh.points[:, 0] < 1e-9,
        name="block",
    )
    return scene


def _measure(name: str, matrices: dict, dim: int, n: tuple[int, ...]) -> dict:
    model = _scene(dim, n).build()
    stepper = BarrierStepper(
        model,
        integrator=BACKWARD_EULER,
        dt=0.05,
        options=BarrierOptions(tol=1e-5),
    )
    state = stepper.initialize(model.initial_state())
    state, _ = stepper.step(state)  # warm-up: compiles the numba kernels
    out = {"dim": dim, "cells": int(model.fem_cells.shape[0]), "nodes": int(model.n_fem_nodes)}
    out.update(newton_phases(stepper, state, matrices=matrices, name=name, step_repeats=3))
    return out


def measure(mode: str, cases: dict) -> dict:
    """Both cases of ``mode``, and CHOLMOD on each case's Hessian per BLAS."""
    matrices: dict = {}
    cases = {
        name: _measure(name, matrices, 2 if name == "2d" else 3, cfg["n"])
        for name, cfg in cases.items()
    }
    return {
        "cases": cases,
        # CHOLMOD factorisation of each case's Hessian, reference vs default BLAS (per process)
        "blas_side_by_side": factorisation_by_blas(matrices),
        "machine_note": "2 shared cores, loaded by other work: compare ratios within this run",
    }


def plot(payload: dict, png: Path) -> None:
    """Seconds of assembly and CHOLMOD per Newton iteration, per case."""
    labels, groups = [], {"assembly": [], "factorize": [], "analyze": []}
    for name, case in payload["cases"].items():
        labels.append(f"{name} ({case['cells']} cells)")
        for key in groups:
            groups[key].append(case.get(f"{key}_s", float("nan")))
    plot_bars(
        labels,
        groups,
        png,
        ylabel="seconds",
        title="Per Newton iteration: assembly vs CHOLMOD",
    )


BENCHMARK = register(
    Benchmark(
        "perf_fem",
        __doc__,
        CASES,
        measure,
        plot=plot,
        record=name_unless("full", "perf_fem"),
        timings=r"_s$|over_factorisation|fraction_of_iteration",
    )
)
run = BENCHMARK.run
