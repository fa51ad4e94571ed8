"""The points of an ``"lr"`` step (``Points``: particles, FEM boundary nodes, facet samples) and
its contact pairs (``Pairs``); ``FemPoints`` sets up the FEM bodies as LR materials.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from bfemp.contact.collision import facet_edge_lengths
from bfemp.errors import warn_user
from bfemp.model import Model
from bfemp.state import State
from geometry.grid import ParticleStencils, particle_stencils

__all__ = ["FemPoints", "Pairs", "Points", "facet_samples"]

log = logging.getLogger(__name__)


@dataclass
class Points:
    """Every point of a step: the P particles, then the FEM boundary nodes, then the facet
    samples. ``stencils`` on the shared active nodes, positions ``x (Q, d)`` m, ``F (Q, d, d)``,
    undeformed radii ``radius0 (Q, d)`` m (0 on FEM points), ``material (Q,)``, ``mass (Q,)`` kg
    (0 on samples)."""

    stencils: ParticleStencils
    x: np.ndarray
    F: np.ndarray
    radius0: np.ndarray
    material: np.ndarray
    mass: np.ndarray


@dataclass
class Pairs:
    """Contact pairs of one step: ``node (K,)`` grid node, ``a (K,)`` material, ``b (K,)`` the
    partner material or -1 (the lumped others), ``ptr (K + 1,)``/``idx``/``side`` the CSR point
    clouds (particle indices; side -1 for a, +1 for the others), ``normal (K, d)`` from a to b,
    ``separation (K,)`` in m (NaN when the detector measures none)."""

    node: np.ndarray
    a: np.ndarray
    b: np.ndarray
    normal: np.ndarray
    separation: np.ndarray
    iterations: np.ndarray
    converged: np.ndarray
    fallback: np.ndarray


class FemPoints:
    """The FEM bodies as LR materials (LR has no FEM; bfemp's design, the ``"lr"`` module
    docstring): their boundary nodes ``nodes (B,)`` with ``node_material (B,)`` and
    ``node_free (B,)`` (not scripted), and facet samples ``samples`` (facet nodes ``(S, d)``,
    barycentric weights ``(S, d)``, materials ``(S,)``), all of radius 0; ``radius0 (P, d)`` m
    and ``material (P,)`` are the particles'."""

    def __init__(self, model: Model, radius0: np.ndarray, material: np.ndarray) -> None:
        self.model, self.radius0, self.material = model, radius0, material
        # boundary nodes and facet samples of the FEM bodies (section 2.6 of the spec)
        d = model.dim
        n_mpm = len(model.mpm_bodies)
        nodes, node_mat, facets, facet_mat = [], [], [], []
        for body in model.fem_bodies:
            f = np.asarray(body.boundary, dtype=np.int64).reshape(-1, d)
            if f.size == 0:
                continue
            facets.append(f)
            facet_mat.append(np.full(f.shape[0], n_mpm + body.index, dtype=np.int64))
            b = np.unique(f)
            nodes.append(b)
            node_mat.append(np.full(b.size, n_mpm + body.index, dtype=np.int64))
        cat = np.concatenate
        self.nodes = cat(nodes) if nodes else np.zeros(0, np.int64)
        self.node_material = cat(node_mat) if node_mat else np.zeros(0, np.int64)
        self.node_free = ~model.fem_prescribed[self.nodes].astype(bool)
        facets_all = cat(facets) if facets else np.zeros((0, d), np.int64)
        facet_material = cat(facet_mat) if facet_mat else np.zeros(0, np.int64)
        dx = model.grid.dx
        if facets_all.shape[0]:
            # the longest edge of each facet
            edge = facet_edge_lengths(model.fem_X, facets_all).reshape(-1, len(facets_all)).max(0)
            if dx < 2.0 * edge.max() * (1.0 - 1e-9):
                warn_user(
                    f"LR_GRID_FINE: the MPM grid (dx = {dx:.4g} m) is finer than twice the FEM "
                    f"boundary edge (up to {edge.max():.4g} m): the FEM material's grid mass "
                    "has gaps between its nodes (spec section 2.6 asks for dx >= 2 x the edge)",
                    logger=log,
                )
            # facet samples at spacing <= dx / 2 (barycentric, the vertices left out)
            per_edge = np.maximum(1, np.ceil(edge / (0.5 * dx)).astype(np.int64))
            self.samples = facet_samples(facets_all, facet_material, per_edge, d)
        else:
            self.samples = (np.zeros((0, d), np.int64), np.zeros((0, d)), np.zeros(0, np.int64))
        self.n_nodes = self.nodes.size
        self.n_samples = self.samples[0].shape[0]

    def points(self, state: State) -> Points:
        """Every point of the step (``Points``), with stencils at their positions."""
        model, d = self.model, self.model.dim
        if self.n_nodes == 0:
            st = particle_stencils(model.grid, state.mpm_x)
            return Points(st, state.mpm_x, state.mpm_F, self.radius0, self.material, model.mpm_mass)
        s_nodes, s_bary, s_mat = self.samples
        sample_x = np.einsum("sk,skd->sd", s_bary, state.fem_x[s_nodes])
        n_extra = self.n_nodes + self.n_samples
        x = np.concatenate([state.mpm_x, state.fem_x[self.nodes], sample_x])
        eye = np.broadcast_to(np.eye(d), (n_extra, d, d))
        F = np.concatenate([state.mpm_F, eye])
        R0 = np.concatenate([self.radius0, np.zeros((n_extra, d))])
        mat = np.concatenate([self.material, self.node_material, s_mat])
        mass = np.concatenate(
            [model.mpm_mass, model.fem_mass[self.nodes], np.zeros(self.n_samples)]
        )
        st = particle_stencils(model.grid, x)
        return Points(st, x, F, R0, mat, mass)

    def scripted_force(self, state: State, fem_force: np.ndarray, dt: float) -> np.ndarray:
        """The forces ``(B, d)`` in N the FEM boundary nodes bring to P2G: the mechanical force
        on free nodes; on scripted nodes m_n (v_n^script(t^{n+1}) - v_n^n) / dt, so that their
        field reaches the script's velocity at t^{n+1} (their mechanical force, gravity
        included, never moves them: a fixed plate's field would otherwise fall at g)."""
        b = self.nodes
        force = fem_force[b]
        scripted = ~self.node_free
        if not scripted.any():
            return force
        nodes = b[scripted]
        v_next = self.model.prescribed_velocities(state.t + dt)[nodes]
        force = force.copy()
        force[scripted] = self.model.fem_mass[nodes, None] * (v_next - state.fem_v[nodes]) / dt
        return force

    def kinematic_fields(self, st: ParticleStencils, mass: np.ndarray) -> np.ndarray | None:
        """``(M, G)`` bool: the fields whose whole grid mass at the node comes from scripted FEM
        nodes (None when no FEM node is scripted).

        A scripted field is infinitely heavy in the contact law (NairnMPM's rigid materials; LR
        has none), which stops the approach at once: with its finite grid mass the law (LR eqs.
        7-10) gave part of the approach to a plate whose script undid it, and a disk went through
        (issue 40, ``tests/bfemp/test_lr_drop.py``; design note ``measurements``, lr). A field
        mixing free and scripted nodes is left finite (its free nodes take the kick)."""
        if not self.n_nodes or self.node_free.all():
            return None
        n_p = self.model.n_particles
        scripted = ~self.node_free
        rows = np.arange(n_p, n_p + self.n_nodes)[scripted]
        nodes = st.nodes[rows]
        w = st.weights[rows] * self.model.fem_mass[self.nodes[scripted], None]
        mat = np.broadcast_to(self.node_material[scripted, None], nodes.shape)
        held = np.zeros_like(mass)
        np.add.at(held, (mat, nodes), w)
        return (mass > 0.0) & (held >= (1.0 - 1e-9) * mass)


def facet_samples(
    facets: np.ndarray, material: np.ndarray, per_edge: np.ndarray, d: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sample points on the facets at spacing facet edge / ``per_edge`` (vertices excluded, the
    nodes are points already): ``(facet nodes (S, d), barycentric weights (S, d), material (S,))``.

    2D: the n - 1 interior points of a segment cut into n; 3D: the barycentric lattice of order n
    of a triangle without its three vertices (points on shared edges appear once per facet).
    """
    out_nodes, out_bary, out_mat = [], [], []
    for n in np.unique(per_edge):  # a few distinct orders, vectorised over facets
        sel = np.flatnonzero(per_edge == n)
        if d == 2:
            t = np.arange(1, n) / n
            bary = np.stack([1.0 - t, t], axis=1)
        else:
            i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
            keep = (i + j <= n).ravel()
            i, j = i.ravel()[keep], j.ravel()[keep]
            k = n - i - j
            corner = (i == n) | (j == n) | (k == n)
            bary = np.stack([i, j, k], axis=1)[~corner] / n
        if bary.shape[0] == 0:
            continue
        out_nodes.append(np.repeat(facets[sel], bary.shape[0], axis=0))
        out_bary.append(np.tile(bary, (sel.size, 1)))
        out_mat.append(np.repeat(material[sel], bary.shape[0]))
    if not out_nodes:
        return np.zeros((0, d), np.int64), np.zeros((0, d)), np.zeros(0, np.int64)
    return np.concatenate(out_nodes), np.concatenate(out_bary), np.concatenate(out_mat)
