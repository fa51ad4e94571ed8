"""Independent check that no FEM node or MPM particle lies inside another FEM body, at the end
of a step and along its straight-line motion, and that no cell or particle inverted.

The barrier and its CCD-filtered line search guarantee that the Newton iterates, and the straight
segments between them, never cross a boundary (section 5). They do not make the step's own
straight-line trajectory x^n -> x^{n+1} (what the frames and the velocity v^{n+1} describe) free
of crossings: with a step far larger than the bodies (|v| dt >> size), frictionless iterates can
slide one body *around* the other in configuration space to the free-flight prediction x-hat, so
every iterate is clear, the end state is clear, and yet the bodies have passed through each other
within the step. This module checks both, with the geometry of :mod:`geometry` (not the
barrier's pairs or distances):

- the end state: every FEM node (interior ones too), every particle and every FEM cell centroid
  (which sees bodies overlapping with all vertices on the other's surface, e.g. equal aligned
  boxes) is tested against the cells (triangles / tetrahedra) of every *other* FEM body. Any
  point strictly inside is an ``"INTERSECTION"``.
- the trajectory (:func:`trajectory_crossing`): continuous collision detection of the step's
  straight-line motion (particles x_p^n -> x_p^{n+1}, FEM nodes likewise) of every FEM boundary
  node and particle against the boundary facets of every other FEM body, and in 3D of boundary
  edges of different bodies against each other, with the line search's rule (a CCD time is
  never later than the true impact: no false negative). A pair is certified clear when its CCD
  reaches the end of the step; one that comes within ``2 FLOOR_REL max|x|`` of touching is a
  crossing, ``"TUNNELED"``. Exact up to that floor: a pass through a body of any thickness is
  found, and so is a chord that cuts a convex corner of another body (the straight-line motion
  does enter it; issue 44, defect 1: a depth-thresholded sampling missed such cuts).
- inversion (:func:`step_inversion`): a FEM cell with J = det F <= 0, or a particle with
  det F_p <= 0, at the end of the step is ``"INVERTED"`` (reported before any crossing: an
  inverted cell's nodes may stick out into another body).

Broad phase: the swept-box spatial hash of :mod:`geometry.broadphase` through
``bfemp.contact.pairs`` (the barrier's), inflation 0; narrow phase: :mod:`geometry.ccd` over the
candidate pairs, vectorised, restarted where a round stops short (``_tunneling._certify``).

Cost: a few per cent of a barrier step on the rings demo, the 3D barrier reference and 3D FEM
boxes in sliding contact; corner cuts do fail the sine-boundary benchmark's quick mode as
TUNNELED (measured: design note ``measurements``, intersection).
"""

from __future__ import annotations

import numpy as np

from bfemp.contact._end_state import (
    Intersection,
    _describe,
    _points,
    end_of_step_points,
    points_inside,
)
from bfemp.contact._tunneling import FLOOR_REL, MAX_ROUNDS, trajectory_crossing
from bfemp.contact.inversion import Inversion, fem_cell_J, step_inversion
from bfemp.model import Model
from bfemp.state import State

__all__ = [
    "FLOOR_REL",
    "Intersection",
    "Inversion",
    "MAX_ROUNDS",
    "end_of_step_points",
    "fem_cell_J",
    "points_inside",
    "step_intersection",
    "step_inversion",
    "trajectory_crossing",
]


def step_intersection(model: Model, start: State, end: State) -> Intersection | None:
    """The first crossing of the step ``start -> end``, or None when there is none.

    First the end state (any FEM node, particle or cell centroid strictly inside a cell of
    another body: ``"INTERSECTION"``), then the straight-line motion (:func:`trajectory_crossing`:
    ``"TUNNELED"``). See the module docstring.

    Args:
        model: the static model (FEM cells, bodies, particles, contact).
        start, end: states at the start and the end of the step.
    """
    if len(model.fem_bodies) == 0:
        return None
    y1, body = _points(model, end)
    cell = points_inside(y1, body, end.fem_x, model.fem_cells, model.fem_cell_body)
    inside = np.flatnonzero(cell >= 0)
    if inside.size:  # the first point inside, in its first cell
        p = int(inside[0])
        return _describe(model, p, int(cell[p]), "INTERSECTION", 1.0, inside.size)
    return trajectory_crossing(model, start, end)
