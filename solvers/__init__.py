"""Numerics only: projected Newton, line search, linear solvers, sparse assembly, PSD projection.

Imports numpy, scipy, scikit-sparse and numba; never imports ``geometry`` or ``bfemp``.
"""

import os as _os

# OpenMP threads (CHOLMOD's, and numba's where its TBB layer is not installed) spin-wait between
# parallel regions by default; on small machines that costs milliseconds per kernel call
# (measured: 8 ms vs 13 us for a 200-particle kernel on 2 cores). Passive waiting must be set
# before the OpenMP runtime starts.
_os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")


from solvers.allocator import keep_freed_memory as _keep_freed_memory
from solvers.assembly import TripletAssembler, Triplets
from solvers.line_search import LineSearchResult, backtracking_line_search
from solvers.linear import (
    CholmodSolver,
    LinearSolveError,
    LinearSolver,
    ScipySolver,
    cholmod_available,
    default_linear_solver,
)
from solvers.newton import Objective, minimize
from solvers.numba_threads import prefer_tbb as _prefer_tbb
from solvers.options import NewtonOptions
from solvers.psd import is_symmetric_psd, project_psd
from solvers.result import TIMING_KEYS, NewtonIteration, NewtonResult, NewtonStatus

# Newton's large arrays come from the heap, reused, instead of fresh pages from the kernel at
# every iteration (3x on the 3D MPM Hessian on a VM that reports freed pages to its host:
# solvers.allocator); BFEMP_KEEP_FREED_MEMORY=0 leaves glibc's defaults.
_keep_freed_memory()

# numba's kernels on TBB's pool: a parallel region costs 2-10 us instead of a ~45 us wake-up of
# passive OpenMP threads (solvers.numba_threads); before any kernel starts numba's threads
_prefer_tbb()

__all__ = [
    "TIMING_KEYS",
    "CholmodSolver",
    "LineSearchResult",
    "LinearSolveError",
    "LinearSolver",
    "NewtonIteration",
    "NewtonOptions",
    "NewtonResult",
    "NewtonStatus",
    "Objective",
    "ScipySolver",
    "TripletAssembler",
    "Triplets",
    "backtracking_line_search",
    "cholmod_available",
    "default_linear_solver",
    "is_symmetric_psd",
    "minimize",
    "project_psd",
]
