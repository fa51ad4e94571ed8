"""How deep a benchmark run went inside FEM bodies, and the bound its strategy states (issue 40).

The trade study (``benchmarks.tradeoff``) judges every point against its strategy's declared
penetration guarantee (``bfemp.steppers.capabilities``): a point whose deepest penetration
(``max_penetration_m``: the largest ``penetration_depth`` of the run's metrics,
``bfemp.contact.penetration``) exceeds the bound (``penetration_bound``) is infeasible.

Which grid's cells the bound counts is a choice the declaration leaves open ("dx of the MPM
grid, or of the strategy's contact grid"); taken here: the MPM background grid of the scene
(lr's multi-material nodes, LR sec. 3.1, and the grid augury's MPM foreground comes from), and
the strategy's own contact grid only where the scene has no MPM grid (augury on FEM bodies
alone, ``augury_blocks``: ``grid_dx``, the grid of AUG's contact operator H). Measured why not
augury's contact grid always: on the quick slope it is 0.442 m where the MPM grid is 5 mm, a
bound 88 x looser than the scene's resolution. Both spacings are recorded, so that a report
can be rerendered under the other reading without running the point again.
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
        stepper: a built stepper; its class carries ``capabilities`` (read when the point runs:
            the values are measured and change), its ``model.grid`` the MPM grid (None without
            particles) and, for augury, ``grid_dx`` its own contact grid (module docstring).

    Returns:
        ``penetration_bound_cells`` (None: no bound, single_field), ``penetration_mpm_grid_dx_m``
        and ``penetration_contact_grid_dx_m`` (m, None where there is no such grid),
        ``penetration_grid_dx_m`` (m, the one the cells are counted on; None where the bound
        needs none: 0 or None cells) and ``penetration_bound_m`` (m; 0 for a bound of 0 cells,
        barrier and two_stage; None without a bound or a grid to count it on).
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
