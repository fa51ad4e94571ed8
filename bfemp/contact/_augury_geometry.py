"""Geometry of augury's foreground (AUG; the ``"augury"`` stepper's helpers): boundary normals of
FEM nodes and MPM particles, the gradient of a particle correction, cell faces and depths.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from bfemp.contact._end_state import cells_containing
from bfemp.contact.augury import ContactStencils, facet_normals
from bfemp.model import Model
from geometry.grid import particle_stencils

__all__ = [
    "cell_faces",
    "correction_gradient",
    "depth_in_cell",
    "face_key",
    "facing_normals",
    "fem_normals",
    "inside_other_cells",
    "mpm_normals",
    "normalize",
    "reach_notes",
    "subset",
]


def fem_normals(x: np.ndarray, facets: np.ndarray, opposite: np.ndarray) -> np.ndarray:
    """Outward unit normals ``(N, d)`` of the FEM boundary nodes at positions ``x (N, d)`` m
    (area-weighted normals of the boundary ``facets (F, d)``, ``opposite (F,)`` the vertex of
    each facet's cell off it; AUG section 2.3; zero off the boundary)."""
    n_f = facet_normals(x, facets, opposite)
    n = x.shape[0]
    flat = facets.reshape(-1)  # d corners per facet
    normals = np.stack(
        [np.bincount(flat, np.repeat(n_f[:, a], facets.shape[1]), n) for a in range(x.shape[1])],
        axis=1,
    )
    return normalize(normals)


def facing_normals(
    x: np.ndarray,
    st: ContactStencils,
    m: np.ndarray,
    body: np.ndarray,
    normals: np.ndarray,
    fg: np.ndarray,
    facets: np.ndarray,
    opposite: np.ndarray,
) -> np.ndarray:
    """``"facing"`` normals of the FEM foreground nodes ``fg (n_fem,)`` as ``(n_fem, d)``
    (``AuguryOptions.normals``; x the FEM positions, the foreground's stencils, masses, bodies
    and own normals first in ``st``, ``m``, ``body``, ``normals``).

    n-bar_other(p) = sum_i N_ip sum_{q not in body(p)} N_iq m_q n_q (a P2G of m n per body);
    where it is non-zero the node takes, of its facets' unit normals, the one with the
    smallest n_f . n-bar_other; elsewhere its own averaged normal.
    """
    n_fem = fg.size
    weights = st.weights
    total = np.zeros((st.n_nodes, x.shape[1]))
    per_body = {}
    for b in np.unique(body):
        sel = body == b
        field = np.zeros_like(total)
        flat = st.nodes[sel].reshape(-1)
        contrib = (weights[sel] * m[sel, None])[:, :, None] * normals[sel][:, None, :]
        for a in range(x.shape[1]):
            field[:, a] = np.bincount(flat, contrib[..., a].reshape(-1), st.n_nodes)
        per_body[b] = field
        total += field
    other = np.zeros((n_fem, x.shape[1]))
    for b, field in per_body.items():
        sel = np.flatnonzero(body[:n_fem] == b)
        if sel.size:
            rest = total - field
            other[sel] = np.einsum("pk,pkd->pd", weights[sel], rest[st.nodes[sel]])
    n_f = normalize(facet_normals(x, facets, opposite))
    fg_pos = np.full(x.shape[0], -1)
    fg_pos[fg] = np.arange(n_fem)
    best = np.full(n_fem, np.inf)
    choice = normals[:n_fem].copy()
    for j in range(facets.shape[1]):
        p = fg_pos[facets[:, j]]
        ok = p >= 0
        score = np.einsum("kd,kd->k", n_f[ok], other[p[ok]])
        order = np.argsort(score)[::-1]  # the last write per node is its smallest score
        pk, sk, nk = p[ok][order], score[order], n_f[ok][order]
        better = sk < best[pk]
        # several facets per node: resolve with a stable minimum per node
        uniq, first = np.unique(pk[::-1], return_index=True)
        idx = len(pk) - 1 - first
        win = better[idx]
        best[uniq[win]] = sk[idx][win]
        choice[uniq[win]] = nk[idx][win]
    has_other = np.einsum("pd,pd->p", other, other) > 0.0
    return np.where(has_other[:, None], choice, normals[:n_fem])


def mpm_normals(
    stencils: ContactStencils, first: int, mass: np.ndarray, body: np.ndarray
) -> np.ndarray:
    """Outward unit normals ``(P, d)`` of the MPM foreground: n_p = normalize(sum_i N_ip
    g_i), g_i = sum_{q in body} m_q grad N_iq (bfemp's MPM foreground).

    grad N_iq is the gradient of node i's kernel at x_q (``contact_stencils``), which points
    from x_q toward node i, so g_i points away from the body's mass: outward. Section 1.4
    writes -sum N_ip g_i, the sign for the gradient taken at the node; with this
    convention it gave inward normals (issue 40: on a disk every rim particle had
    cos(n_p, radial) = -1), which turned compressive corrections into "tensile" ones that
    the augury iteration removes, and an MPM body sank through a fixed plate.
    """
    rows = np.arange(first, first + mass.size)
    nodes = stencils.nodes[rows]
    grads = stencils.grads[rows]
    w = stencils.weights[rows]
    d = stencils.grads.shape[2]
    out = np.zeros((mass.size, d))
    for b in np.unique(body):
        sel = np.flatnonzero(body == b)
        g = np.zeros((stencils.n_nodes, d))
        np.add.at(g, nodes[sel].reshape(-1), (mass[sel, None, None] * grads[sel]).reshape(-1, d))
        out[sel] = np.einsum("pk,pkd->pd", w[sel], g[nodes[sel]])  # outward (docstring)
    return normalize(out)


def correction_gradient(model: Model, x: np.ndarray, dv: np.ndarray) -> np.ndarray:
    """Gradient ``(P, d, d)`` in 1/s of the MPM velocity correction ``dv (P, d)`` (m/s) on the
    engine's MPM grid at x^n ``(P, d)``: per MPM body, the mass-weighted nodal field
    dv_i = sum_p w_ip m_p dv_p / sum_p w_ip m_p, then sum_i dv_i grad w_ip^T (the G2P
    velocity gradient the engine's F update uses)."""
    st = particle_stencils(model.grid, x)
    d = model.dim
    m = model.mpm_mass
    out = np.zeros((x.shape[0], d, d))
    body = model.mpm_particle_body
    for b in np.unique(body):
        sel = np.flatnonzero(body == b)
        nodes = st.nodes[sel]
        wm = st.weights[sel] * m[sel, None]
        flat = nodes.reshape(-1)
        mass = np.bincount(flat, wm.reshape(-1), st.n_nodes)
        field = np.zeros((st.n_nodes, d))
        for a in range(d):
            field[:, a] = np.bincount(flat, (wm * dv[sel, a, None]).reshape(-1), st.n_nodes)
        np.divide(field, mass[:, None], out=field, where=mass[:, None] > 0.0)
        out[sel] = np.einsum("pka,pkc->pac", field[nodes], st.grads[sel])
    return out


def normalize(v: np.ndarray) -> np.ndarray:
    norm = np.sqrt(np.einsum("pd,pd->p", v, v))
    out = np.zeros_like(v)
    np.divide(v, norm[:, None], out=out, where=norm[:, None] > 0.0)
    return out


def depth_in_cell(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Distance in m of each point ``(Q, d)`` inside its simplex ``(Q, d + 1, d)`` to the
    simplex's nearest face: min_j lambda_j / |grad lambda_j| (barycentric lambda)."""
    inv = np.linalg.inv(np.swapaxes(cells[:, 1:] - cells[:, :1], 1, 2))  # rows: grad lambda_1..d
    lam = np.einsum("qab,qb->qa", inv, points - cells[:, 0])
    grads = np.concatenate([-inv.sum(axis=1, keepdims=True), inv], axis=1)  # (Q, d + 1, d)
    lam = np.concatenate([1.0 - lam.sum(axis=1, keepdims=True), lam], axis=1)
    return (lam / np.linalg.norm(grads, axis=2)).min(axis=1)


def face_key(faces_sorted: np.ndarray, n: int) -> np.ndarray:
    """One int64 per sorted facet (n^d < 2^63: n < 2e6 nodes in 3D)."""
    key = np.zeros(faces_sorted.shape[0], dtype=np.int64)
    for j in range(faces_sorted.shape[1]):
        key = key * np.int64(n) + faces_sorted[:, j]
    return key


def cell_faces(cells: np.ndarray, n: int, d: int) -> tuple[np.ndarray, np.ndarray]:
    """Sorted keys of every cell face and the vertex opposite each (``(M (d+1),)`` each)."""
    cells = np.asarray(cells, dtype=np.int64)
    keys, opp = [], []
    for j in range(d + 1):
        face = np.delete(cells, j, axis=1)
        keys.append(face_key(np.sort(face, axis=1), n))
        opp.append(cells[:, j])
    keys = np.concatenate(keys) if keys else np.zeros(0, np.int64)
    opp = np.concatenate(opp) if opp else np.zeros(0, np.int64)
    order = np.argsort(keys, kind="stable")
    return keys[order], opp[order]


def subset(st: ContactStencils, sel: np.ndarray) -> ContactStencils:
    """The stencils of the particles ``sel`` (node indices unchanged)."""
    nodes, weights = np.ascontiguousarray(st.nodes[sel]), np.ascontiguousarray(st.weights[sel])
    return replace(st, nodes=nodes, weights=weights, grads=st.grads[sel], D=st.D[sel])


def inside_other_cells(
    points: np.ndarray,
    owner: np.ndarray,
    vertices: np.ndarray,
    cells: np.ndarray,
    cell_body: np.ndarray,
) -> tuple[int, float, float]:
    """How many ``points (Q, d)`` m of bodies ``owner (Q,)`` lie strictly inside a simplex
    ``cells (C, d + 1)`` (vertex indices into ``vertices (V, d)`` m) of another body
    (``cell_body (C,)``), the deepest barycentric depth and the deepest distance in m to that
    cell's nearest face (AUG pitfall A9). Strictly: every barycentric coordinate above 1e-9
    (bfemp's choice; the paper gives none)."""
    found, depth = cells_containing(
        np.ascontiguousarray(points), np.ascontiguousarray(owner), vertices, cells, cell_body, 1e-9
    )
    inside = found >= 0
    if not inside.any():
        return 0, 0.0, 0.0
    depth_m = float(depth_in_cell(points[inside], vertices[cells[found[inside]]]).max())
    return int(inside.sum()), float(depth.max()), depth_m


def reach_notes(
    dt: float,
    tau: float,
    dx: float,
    node_shared: np.ndarray,
    v_lo: np.ndarray,
    v_hi: np.ndarray,
    v_bar: np.ndarray,
) -> list[str]:
    """AUGURY_REACH / AUGURY_STEP_REACH for steps dt and tau in s on a contact grid of spacing
    dx m: v_rel is the spread ``v_hi - v_lo (G, d)`` m/s of the predicted velocities ``v_bar
    (n, d)`` at the contact nodes ``node_shared (G,)`` two bodies share (an upper bound)."""
    notes = []
    v_max = float(np.sqrt(np.einsum("pd,pd->p", v_bar, v_bar)).max()) if v_bar.size else 0.0
    if dt * v_max > 0.5 * dx:
        notes.append(
            f"AUGURY_STEP_REACH: dt max|v| = {dt * v_max:.4g} m exceeds grid_dx / 2 = "
            f"{0.5 * dx:.4g} m"
        )
    if node_shared.any():
        spread = v_hi[node_shared] - v_lo[node_shared]
        v_rel = float(np.sqrt((spread**2).sum(axis=1)).max())
        if tau * v_rel > dx / 3.0:
            notes.append(
                f"AUGURY_REACH: tau |v_rel| = {tau * v_rel:.4g} m exceeds grid_dx / 3 = "
                f"{dx / 3.0:.4g} m (AUG eq. 50: bodies may stop short or overshoot)"
            )
    return notes
