"""How deep anything lies inside a FEM body: one geometric check for every strategy.

``Simulation`` writes the ``penetration_depth`` metrics column from :class:`PenetrationCheck`
after every step, whatever the strategy, so that strategies are compared on the same measure
and a strategy's own notes (augury's ``INTERPENETRATION``, ...) are not the only witness. It
uses geometry alone (no barrier, no contact grid): every FEM node and every particle is tested
against the triangles / tetrahedra of every *other* FEM body (strict barycentric inside test,
:func:`bfemp.contact.intersection.points_inside`), and a point inside gets its distance to that
body's boundary facets (brute force over the body's facets: only inside points pay it).

A point on or outside the boundary has depth 0; the column is the largest depth in m. The depth
of a point inside a body is at most half that body's thickness, and a point that went all the
way through a body is outside it again (depth 0): where bodies end up is for other checks to say
(the conformance catalogue's ``held`` and ``no_pass``, the barrier's ``TUNNELED``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bfemp.contact.intersection import points_inside
from bfemp.model import Model
from bfemp.state import State
from geometry.distance import point_edge_distance, point_triangle_distance

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
        #: each FEM body's boundary facets (k, d) (global node indices), by body index
        self.facets = {b.index: np.asarray(b.boundary, dtype=np.int64) for b in model.fem_bodies}

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
        depth = np.zeros(point.size)
        for b in np.unique(body):  # the bodies that hold points: a few; vectorised inside
            depth[body == b] = self._distance(y[point[body == b]], state.fem_x, self.facets[b])
        return Penetration(depth, point, body)

    @staticmethod
    def _distance(y: np.ndarray, x: np.ndarray, facets: np.ndarray) -> np.ndarray:
        """Distance ``(n,)`` in m of points ``y (n, d)`` to the nearest of ``facets (k, d)``
        (segments in 2D, triangles in 3D; vertices in ``x``), in chunks of about 1e6 pairs."""
        out = np.empty(y.shape[0])
        chunk = max(1, 1_000_000 // max(1, facets.shape[0]))
        for lo in range(0, y.shape[0], chunk):
            q = y[lo : lo + chunk]
            p = np.repeat(q, facets.shape[0], axis=0)
            f = np.tile(facets, (q.shape[0], 1))
            vertices = [x[f[:, a]] for a in range(facets.shape[1])]
            dist = (point_edge_distance if len(vertices) == 2 else point_triangle_distance)(
                p, *vertices
            )
            out[lo : lo + chunk] = dist.reshape(q.shape[0], facets.shape[0]).min(axis=1)
        return out

    def depth(self, state: State) -> float:
        """The largest penetration depth in m (0.0 when nothing is inside another FEM body)."""
        return self.points(state).max_depth
