"""Collision points and FEM boundary facets of one step, as an affine image of the unknowns.

Collision points (ARCHITECTURE.md): FEM boundary nodes (identity rows) and MPM particles (B-spline
images of the grid nodes, x_q = sum_i w_iq x_i, BFEMP eq. 29). Each point c has a stencil of
all-node indices ``nodes (C, K)`` with weights ``weights (C, K)`` (K = 3^d with particles, 1
otherwise; padding has weight 0), so its position is ``sum_k weights[c, k] Y[nodes[c, k]]`` and
every path x + alpha p stays linear, as CCD needs.

Facets are the FEM boundary edges (2D) or triangles (3D) in collision-point indices. For the
duplicate-removal of BFEMP eqs. 31-32 every boundary vertex v and (3D) boundary edge e carries a
coefficient: the potential of a point q is

    sum_facets b(d) + sum_edges c_e b(d_PE) + sum_vertices c_v b(d_PP),

with c_e = -(eta_e - 1) (eta_e facets per edge) and, in 2D, c_v = -(eta_v - 1), in 3D
c_v = 1 - t_v + sum_{e ni v} (eta_e - 1) (t_v facets per vertex): 1 on closed surfaces, 0 on a
surface border, so that a point nearest to a vertex or an edge counts once.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from bfemp.contact.barrier import boundary_vertex_weights, particle_contact_weight
from bfemp.model import Model

__all__ = ["CollisionSet", "PointStencils", "build_collision_set", "facet_edge_lengths"]


@dataclass(frozen=True)
class PointStencils:
    """Where the particles are, as affine images of the unknowns' nodes.

    Attributes:
        nodes: all-node indices ``(P, K)`` of each particle's stencil (for the barrier step:
            the particle's grid nodes, offset by the FEM node count; for a strategy whose
            unknowns are the particles themselves: one node each, K = 1).
        weights: stencil weights ``(P, K)`` (rows sum to 1).
    """

    nodes: np.ndarray
    weights: np.ndarray

    def __post_init__(self) -> None:
        if self.nodes.shape != self.weights.shape or self.nodes.ndim != 2:
            raise ValueError(
                f"PointStencils: nodes {self.nodes.shape} and weights {self.weights.shape} "
                "must both be (P, K)"
            )


@dataclass(frozen=True)
class CollisionSet:
    """Collision points, facets and duplicate-removal coefficients of one step.

    Attributes:
        nodes: all-node indices of each point's stencil ``(C, K)``.
        weights: stencil weights ``(C, K)`` (rows sum to 1; padding 0).
        point_body: owning body of each point ``(C,)``: FEM bodies 0.., MPM bodies -1 - index.
        is_particle: ``(C,)`` bool.
        omega: integration weight of each point as the point side of a pair ``(C,)``: particles
            2 sqrt(V/pi) (2D) / pi (3V/4pi)^(2/3) (3D) (section 4.2); FEM nodes their lumped
            boundary measure (m in 2D, m^2 in 3D).
        particle_index: particle of each point ``(C,)`` (-1 for FEM nodes).
        n_fem_points: FEM boundary nodes come first: points ``[0, n_fem_points)``.
        facets: boundary facets ``(F, d)`` in point indices; ``facet_body (F,)``.
        edges: (3D) unique boundary edges ``(E, 2)`` with coefficients ``edge_coef (E,)``; empty
            in 2D; ``edge_body (E,)`` their body and ``edge_rest (E, 2, 3)`` their rest end
            points (for the edge-edge mollifier and weights of FEM-FEM contact).
        vertex_coef: coefficient of each FEM boundary point as a point-point term
            ``(n_fem_points,)``.
    """

    nodes: np.ndarray
    weights: np.ndarray
    point_body: np.ndarray
    is_particle: np.ndarray
    omega: np.ndarray
    particle_index: np.ndarray
    n_fem_points: int
    facets: np.ndarray
    facet_body: np.ndarray
    edges: np.ndarray
    edge_coef: np.ndarray
    vertex_coef: np.ndarray
    edge_body: np.ndarray = None
    edge_rest: np.ndarray = None

    @property
    def n_points(self) -> int:
        """Number of collision points C."""
        return int(self.nodes.shape[0])

    def positions(self, node_positions: np.ndarray) -> np.ndarray:
        """Collision-point positions ``(C, d)`` in m from all-node positions ``(n_all, d)``."""
        return _gather(node_positions, self.nodes, self.weights)


@njit(cache=True, parallel=True)
def _gather(y, nodes, weights):  # noqa: ANN001, ANN202
    n, k = nodes.shape
    d = y.shape[1]
    out = np.zeros((n, d))
    for c in prange(n):
        for a in range(k):
            w = weights[c, a]
            if w != 0.0:
                for i in range(d):
                    out[c, i] += w * y[nodes[c, a], i]
    return out


def _facet_topology(facets: np.ndarray, n_vertices: int, dim: int):  # noqa: ANN202
    """Edge and vertex coefficients of BFEMP eqs. 31-32 for boundary facets ``(F, d)``."""
    if dim == 2:
        eta = np.bincount(facets.ravel(), minlength=n_vertices)
        return np.zeros((0, 2), dtype=np.int64), np.zeros(0), -(eta - 1.0) * (eta > 0)
    pairs = np.concatenate([facets[:, [0, 1]], facets[:, [1, 2]], facets[:, [2, 0]]])
    pairs.sort(axis=1)
    edges, eta_e = np.unique(pairs, axis=0, return_counts=True)
    edge_coef = -(eta_e - 1.0)
    t_v = np.bincount(facets.ravel(), minlength=n_vertices)
    excess = np.zeros(n_vertices)
    np.add.at(excess, edges.ravel(), np.repeat(eta_e - 1.0, 2))
    vertex_coef = (1.0 - t_v + excess) * (t_v > 0)
    return edges.astype(np.int64), edge_coef, vertex_coef


def facet_edge_lengths(x: np.ndarray, facets: np.ndarray) -> np.ndarray:
    """Edge lengths in m of boundary ``facets (F, d)`` at node positions ``x (N, d)``: ``(F,)``
    segments in 2D; in 3D ``(3 F,)``, the edges v0 v1 of every triangle, then v1 v2, then v2 v0."""
    if facets.size == 0:
        return np.zeros(0)
    p = x[facets]
    k = facets.shape[1]
    lengths = [
        np.linalg.norm(p[:, (j + 1) % k] - p[:, j], axis=1) for j in range(k if k > 2 else 1)
    ]
    return np.concatenate(lengths)


def build_collision_set(model: Model, particles: PointStencils | None) -> CollisionSet:
    """Collision points and facets: the FEM boundary nodes (identity rows) and, with
    ``particles``, every particle through its stencil (all particles, in particle order)."""
    d = model.dim
    with_particles = particles is not None and model.n_particles > 0
    k = particles.nodes.shape[1] if with_particles else 1
    fem_nodes, fem_body, facets, facet_body, omegas = [], [], [], [], []
    for body in model.fem_bodies:  # a few bodies; vectorised inside
        facet = body.boundary  # global node indices (k, d)
        verts = np.unique(facet)
        local = np.searchsorted(verts, facet)
        pts = model.fem_X[verts]
        omegas.append(boundary_vertex_weights(pts, local))
        offset = sum(v.size for v in fem_nodes)
        facets.append(local + offset)
        facet_body.append(np.full(facet.shape[0], body.index, dtype=np.int64))
        fem_nodes.append(verts)
        fem_body.append(np.full(verts.size, body.index, dtype=np.int64))
    fem_nodes_all = np.concatenate([np.zeros(0, dtype=np.int64), *fem_nodes])
    n_fem_points = fem_nodes_all.size
    facets_all = np.concatenate([np.zeros((0, d), dtype=np.int64), *facets])
    nodes = np.zeros((n_fem_points, k), dtype=np.int64)
    nodes[:, 0] = fem_nodes_all
    weights = np.zeros((n_fem_points, k))
    weights[:, 0] = 1.0
    point_body = np.concatenate([np.zeros(0, dtype=np.int64), *fem_body])
    omega = np.concatenate([np.zeros(0), *omegas])
    particle_index = np.full(n_fem_points, -1, dtype=np.int64)
    is_particle = np.zeros(n_fem_points, dtype=bool)
    if with_particles:
        if particles.nodes.shape[0] != model.n_particles:
            raise ValueError(
                f"PointStencils: {particles.nodes.shape[0]} rows for {model.n_particles} particles"
            )
        nodes = np.concatenate([nodes, particles.nodes.astype(np.int64)])
        weights = np.concatenate([weights, particles.weights])
        point_body = np.concatenate([point_body, -1 - model.mpm_particle_body])
        omega = np.concatenate([omega, particle_contact_weight(model.mpm_volume, d)])
        particle_index = np.concatenate([particle_index, np.arange(model.n_particles)])
        is_particle = np.concatenate([is_particle, np.ones(model.n_particles, dtype=bool)])
    edges, edge_coef, vertex_coef = _facet_topology(facets_all, n_fem_points, d)
    point_body_fem = point_body[:n_fem_points]
    edge_body = point_body_fem[edges[:, 0]] if edges.size else np.zeros(0, dtype=np.int64)
    edge_rest = model.fem_X[fem_nodes_all[edges]] if edges.size else np.zeros((0, 2, d))
    return CollisionSet(
        nodes=np.ascontiguousarray(nodes),
        weights=np.ascontiguousarray(weights),
        point_body=point_body,
        is_particle=is_particle,
        omega=omega,
        particle_index=particle_index,
        n_fem_points=n_fem_points,
        facets=np.ascontiguousarray(facets_all),
        facet_body=np.concatenate([np.zeros(0, dtype=np.int64), *facet_body]),
        edges=edges,
        edge_coef=edge_coef,
        vertex_coef=vertex_coef,
        edge_body=edge_body,
        edge_rest=edge_rest,
    )
