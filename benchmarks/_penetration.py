"""How deep a benchmark run went inside FEM bodies, and the bound its strategy states (issue 40).

The trade study (``benchmarks.tradeoff``) judges every point against its strategy's declared
penetration guarantee (``bfemp.steppers.capabilities``): a point whose deepest penetration
exceeds the bound is infeasible. The two numbers are taken here, in the point's own process:

- ``max_penetration_m``: the largest value of the ``penetration_depth`` metrics column over the
  run (m; ``bfemp.contact.penetration``: the deepest any FEM node or particle lies inside
  another FEM body after a step, the same geometric check for every strategy), None where the
  run has no such column (no FEM body, or a FEM body alone);
- ``penetration_bound_m``: ``capabilities.penetration_bound_cells`` of the stepper's class, read
  when the point runs (the values are measured and change), times the spacing of the grid the
  strategy's contact lives on, ``penetration_grid_dx_m``. That grid is a choice the
  declaration leaves open ("cells of its grid"): the strategy's own contact grid where it has
  one (augury's ``grid_dx``, AUG sec. 2: the grid of the contact operator H), else the MPM
  background grid (lr's multi-material nodes, LR sec. 3.1). A bound of 0 cells (barrier,
  two_stage: nothing may end inside a FEM body) is 0 m whatever the grid; a strategy that
  couples nothing with a FEM body (``single_field``) has none (None).
"""

from __future__ import annotations

import math

import numpy as np

import bfemp

__all__ = ["COLUMN", "max_penetration", "penetration_bound", "penetration_summary"]

#: the metrics column of ``bfemp.Simulation`` read here
COLUMN = "penetration_depth"


def penetration_bound(stepper: object) -> dict:
    """The penetration bound of ``stepper``'s strategy on its grid.

    Args:
        stepper: a built stepper (``Simulation.stepper``, or one built directly); its class
            carries ``capabilities`` and, for a grid strategy, ``model.grid`` and perhaps its
            own ``grid_dx`` (module docstring).

    Returns:
        ``penetration_bound_cells`` (the class's declaration, None: no bound),
        ``penetration_grid_dx_m`` (m, the grid the cells are counted on; None where the bound
        does not need one: 0 or None cells) and ``penetration_bound_m`` (m; None where the
        strategy states no bound, or a bound in cells without a grid to count them on).
    """
    cells = type(stepper).capabilities.penetration_bound_cells
    out = {"penetration_bound_cells": cells, "penetration_grid_dx_m": None}
    if cells is None:
        return out | {"penetration_bound_m": None}
    if cells == 0.0:
        return out | {"penetration_bound_m": 0.0}
    dx = getattr(stepper, "grid_dx", None)  # a contact grid of its own (augury)
    if dx is None:
        grid = getattr(getattr(stepper, "model", None), "grid", None)
        dx = None if grid is None else float(grid.dx)
    bound = float(cells) * float(dx) if dx is not None else None
    return out | {"penetration_grid_dx_m": dx, "penetration_bound_m": bound}


def max_penetration(*sims: bfemp.Simulation) -> float | None:
    """The largest ``penetration_depth`` over the rows of every simulation given (m; NaN rows
    are skipped), None where none of them writes the column."""
    depths = [
        float(np.nanmax(col, initial=0.0))
        for sim in sims
        if COLUMN in sim.metrics.columns
        for col in [sim.metrics.column(COLUMN)]
    ]
    return max(depths) if depths else None


def penetration_summary(*sims: bfemp.Simulation) -> dict:
    """``max_penetration_m`` over the runs of ``sims`` (the parts of one benchmark run, e.g.
    the slope's settling and release, with one strategy on one grid) and the bound of the
    first one's stepper (``penetration_bound``): JSON-ready scalars."""
    if not sims:
        raise ValueError("penetration_summary: give at least one Simulation")
    depth = max_penetration(*sims)
    if depth is not None and not math.isfinite(depth):
        depth = None
    return {"max_penetration_m": depth, **penetration_bound(sims[0].stepper)}
