"""How deep a benchmark run went inside FEM bodies, and the bound its strategy states (issue 40).

The trade study (``benchmarks.tradeoff``) judges every point against its strategy's declared
penetration guarantee (``bfemp.steppers.capabilities``): a point whose deepest penetration
exceeds the bound is infeasible. The two numbers are taken here, in the point's own process:

- ``max_penetration_m``: the largest value of the ``penetration_depth`` metrics column over the
  run (m; ``bfemp.contact.penetration``: the deepest any FEM node or particle lies inside
  another FEM body after a step, the same geometric check for every strategy), None where the
  run has no such column (no FEM body, or a FEM body alone);
- ``penetration_bound_m``: ``capabilities.penetration_bound_cells`` of the stepper's class, read
  when the point runs (the values are measured and change), times ``penetration_grid_dx_m``.
  Which grid's cells is a choice the declaration leaves open ("dx of the MPM grid, or of the
  strategy's contact grid"); taken here: the MPM background grid of the scene (the point's
  ``dx``: lr's multi-material nodes, LR sec. 3.1, and the grid augury's MPM foreground comes
  from), and the strategy's own contact grid only where the scene has no MPM grid (augury on
  FEM bodies alone, ``augury_blocks``: ``grid_dx``, the grid of AUG's contact operator H).
  Measured why not augury's contact grid always: on the quick slope it is 0.442 m (2 x the
  mean FEM boundary edge of the coarse slope mesh) where the MPM grid is 5 mm, a bound 88 x
  looser than the scene's resolution that no penetration of the box could exceed. Both
  spacings are recorded (``penetration_mpm_grid_dx_m``, ``penetration_contact_grid_dx_m``),
  so that a report can be rerendered under the other reading without running the point again.
  A bound of 0 cells (barrier, two_stage: nothing may end inside a FEM body) is 0 m whatever
  the grid; a strategy that couples nothing with a FEM body (``single_field``) has none (None).
"""

from __future__ import annotations

import math

import numpy as np

import bfemp

__all__ = ["COLUMN", "KEYS", "max_penetration", "penetration_bound", "penetration_summary"]

#: the metrics column of ``bfemp.Simulation`` read here
COLUMN = "penetration_depth"
#: what a run reports (``penetration_summary``; m, but the cells)
KEYS = (
    "max_penetration_m",
    "penetration_bound_m",
    "penetration_bound_cells",
    "penetration_grid_dx_m",
    "penetration_mpm_grid_dx_m",
    "penetration_contact_grid_dx_m",
)


def penetration_bound(stepper: object) -> dict:
    """The penetration bound of ``stepper``'s strategy on its grid.

    Args:
        stepper: a built stepper (``Simulation.stepper``, or one built directly); its class
            carries ``capabilities``, its ``model.grid`` the MPM grid (None without particles)
            and, for augury, ``grid_dx`` its own contact grid (module docstring).

    Returns:
        ``penetration_bound_cells`` (the class's declaration, None: no bound),
        ``penetration_mpm_grid_dx_m`` and ``penetration_contact_grid_dx_m`` (m, None where
        there is no such grid), ``penetration_grid_dx_m`` (m, the one the cells are counted
        on: the MPM grid, else the contact grid; None where the bound needs none: 0 or None
        cells) and ``penetration_bound_m`` (m; None where the strategy states no bound, or a
        bound in cells without a grid to count them on).
    """
    cells = type(stepper).capabilities.penetration_bound_cells
    grid = getattr(getattr(stepper, "model", None), "grid", None)
    mpm_dx = None if grid is None else float(grid.dx)
    contact_dx = getattr(stepper, "grid_dx", None)  # a contact grid of its own (augury)
    out = {
        "penetration_bound_cells": cells,
        "penetration_mpm_grid_dx_m": mpm_dx,
        "penetration_contact_grid_dx_m": None if contact_dx is None else float(contact_dx),
        "penetration_grid_dx_m": None,
    }
    if cells is None:
        return out | {"penetration_bound_m": None}
    if cells == 0.0:
        return out | {"penetration_bound_m": 0.0}
    dx = mpm_dx if mpm_dx is not None else out["penetration_contact_grid_dx_m"]
    bound = float(cells) * dx if dx is not None else None
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
