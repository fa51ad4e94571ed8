"""Numerics only: projected Newton, line search, linear solvers, sparse assembly, PSD projection.

Imports numpy, scipy, scikit-sparse and numba; never imports ``geometry`` or ``bfemp``.
"""

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
from solvers.options import NewtonOptions
from solvers.psd import is_symmetric_psd, project_psd
from solvers.result import TIMING_KEYS, NewtonIteration, NewtonResult, NewtonStatus

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
