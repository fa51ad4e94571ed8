"""The barrier contact potential B(x) of eqs. 28-32 as an energy term, with the CCD step bound.

B(x) = sum over active pairs of omega_q c b(d), with b the clamped log barrier of eq. 27, c the
duplicate-removal coefficient (1 for facets) and omega_q the point's integration weight (section
4.2). Derivatives chain from the unsigned distance to the pair's collision points, then to nodes
through the affine collision map (eq. 29). Local Hessians are projected to PSD per pair before the
chain rule. ``max_step_size`` returns 0.9 x the earliest time of impact of any point against any
facet along the linear path x -> x + p (section 5), so no iterate ever crosses a boundary.
"""

from __future__ import annotations

import logging

import numpy as np

from bfemp.contact._assembly_kernels import _count_entries, _fill_triplets, _scatter_gradient
from bfemp.contact.barrier import barrier, barrier_derivative, barrier_second_derivative
from bfemp.contact.collision import CollisionSet, build_collision_set
from bfemp.contact.pairs import ContactPairs, candidate_pairs, find_pairs
from bfemp.terms.base import StepContext
from geometry import distance as dist
from geometry.ccd import point_edge_ccd, point_triangle_ccd
from solvers.assembly import Triplets
from solvers.psd import project_psd

__all__ = ["BarrierTerm", "CCD_FRACTION"]

log = logging.getLogger(__name__)

#: Fraction of the earliest time of impact used as the line-search start (section 5).
CCD_FRACTION = 0.9

_GRADIENT = {
    "pp": dist.point_point_distance_gradient,
    "pe": dist.point_edge_distance_gradient,
    "pt": dist.point_triangle_distance_gradient,
}
_HESSIAN = {
    "pp": dist.point_point_distance_hessian,
    "pe": dist.point_edge_distance_hessian,
    "pt": dist.point_triangle_distance_hessian,
}


class BarrierTerm:
    """Barrier between MPM particles / FEM boundary nodes and FEM boundary facets.

    Args:
        dhat: activation distance in m.
        kappa: barrier stiffness in Pa (the ``"auto"`` choice is made by the stepper, which
            sets ``kappa`` before each step).
    """

    name = "barrier"

    def __init__(self, dhat: float, kappa: float) -> None:
        self.dhat = float(dhat)
        self.kappa = float(kappa)
        self.pairs: ContactPairs | None = None

    # ------------------------------------------------------------------ set-up
    def begin_step(self, ctx: StepContext) -> None:
        """Collision points and facets of this step (particles follow the new stencils)."""
        self.collisions: CollisionSet = build_collision_set(ctx.model, ctx.mpm)
        self._layout = ctx.layout
        self._fixed = ctx.fixed_positions

    def collision_positions(self, x: np.ndarray) -> np.ndarray:
        """Collision-point positions ``(C, d)`` in m for unknowns ``x (n_dof,)``."""
        return self.collisions.positions(self._layout.positions(x, self._fixed))

    def solution_changed(self, x: np.ndarray) -> None:
        """Active pairs and distances at ``x``."""
        self._pos = self.collision_positions(x)
        self.pairs = find_pairs(self.collisions, self._pos, self.dhat)

    # ------------------------------------------------------------------ energy
    def _scaled(self, kind: str) -> np.ndarray:
        pts = self.pairs.points[kind]
        return self.collisions.omega[pts[:, 0]] * self.pairs.coef[kind]

    def value(self, x: np.ndarray) -> float:
        """B(x) in J (J/m in 2D); +inf if a distance is <= 0."""
        total = 0.0
        for kind, d in self.pairs.distance.items():
            if d.size:
                total += float(np.dot(self._scaled(kind), barrier(d, self.dhat, self.kappa)))
        return total

    def _local(self, kind: str) -> tuple[np.ndarray, list[np.ndarray]]:
        pts = self.pairs.points[kind]
        return pts, [self._pos[pts[:, a]] for a in range(pts.shape[1])]

    def gradient(self, x: np.ndarray) -> np.ndarray:
        """dB/dx ``(n_dof,)`` in N."""
        out = np.zeros((self._layout.n_all, self._layout.dim))
        for kind, d in self.pairs.distance.items():
            if not d.size:
                continue
            pts, args = self._local(kind)
            scale = self._scaled(kind) * barrier_derivative(d, self.dhat, self.kappa)
            local = scale[:, None] * _GRADIENT[kind](*args)
            _scatter_gradient(out, local, pts, self.collisions.nodes, self.collisions.weights)
        return self._layout.restrict(out)

    def hessian(self, x: np.ndarray, psd: bool) -> Triplets:
        """Per-pair local Hessians (PSD-projected when ``psd``) chained to node DOFs."""
        parts = []
        cs = self.collisions
        dof_node = self._layout.dof_node
        for kind, d in self.pairs.distance.items():
            if not d.size:
                continue
            pts, args = self._local(kind)
            grad = _GRADIENT[kind](*args)
            scale = self._scaled(kind)
            b1 = barrier_derivative(d, self.dhat, self.kappa)
            b2 = barrier_second_derivative(d, self.dhat, self.kappa)
            local = (scale * b2)[:, None, None] * grad[:, :, None] * grad[:, None, :]
            local += (scale * b1)[:, None, None] * _HESSIAN[kind](*args)
            if psd:
                local = project_psd(local)
            counts = _count_entries(pts, cs.nodes, cs.weights, dof_node)
            starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
            dd = self._layout.dim**2
            total = int(counts.sum()) * dd
            rows = np.empty(total, dtype=np.int64)
            cols = np.empty(total, dtype=np.int64)
            vals = np.empty(total)
            _fill_triplets(local, pts, cs.nodes, cs.weights, dof_node, starts, rows, cols, vals)
            parts.append(Triplets(rows, cols, vals))
        return Triplets.concatenate(parts) if parts else Triplets.empty()

    # ------------------------------------------------------------------ feasibility
    def max_step_size(self, x: np.ndarray, p: np.ndarray) -> float:
        """0.9 x the earliest time of impact along x -> x + p (CCD, section 5); at most 1."""
        cs = self.collisions
        if cs.facets.shape[0] == 0:
            return 1.0
        start = self._pos
        end = self.collision_positions(x + p)
        cand = candidate_pairs(cs, start, 0.0, end)
        if cand.shape[0] == 0:
            return 1.0
        q = cand[:, 0]
        f = cs.facets[cand[:, 1]]
        motion = end - start
        pts = [start[q]] + [start[f[:, a]] for a in range(f.shape[1])]
        mot = [motion[q]] + [motion[f[:, a]] for a in range(f.shape[1])]
        ccd = point_edge_ccd if f.shape[1] == 2 else point_triangle_ccd
        toi = ccd(*pts, *mot, t_max=1.0)
        t = float(toi.min())
        return 1.0 if t >= 1.0 else CCD_FRACTION * t

    # ------------------------------------------------------------------ reporting
    def point_forces(self) -> np.ndarray:
        """Contact forces ``(C, d)`` in N (N/m in 2D) on the collision points at the current
        iterate: -dB/dy per point, before the chain rule to nodes (FEM boundary nodes first,
        then particles, as in ``collisions``)."""
        cs = self.collisions
        out = np.zeros((cs.n_points, self._layout.dim))
        for kind, d in self.pairs.distance.items():
            if not d.size:
                continue
            pts, args = self._local(kind)
            scale = self._scaled(kind) * barrier_derivative(d, self.dhat, self.kappa)
            local = (scale[:, None] * _GRADIENT[kind](*args)).reshape(len(d), pts.shape[1], -1)
            np.add.at(out, pts.reshape(-1), -local.reshape(-1, out.shape[1]))
        return out

    def min_distance(self) -> float:
        """Smallest active pair distance at the current iterate (inf when none is active)."""
        return self.pairs.min_distance() if self.pairs is not None else float("inf")
