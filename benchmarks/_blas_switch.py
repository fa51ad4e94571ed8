"""Reference BLAS against the optimised one, side by side in one benchmark run.

The BLAS a process uses is fixed when the dynamic loader resolves ``libblas.so.3`` (and
``liblapack.so.3``, which on Debian's OpenBLAS loads OpenBLAS too), so the switch is per process:
a child process started with ``LD_LIBRARY_PATH`` pointing at the reference BLAS and LAPACK
directories runs on them; one started without runs on the system default (OpenBLAS once
``make setup`` installed it).  :func:`factorisation_by_blas` times CHOLMOD's numeric
factorisation of the same matrices in both.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

import scipy.sparse as sp

from benchmarks._shared import child_json

__all__ = ["REFERENCE_DIRS", "factorisation_by_blas", "reference_blas_env"]

#: where Debian installs the reference BLAS and LAPACK (libblas3, liblapack3)
REFERENCE_DIRS = ("/usr/lib/x86_64-linux-gnu/blas", "/usr/lib/x86_64-linux-gnu/lapack")

_CHILD = """
import json, sys, time
import numpy as np, scipy.sparse as sp
from solvers.blas import cholmod_blas
from solvers.linear import CholmodSolver
out = {"blas": cholmod_blas().name, "factorize_s": {}}
for name, path in json.loads(sys.argv[1]).items():
    A = sp.load_npz(path).tocsc()
    solver = CholmodSolver()
    best = float("inf")
    for _ in range(int(sys.argv[2]) + 1):  # the first call pays the analysis
        solver.solve(A, np.ones(A.shape[0]))
        best = min(best, solver.last_timings["factorize"])
    out["factorize_s"][name] = best
print(json.dumps(out))
"""


def reference_blas_env() -> dict | None:
    """The environment of a child process on the reference BLAS, or None if not installed."""
    if not all(Path(d, f"lib{Path(d).name}.so.3").exists() for d in REFERENCE_DIRS):
        return None
    env = dict(os.environ)
    env["LD_LIBRARY_PATH"] = ":".join([*REFERENCE_DIRS, env.get("LD_LIBRARY_PATH", "")]).rstrip(":")
    return env


def factorisation_by_blas(matrices: dict[str, sp.spmatrix], repeats: int = 3) -> dict:
    """CHOLMOD numeric factorisation seconds (best of ``repeats``) under each BLAS.

    Args:
        matrices: name -> symmetric positive definite matrix.
        repeats: timed factorisations per matrix and BLAS.

    Returns:
        ``{"default": {"blas": name, "factorize_s": {...}}, "default_1_thread": {...} (the
        default BLAS limited to one thread), "reference": {...} or None, "speedup": {name:
        reference / default}}``.
    """
    with tempfile.TemporaryDirectory() as tmp:
        paths = {name: str(Path(tmp, f"{name}.npz")) for name in matrices}
        for name, A in matrices.items():
            sp.save_npz(paths[name], sp.csc_matrix(A))

        def child(env: dict | None) -> dict | None:  # a failed child is recorded, not fatal
            if env is None:
                return None
            args = (json.dumps(paths), str(repeats))
            return {"blas": None, "factorize_s": {}} | child_json(
                _CHILD, *args, env=env, timeout=1800
            )

        default = child(dict(os.environ))
        # the same BLAS on one thread: oversubscription on a shared machine, measured
        one_thread = child(dict(os.environ, OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1"))
        reference = child(reference_blas_env())
    speedup = {}
    if reference is not None and "error" not in reference and "error" not in default:
        speedup = {
            name: float(reference["factorize_s"][name] / max(default["factorize_s"][name], 1e-12))
            for name in matrices
        }
    return {
        "default": default,
        "default_1_thread": one_thread,
        "reference": reference,
        "speedup": speedup,
        "repeats": repeats,
    }
