"""The barrier contact potential B(x) of BFEMP eqs. 28-32 as an energy term, with the CCD step
bound.

B(x) = sum over active pairs of omega_q c b(d), with b the clamped log barrier of BFEMP eq. 27, c
the duplicate-removal coefficient (1 for facets) and omega_q the point's integration weight (section
4.2). Derivatives chain from the unsigned distance to the pair's collision points, then to nodes
through the affine collision map (BFEMP eq. 29). Local Hessians are projected to PSD per pair before
the chain rule (in the closest feature's difference coordinates, :mod:`._barrier_kernels`), and the
chain rule sums all pairs' blocks per (node, node) pair (:mod:`._assembly_kernels`).
``max_step_size`` returns 0.9 x the earliest time of impact of any point against any facet along
the linear path x -> x + p (section 5), so no iterate ever crosses a boundary.
"""

from __future__ import annotations

import numpy as np

from bfemp.contact._assembly_kernels import _chain_hessian, _scatter_gradient
from bfemp.contact.collision import CollisionSet, PointStencils, build_collision_set
from bfemp.contact.evaluation import (
    barrier_energy,
    barrier_pair_gradients,
    barrier_pair_hessians,
)
from bfemp.contact.pairs import (
    ContactPairs,
    candidate_pairs,
    edge_edge_active,
    edge_edge_pairs,
    find_pairs,
)
from bfemp.terms.base import StepContext
from geometry.ccd import earliest_impact
from solvers.assembly import Triplets

__all__ = ["BarrierTerm", "CCD_FRACTION"]


#: Fraction of the earliest time of impact used as the line-search start (section 5).
CCD_FRACTION = 0.9


class BarrierTerm:
    """Barrier between MPM particles / FEM boundary nodes and FEM boundary facets.

    Args:
        dhat: activation distance in m.
        kappa: barrier stiffness in Pa (the ``"auto"`` choice is made by the stepper, which
            sets ``kappa`` before each step).
    """

    name = "barrier"
    contact = True  # weighted by the integrator's contact_weight

    def __init__(self, dhat: float, kappa: float) -> None:
        self.dhat = float(dhat)
        self.kappa = float(kappa)
        self.pairs: ContactPairs | None = None

    # ------------------------------------------------------------------ set-up
    def begin_step(self, ctx: StepContext) -> None:
        """Collision points and facets of this step (particles follow the new stencils)."""
        particles = None
        if ctx.mpm is not None:  # particles: B-spline images of the step's grid nodes
            st = ctx.mpm.stencils
            particles = PointStencils(st.nodes + ctx.mpm.node_offset, st.weights)
        self.collisions: CollisionSet = build_collision_set(ctx.model, particles)
        self._layout = ctx.layout
        self._fixed = ctx.fixed_positions
        self._line: dict | None = None  # broad-phase candidates of the current line search

    def collision_positions(self, x: np.ndarray) -> np.ndarray:
        """Collision-point positions ``(C, d)`` in m for unknowns ``x (n_dof,)``."""
        return self.collisions.positions(self._layout.positions(x, self._fixed))

    def solution_changed(self, x: np.ndarray) -> None:
        """Active pairs and distances at ``x`` (a line search's trials share one broad phase)."""
        self._pos = pos = self.collision_positions(x)
        line, cand = self._line, None
        if line is not None and not (pos.shape[1] == 3 and edge_edge_active(self.collisions)):
            line["trials"] += 1
            if line["trials"] == 2:  # first backtrack: later trials lie between start and here
                line.update(lo=np.minimum(line["start"], pos), hi=np.maximum(line["start"], pos))
                line["cand"] = candidate_pairs(self.collisions, line["start"], self.dhat, pos)
            if "cand" in line and (pos >= line["lo"]).all() and (pos <= line["hi"]).all():
                cand = line["cand"]  # the swept boxes (grown by d-hat) hold every pair near pos
        self.pairs = find_pairs(self.collisions, pos, self.dhat, cand)

    # ------------------------------------------------------------------ energy
    def value(self, x: np.ndarray) -> float:
        """B(x) in J (J/m in 2D); +inf if a distance is <= 0."""
        return barrier_energy(self.pairs, self._pos, self.collisions.omega, self.dhat, self.kappa)

    def _pair_gradients(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        return barrier_pair_gradients(
            self.pairs, self._pos, self.collisions.omega, self.dhat, self.kappa
        )

    def gradient(self, x: np.ndarray) -> np.ndarray:
        """dB/dx ``(n_dof,)`` in N."""
        out = np.zeros((self._layout.n_all, self._layout.dim))
        cs = self.collisions
        for pts, local in self._pair_gradients().values():
            _scatter_gradient(out, local, pts, cs.nodes, cs.weights)
        return self._layout.restrict(out)

    def hessian(self, x: np.ndarray, psd: bool) -> Triplets:
        """Per-pair local Hessians (PSD-projected when ``psd``) chained to node DOFs."""
        cs = self.collisions
        dof_node = self._layout.dof_node
        local = barrier_pair_hessians(self.pairs, self._pos, cs.omega, self.dhat, self.kappa, psd)
        parts = [
            Triplets(*_chain_hessian(h, pts, cs.nodes, cs.weights, dof_node))
            for pts, h in local.values()
        ]
        return Triplets.concatenate(parts) if parts else Triplets.empty()

    # ------------------------------------------------------------------ feasibility
    def max_step_size(self, x: np.ndarray, p: np.ndarray) -> float:
        """0.9 x the earliest time of impact along x -> x + p (CCD, section 5); at most 1.
        Opens a line search, whose backtracked trials x + alpha p share one broad phase."""
        self._line = {"start": self._pos, "trials": 0}
        return self._step_fraction(self._pos, self.collision_positions(x + p))

    def scripted_step(
        self,
        x: np.ndarray,
        fixed_from: np.ndarray,
        fixed_to: np.ndarray,
        x_to: np.ndarray | None = None,
    ) -> float:
        """How far scripted nodes may move from ``fixed_from`` toward ``fixed_to`` (all-node
        positions ``(n_all, d)``) while the unknowns move from ``x`` toward ``x_to`` (``(n_dof,)``
        in m; held at ``x`` when None), both linearly: 1 when nothing is in the way, else 0.9 x
        the earliest time of impact (the stepper moves them part-way and re-solves)."""
        cs, layout = self.collisions, self._layout
        start = cs.positions(layout.positions(x, fixed_from))
        end = cs.positions(layout.positions(x if x_to is None else x_to, fixed_to))
        return self._step_fraction(start, end)

    def _step_fraction(self, start: np.ndarray, end: np.ndarray) -> float:
        """1 when collision points moving linearly start -> end meet no facet (or edge), else
        ``CCD_FRACTION`` x the earliest time of impact in [0, 1]."""
        cs = self.collisions
        if cs.facets.shape[0] == 0:
            return 1.0
        cand = candidate_pairs(cs, start, 0.0, end)
        rows = np.column_stack([cand[:, 0], cs.facets[cand[:, 1]]])  # point, facet vertices
        kind = "point_edge" if rows.shape[1] == 3 else "point_triangle"
        ee = None
        if start.shape[1] == 3 and edge_edge_active(cs):
            ee = edge_edge_pairs(cs, start, 0.0, end)[0]
        t = earliest_impact(start, end - start, **{kind: rows}, edge_edge=ee)
        return 1.0 if t >= 1.0 else CCD_FRACTION * t

    # ------------------------------------------------------------------ reporting
    def pair_point_forces(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Per-pair contact forces at the current iterate: kind -> ``(points (n, m), forces
        (n, m, d))``, the force in N (N/m in 2D) on each of the ``m`` collision points of each
        active pair (-d(omega c b)/dy); a pair's forces sum to zero (the barrier depends on
        differences of positions only)."""
        d = self._pos.shape[1]
        return {
            kind: (pts, -local.reshape(len(pts), pts.shape[1], d))
            for kind, (pts, local) in self._pair_gradients().items()
        }

    def point_forces(self) -> np.ndarray:
        """Contact forces ``(C, d)`` in N (N/m in 2D) on the collision points at the current
        iterate: -dB/dy per point, before the chain rule to nodes (FEM boundary nodes first,
        then particles, as in ``collisions``)."""
        cs = self.collisions
        out = np.zeros((cs.n_points, self._layout.dim))
        for pts, forces in self.pair_point_forces().values():
            np.add.at(out, pts.reshape(-1), forces.reshape(-1, out.shape[1]))
        return out

    def min_distance(self) -> float:
        """Smallest active pair distance at the current iterate (inf when none is active)."""
        return self.pairs.min_distance() if self.pairs is not None else float("inf")
