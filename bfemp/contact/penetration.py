"""How deep anything lies inside a FEM body: one geometric check for every strategy.

``Simulation`` writes the ``penetration_depth`` metrics column from :class:`PenetrationCheck`
after every step, whatever the strategy, so that strategies are compared on the same measure
and a strategy's own notes (augury's ``INTERPENETRATION``, ...) are not the only witness. It
uses geometry alone (no barrier, no contact grid): every FEM node and every particle is tested
against the triangles / tetrahedra of every *other* FEM body (strict barycentric inside test,
:func:`bfemp.contact.intersection.points_inside`), and a point inside gets its distance to that
body's boundary facets (brute force over the body's facets: only inside points pay it).

A point on or outside the boundary has depth 0; the column is the largest depth in m.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bfemp.contact.intersection import _boundary_facets, _surface_distance, points_inside
from bfemp.model import Model
from bfemp.state import State

__all__ = ["Penetration", "PenetrationCheck"]


@dataclass(frozen=True)
class Penetration:
    """The points inside other FEM bodies in one state.

    Attributes:
        depth: ``(n,)`` distance in m of each inside point to the boundary of the body it is in.
        point: ``(n,)`` index of each inside point: FEM nodes 0..N-1, then particles N..N+P-1.
        body: ``(n,)`` index of the FEM body each point is inside.
    """

    depth: np.ndarray
    point: np.ndarray
    body: np.ndarray

    @property
    def max_depth(self) -> float:
        """The deepest point's depth in m (0.0 when nothing is inside)."""
        return float(self.depth.max(initial=0.0))


class PenetrationCheck:
    """The point-in-body test of one model (module docstring); build with :meth:`for_model`."""

    def __init__(self, model: Model) -> None:
        self.model = model
        node_body = np.repeat(
            np.array([b.index for b in model.fem_bodies], dtype=np.int64),
            [b.n_nodes for b in model.fem_bodies],
        )
        # particles get ids no cell has (negative), so they are tested against every FEM body
        self.point_body = np.concatenate([node_body, -1 - model.mpm_particle_body])
        self.facets, self.facet_start = _boundary_facets(model)

    @classmethod
    def for_model(cls, model: Model) -> PenetrationCheck | None:
        """The check, or None when nothing can be inside a FEM body (no FEM body, or a FEM body
        alone)."""
        n_bodies = len(model.fem_bodies) + len(model.mpm_bodies)
        if not model.fem_bodies or n_bodies < 2:
            return None
        return cls(model)

    def points(self, state: State) -> Penetration:
        """The FEM nodes and particles of ``state`` inside another FEM body, with their depths."""
        model = self.model
        y = np.ascontiguousarray(np.concatenate([state.fem_x, state.mpm_x]))
        cell = points_inside(y, self.point_body, state.fem_x, model.fem_cells, model.fem_cell_body)
        point = np.flatnonzero(cell >= 0)
        body = np.ascontiguousarray(model.fem_cell_body[cell[point]], dtype=np.int64)
        if point.size == 0:
            return Penetration(np.zeros(0), point, body)
        v = np.ascontiguousarray(state.fem_x)
        depth = _surface_distance(
            y, y, v, v, self.facets, self.facet_start, point.astype(np.int64), body, 1.0
        )
        return Penetration(depth, point, body)

    def depth(self, state: State) -> float:
        """The largest penetration depth in m (0.0 when nothing is inside another FEM body)."""
        return self.points(state).max_depth
