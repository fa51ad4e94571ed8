"""Active contact pairs of a configuration: every term of BFEMP eqs. 31-32 with d < d-hat.

Point side: every particle and (for FEM-FEM contact) every FEM boundary node; facet side: FEM
boundary facets of another body. Never particle-particle, never a body against itself. The broad
phase (spatial hash, boxes inflated by d-hat) proposes (point, facet) candidates; the point-point
(vertex) and 3D point-edge terms of the duplicate removal are derived from the facets of the
candidates within d-hat (a facet's vertex or edge is never closer than the facet).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bfemp.contact._barrier_kernels import _pair_distances
from bfemp.contact.collision import CollisionSet
from geometry._distance_kernels import KIND_EE, KIND_PE, KIND_PP, KIND_PT
from geometry.broadphase import edge_edge_candidates, point_simplex_candidates, unique_keys

__all__ = ["ContactPairs", "PAIR_KINDS", "candidate_pairs", "edge_edge_active", "find_pairs"]

#: kind -> number of collision points: point-point, point-edge, point-triangle, edge-edge.
PAIR_KINDS = {"pp": 2, "pe": 3, "pt": 4, "ee": 4}
_KIND = {"pp": KIND_PP, "pe": KIND_PE, "pt": KIND_PT, "ee": KIND_EE}


@dataclass(frozen=True)
class ContactPairs:
    """Active pairs grouped by kind.

    Attributes:
        points: kind -> collision-point indices ``(n_kind, m)`` (point first, then the primitive).
        coef: kind -> duplicate-removal coefficient ``(n_kind,)`` (1 for facets).
        distance: kind -> unsigned distance ``(n_kind,)`` in m.
    """

    points: dict[str, np.ndarray]
    coef: dict[str, np.ndarray]
    distance: dict[str, np.ndarray]
    eps_x: np.ndarray | None = None  # edge-edge mollifier thresholds (n_ee,)

    @property
    def n_pairs(self) -> int:
        """Number of active pairs of every kind."""
        return sum(v.shape[0] for v in self.points.values())

    def min_distance(self) -> float:
        """Smallest active distance (inf when there is none)."""
        values = [v.min() for v in self.distance.values() if v.size]
        return float(min(values)) if values else float("inf")


def _distance(kind: str, pos: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Unsigned distances ``(n,)`` of the pairs ``pts (n, m)`` of a kind at ``pos (C, d)``."""
    if pts.shape[0] == 0:
        return np.zeros(0)
    return _pair_distances(pos, np.ascontiguousarray(pts), _KIND[kind])


def candidate_pairs(
    cs: CollisionSet,
    pos: np.ndarray,
    inflation: float,
    pos_end: np.ndarray | None = None,
) -> np.ndarray:
    """(point, facet) candidates ``(n, 2)`` of different bodies whose boxes (swept to
    ``pos_end``) overlap, sorted."""
    nf = cs.n_fem_points
    return point_simplex_candidates(
        pos,
        pos[:nf],
        cs.facets,
        inflation=inflation,
        points_end=pos_end,
        vertices_end=None if pos_end is None else pos_end[:nf],
        groups=(cs.point_body, cs.facet_body),
    )


def find_pairs(
    cs: CollisionSet, pos: np.ndarray, dhat: float, candidates: np.ndarray | None = None
) -> ContactPairs:
    """All terms of BFEMP eqs. 31-32 with distance below ``dhat`` at positions ``pos (C, d)``;
    ``candidates``: (point, facet) rows holding every facet pair within ``dhat`` of ``pos``, sorted
    (the broad phase's, found here when None)."""
    dim = pos.shape[1]
    bad = ~np.isfinite(pos).all(axis=1)
    if bad.any():
        raise ValueError(f"collision positions are not finite in rows {np.flatnonzero(bad)[:10]}")
    cand = candidate_pairs(cs, pos, dhat) if candidates is None else candidates
    facet_kind = "pe" if dim == 2 else "pt"
    out_pts, out_coef, out_dist = {}, {}, {}

    def add(kind: str, pts: np.ndarray, coef: np.ndarray) -> np.ndarray:
        """Keep the pairs ``pts`` of ``kind`` within ``dhat``; their distances ``(n,)``."""
        d = _distance(kind, pos, pts)
        active = d < dhat
        out_pts[kind] = np.ascontiguousarray(pts[active])
        out_coef[kind] = np.ascontiguousarray(coef[active])
        out_dist[kind] = np.ascontiguousarray(d[active])
        return d

    q = cand[:, 0]
    facets = cs.facets[cand[:, 1]]
    d = add(facet_kind, np.column_stack([q, facets]), np.ones(q.size))
    # Vertex and edge terms only of facets within dhat (a vertex or an edge of a facet is no
    # closer than the facet itself; the margin covers the round-off of the two formulas).
    near = d < dhat * (1.0 + 1e-9)
    q, facets = q[near], facets[near]
    nf = cs.n_fem_points
    # vertex (point-point) terms of those facets, once per (point, vertex): int64 keys q nf + v
    keys = unique_keys(np.repeat(q, dim) * nf + facets.ravel())
    vertex = keys % max(nf, 1)
    vcoef = cs.vertex_coef[vertex]
    nz = vcoef != 0.0
    add("pp", np.column_stack([keys[nz] // max(nf, 1), vertex[nz]]), vcoef[nz])
    if dim == 3:
        # edge (point-edge) terms of those triangles, once per (point, edge): keys q E + edge
        tri_edges = np.sort(
            np.concatenate([facets[:, [0, 1]], facets[:, [1, 2]], facets[:, [2, 0]]]), axis=1
        )
        n_edges = max(cs.edges.shape[0], 1)
        edge_key = cs.edges[:, 0] * (nf + 1) + cs.edges[:, 1]  # sorted (unique edges)
        edge = np.searchsorted(edge_key, tri_edges[:, 0] * (nf + 1) + tri_edges[:, 1])
        keys = unique_keys(np.tile(q, 3) * n_edges + edge)
        edge = keys % n_edges
        ecoef = cs.edge_coef[edge]
        nz = ecoef != 0.0
        add("pe", np.column_stack([keys[nz] // n_edges, cs.edges[edge[nz]]]), ecoef[nz])
    eps_x = None
    if dim == 3 and edge_edge_active(cs):
        ee, w = edge_edge_pairs(cs, pos, dhat)
        add("ee", ee, w)
        eps_x = _edge_eps(cs, out_pts["ee"])
    return ContactPairs(out_pts, out_coef, out_dist, eps_x)


def edge_edge_active(cs: CollisionSet) -> bool:
    """Whether edge-edge terms can occur: 3D boundary edges of more than one FEM body."""
    body = cs.edge_body
    return bool(cs.edges.shape[0] and body is not None and np.any(body != body[0]))


def edge_edge_pairs(
    cs: CollisionSet, pos: np.ndarray, inflation: float, pos_end: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """3D FEM-FEM edge-edge candidates ``(n, 4)`` (point indices ea0 ea1 eb0 eb1) of different
    bodies, and their weights (m^2): a quarter of the product of the rest edge lengths, the
    boundary measure an edge pair stands for (the edge-edge analogue of a node's weight)."""
    nf = cs.n_fem_points
    cand = edge_edge_candidates(
        pos[:nf],
        cs.edges,
        cs.edges,
        inflation=inflation,
        vertices_end=None if pos_end is None else pos_end[:nf],
    )
    cand = cand[(cand[:, 0] < cand[:, 1]) & (cs.edge_body[cand[:, 0]] != cs.edge_body[cand[:, 1]])]
    ee = np.column_stack([cs.edges[cand[:, 0]], cs.edges[cand[:, 1]]])
    length = np.linalg.norm(cs.edge_rest[:, 1] - cs.edge_rest[:, 0], axis=1)
    return ee, 0.25 * length[cand[:, 0]] * length[cand[:, 1]]


def _edge_eps(cs: CollisionSet, ee: np.ndarray) -> np.ndarray:
    """IPC's mollifier threshold eps_x = 1e-3 |a0|^2 |b0|^2 from rest positions."""
    rest = np.zeros((cs.n_fem_points, 3))
    # rest position of every FEM boundary point, from the edges that reference it
    rest[cs.edges.reshape(-1)] = cs.edge_rest.reshape(-1, 3)
    a = rest[ee[:, 1]] - rest[ee[:, 0]]
    b = rest[ee[:, 3]] - rest[ee[:, 2]]
    return 1e-3 * np.einsum("ij,ij->i", a, a) * np.einsum("ij,ij->i", b, b)
