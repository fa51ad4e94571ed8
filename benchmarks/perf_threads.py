"""Thread counts of BLAS (under CHOLMOD) and numba (assembly), measured both ways (issue 13).

A barrier step runs its numba kernels (local Hessians, assembly, CCD) and CHOLMOD's BLAS one
after the other, never at once, so both pools may use every core without oversubscribing them
in principle; OpenBLAS's worker threads spin for a while after each call, though, and may slow
the numba kernels that follow. Each combination of ``OPENBLAS_NUM_THREADS``/``MKL_NUM_THREADS``
and ``NUMBA_NUM_THREADS`` in {1, cores} runs in its own child process (pool sizes are fixed at
start-up), on the same scenes: a 3D MPM block on a slip floor and a 3D FEM block
(``perf_mpm``/``perf_fem`` scenes), one warm-up step and then the best of ``repeats`` timed
steps. The record names the fastest combination per scene and compares it with the library's
default (no variable set: both pools at the core count).
"""

from __future__ import annotations

import json
import logging
import os

from benchmarks._shared import child_json
from benchmarks.runner import Benchmark, name_unless, register

log = logging.getLogger(__name__)

NAME = "perf_threads"

MODES = {
    "quick": {"mpm3d": ((8, 8, 4), 8), "fem3d": (6, 4, 4), "repeats": 2},
    "full": {"mpm3d": ((14, 14, 7), 8), "fem3d": (16, 8, 8), "repeats": 3},
    # what tests/benchmarks/test_perf_threads.py runs
    "smoke": {"mpm3d": ((4, 4, 2), 8), "fem3d": (3, 2, 2), "repeats": 1},
}

_CHILD = """
import json, sys
import numba
from benchmarks import catalogue
from benchmarks._phases import wall_times, warm_stepper
from solvers.blas import cholmod_blas
cfg = json.loads(sys.argv[1])
scenes = {
    "mpm3d": (catalogue.mpm_block_scene(3, tuple(cfg["mpm3d"][0]), cfg["mpm3d"][1]), 0.01),
    "fem3d": (catalogue.fem_block_scene(3, tuple(cfg["fem3d"])), 0.05),
}
blas = cholmod_blas()
out = {"blas": blas.name, "blas_threads": blas.threads, "numba_threads": numba.get_num_threads(),
       "step_s": {}}
for name, (scene, dt) in scenes.items():
    # warm-up: numba compilation (cached) and the symbolic analysis
    stepper, _ = warm_stepper(scene.build(), dt, 1e-4)
    state0 = stepper.initialize(stepper.model.initial_state())
    out["step_s"][name] = min(wall_times(lambda: stepper.step(state0), cfg["repeats"]))
print(json.dumps(out))
"""

_POOL_VARS = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "OMP_NUM_THREADS", "NUMBA_NUM_THREADS")


def _child(cfg: dict, blas_threads: int | None, numba_threads: int | None) -> dict:
    """``_CHILD`` with the pools of the given sizes (None: the variable unset)."""
    env = {k: v for k, v in os.environ.items() if k not in _POOL_VARS}
    if blas_threads is not None:
        env["OPENBLAS_NUM_THREADS"] = env["MKL_NUM_THREADS"] = str(blas_threads)
    if numba_threads is not None:
        env["NUMBA_NUM_THREADS"] = str(numba_threads)
    row = child_json(_CHILD, json.dumps(cfg), env=env)
    if "error" in row:
        raise RuntimeError(f"{NAME}: blas {blas_threads}, numba {numba_threads}: {row['error']}")
    return row


def measure(mode: str, cfg: dict) -> dict:
    """The scenes of ``mode`` under each thread combination."""
    cores = os.cpu_count() or 1
    counts = sorted({1, cores})
    combos = {"default": (None, None)}
    combos |= {f"blas{b}_numba{nb}": (b, nb) for b in counts for nb in counts}
    rows = {name: _child(cfg, *threads) for name, threads in combos.items()}
    step_s = {name: row["step_s"] for name, row in rows.items()}
    fastest = {s: min(rows, key=lambda r: step_s[r][s]) for s in step_s["default"]}
    for s, best in fastest.items():
        log.info("%s: fastest %s %s, default %s", s, best, step_s[best][s], step_s["default"][s])
    return {
        "cores": cores,
        "parameters": dict(cfg),
        "rows": rows,
        "fastest": fastest,
        "default_over_fastest": {
            s: step_s["default"][s] / step_s[f][s] for s, f in fastest.items()
        },
    }


BENCHMARK = register(
    Benchmark(NAME, __doc__, MODES, measure, record=name_unless("full", NAME), timings=r"_s$")
)
run = BENCHMARK.run
