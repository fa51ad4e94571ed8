"""Active contact pairs of a configuration: every term of eqs. 31-32 with d < d-hat.

Point side: every particle and (for FEM-FEM contact) every FEM boundary node; facet side: FEM
boundary facets of another body. Never particle-particle, never a body against itself. The broad
phase (spatial hash, boxes inflated by d-hat) proposes (point, facet) candidates; the point-point
(vertex) and 3D point-edge terms of the duplicate removal are derived from the candidates' facets.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bfemp.contact.collision import CollisionSet
from geometry import distance as dist
from geometry.broadphase import edge_edge_candidates, point_simplex_candidates

__all__ = ["ContactPairs", "PAIR_KINDS", "find_pairs", "candidate_pairs"]

#: kind -> number of collision points: point-point, point-edge, point-triangle, edge-edge.
PAIR_KINDS = {"pp": 2, "pe": 3, "pt": 4, "ee": 4}


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
    args = [pos[pts[:, a]] for a in range(pts.shape[1])]
    if kind == "pp":
        return dist.point_point_distance(*args)
    if kind == "pe":
        return dist.point_edge_distance(*args)
    if kind == "ee":
        return dist.edge_edge_distance(*args)
    return dist.point_triangle_distance(*args)


def candidate_pairs(
    cs: CollisionSet,
    pos: np.ndarray,
    inflation: float,
    pos_end: np.ndarray | None = None,
) -> np.ndarray:
    """(point, facet) candidates ``(n, 2)`` whose boxes (swept to ``pos_end``) overlap."""
    if cs.facets.shape[0] == 0 or cs.n_points == 0:
        return np.zeros((0, 2), dtype=np.int64)
    nf = cs.n_fem_points
    cand = point_simplex_candidates(
        pos,
        pos[:nf],
        cs.facets,
        inflation=inflation,
        points_end=pos_end,
        vertices_end=None if pos_end is None else pos_end[:nf],
    )
    keep = cs.point_body[cand[:, 0]] != cs.facet_body[cand[:, 1]]
    return cand[keep]


def find_pairs(cs: CollisionSet, pos: np.ndarray, dhat: float) -> ContactPairs:
    """All terms of eqs. 31-32 with distance below ``dhat`` at positions ``pos (C, d)``."""
    dim = pos.shape[1]
    cand = candidate_pairs(cs, pos, dhat)
    facet_kind = "pe" if dim == 2 else "pt"
    out_pts, out_coef, out_dist = {}, {}, {}

    def add(kind: str, pts: np.ndarray, coef: np.ndarray) -> None:
        if pts.shape[0] == 0:
            d = np.zeros(0)
        else:
            d = _distance(kind, pos, pts)
        active = d < dhat
        out_pts[kind] = np.ascontiguousarray(pts[active])
        out_coef[kind] = np.ascontiguousarray(coef[active])
        out_dist[kind] = np.ascontiguousarray(d[active])

    q = cand[:, 0]
    facets = cs.facets[cand[:, 1]]
    add(facet_kind, np.column_stack([q, facets]), np.ones(cand.shape[0]))
    # vertex (point-point) terms of the candidates' facets, once per (point, vertex)
    pv = np.unique(np.column_stack([np.repeat(q, dim), facets.ravel()]), axis=0)
    vcoef = cs.vertex_coef[pv[:, 1]] if pv.size else np.zeros(0)
    nz = vcoef != 0.0
    add("pp", pv[nz], vcoef[nz])
    if dim == 3:
        # edge (point-edge) terms of the candidates' triangles, once per (point, edge)
        tri_edges = np.sort(
            np.concatenate([facets[:, [0, 1]], facets[:, [1, 2]], facets[:, [2, 0]]]), axis=1
        )
        pe = np.unique(np.column_stack([np.tile(q, 3), tri_edges]), axis=0)
        if pe.size:
            # coefficient of each edge: look up in the sorted unique edge list
            key = cs.edges[:, 0] * (cs.n_fem_points + 1) + cs.edges[:, 1]
            where = np.searchsorted(key, pe[:, 1] * (cs.n_fem_points + 1) + pe[:, 2])
            ecoef = cs.edge_coef[where]
        else:
            ecoef = np.zeros(0)
        nz = ecoef != 0.0
        add("pe", pe[nz], ecoef[nz])
    eps_x = None
    if dim == 3 and cs.edges.shape[0] and np.unique(cs.edge_body).size > 1:
        ee, w = edge_edge_pairs(cs, pos, dhat)
        add("ee", ee, w)
        eps_x = _edge_eps(cs, out_pts["ee"])
    return ContactPairs(out_pts, out_coef, out_dist, eps_x)


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
