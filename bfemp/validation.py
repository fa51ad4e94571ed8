"""Checks of the initial configuration that involve several bodies (contact scenes).

The barrier of BFEMP is finite only while every particle and FEM boundary node is at a positive
distance from the other bodies' boundaries, so a contact scene must start without overlap:

- no MPM particle inside (or on the boundary of) a FEM body's mesh;
- no two FEM bodies overlapping: no node of one inside the other's mesh, and no boundary edge of
  one crossing a boundary edge (2D) or boundary triangle (3D) of the other;
- no particle closer than ``dhat`` to a FEM boundary, where it would start with an active
  barrier force (the scene author almost always meant the bodies to start apart);
- likewise no FEM boundary node closer than ``dhat`` to the boundary of another FEM body
  (node-facet distances, the pairs of the FEM-FEM barrier; 3D edge-edge distances are not
  checked). Pairs of two fully prescribed bodies are exempt: their barrier acts on no unknown.

Each failure raises :class:`~bfemp.errors.SceneError` naming the bodies, the offending indices,
the distance found and a suggested fix. Inside tests use the barycentric point location of
:func:`geometry.sampling.locate_points` (points on a facet count as inside); crossings use the
candidates of :mod:`geometry.broadphase` and exact orientation predicates evaluated in floating
point; distances use :mod:`geometry.distance`.
"""

from __future__ import annotations

import logging

import numpy as np

from bfemp.errors import SceneError
from bfemp.model import Model
from geometry._meshing_report import format_indices
from geometry.broadphase import box_overlap_pairs, point_simplex_candidates
from geometry.distance import point_edge_distance, point_triangle_distance
from geometry.mesh import TetMesh, TriMesh
from geometry.sampling import locate_points

__all__ = ["check_clearance", "check_fem_clearance", "check_no_overlap", "validate_initial"]

log = logging.getLogger(__name__)


def _clearance_error(
    what: str, items: np.ndarray, d_min: float, dhat: float, body: str, field: str, other: str
) -> SceneError:
    """The error for the ``items`` (``what``: "particle" or "node"; indices within ``body``,
    from its ``field``) that start within ``dhat`` (m) of fem body ``other``, the closest at
    ``d_min`` (m)."""
    return SceneError(
        f"{items.size} {what}(s) start within dhat = {dhat:g} m of fem body '{other}' (closest "
        f"{d_min:.3g} m; {what}s {format_indices(items)})",
        body=body,
        field=field,
        hint=f"move the bodies at least {dhat - d_min:.3g} m further apart, or use a "
        f"dhat below {d_min:.3g} m",
    )


def _positions(model: Model, fem_x: np.ndarray | None, mpm_x: np.ndarray | None) -> tuple:
    fem_x = model.fem_X if fem_x is None else np.asarray(fem_x, dtype=np.float64)
    mpm_x = model.mpm_X if mpm_x is None else np.asarray(mpm_x, dtype=np.float64)
    for name, x, ref in (("fem_x", fem_x, model.fem_X), ("mpm_x", mpm_x, model.mpm_X)):
        if x.shape != ref.shape:
            raise ValueError(f"{name} must have shape {ref.shape}, got {x.shape}")
    return fem_x, mpm_x


def _boundary_edges(model: Model, body: object) -> np.ndarray:
    """Global node indices ``(e, 2)`` of the boundary edges of a FEM body."""
    faces = body.boundary
    if model.dim == 2:
        return faces
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    return np.unique(np.sort(edges, axis=1), axis=0)


def _orient2d(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Twice the signed area of the triangles (a, b, c), rows ``(n, 2)``."""
    u, v = b - a, c - a
    return u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]


def _orient3d(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Six times the signed volume of the tetrahedra (a, b, c, d), rows ``(n, 3)``."""
    return np.einsum("ij,ij->i", np.cross(b - a, c - a), d - a)


def _crossing_2d(x: np.ndarray, ea: np.ndarray, eb: np.ndarray) -> np.ndarray:
    """Closed segments ``ea[i]`` and ``eb[i]`` intersect (their boxes are known to overlap).

    Each segment's end points lie on different sides of (or on) the other's line; for collinear
    segments the overlapping boxes mean they share a piece.
    """
    p, q, r, s = x[ea[:, 0]], x[ea[:, 1]], x[eb[:, 0]], x[eb[:, 1]]
    return (_orient2d(p, q, r) * _orient2d(p, q, s) <= 0.0) & (
        _orient2d(r, s, p) * _orient2d(r, s, q) <= 0.0
    )


def _crossing_3d(x: np.ndarray, edges: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Segments ``edges[i]`` pierce triangles ``tris[i]`` (coplanar touching is left to the
    inside test): end points on both sides of the plane, and the line passes the three edges
    of the triangle on the same side."""
    p, q = x[edges[:, 0]], x[edges[:, 1]]
    a, b, c = x[tris[:, 0]], x[tris[:, 1]], x[tris[:, 2]]
    sp, sq = _orient3d(a, b, c, p), _orient3d(a, b, c, q)
    straddle = (sp * sq <= 0.0) & ~((sp == 0.0) & (sq == 0.0))
    w = np.stack([_orient3d(p, q, a, b), _orient3d(p, q, b, c), _orient3d(p, q, c, a)], axis=1)
    inside = np.all(w >= 0.0, axis=1) | np.all(w <= 0.0, axis=1)
    return straddle & inside


def _boxes(x: np.ndarray, simplices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    v = x[simplices]
    return v.min(axis=1), v.max(axis=1)


def _fem_pair_crossing(model: Model, a: object, b: object, fem_x: np.ndarray) -> np.ndarray:
    """Indices into the boundary edges of ``a`` that cross the boundary of ``b``."""
    edges = _boundary_edges(model, a)
    facets = b.boundary
    if edges.size == 0 or facets.size == 0:
        return np.zeros(0, dtype=np.int64)
    pairs = box_overlap_pairs(*_boxes(fem_x, edges), *_boxes(fem_x, facets))
    if pairs.size == 0:
        return np.zeros(0, dtype=np.int64)
    crossing = _crossing_2d if model.dim == 2 else _crossing_3d
    hit = crossing(fem_x, edges[pairs[:, 0]], facets[pairs[:, 1]])
    return np.unique(pairs[hit, 0])


def check_no_overlap(
    model: Model, fem_x: np.ndarray | None = None, mpm_x: np.ndarray | None = None
) -> None:
    """Raise ``SceneError`` when bodies overlap.

    Args:
        model: the model (FEM meshes and MPM particles).
        fem_x: FEM node positions ``(N, d)`` in m (default: the rest positions, t = 0).
        mpm_x: particle positions ``(P, d)`` in m (default: the initial positions).
    """
    fem_x, mpm_x = _positions(model, fem_x, mpm_x)
    mesh_cls = TriMesh if model.dim == 2 else TetMesh
    meshes = [
        mesh_cls(fem_x[b.nodes], model.fem_cells[b.cells] - b.nodes.start) for b in model.fem_bodies
    ]
    for body, mesh in zip(model.fem_bodies, meshes, strict=True):
        if model.n_particles == 0:
            break
        inside = locate_points(mesh, mpm_x) >= 0
        for mpm_body in model.mpm_bodies:
            hit = np.flatnonzero(inside[mpm_body.particles])
            if hit.size:
                raise SceneError(
                    f"{hit.size} particle(s) start inside fem body '{body.name}' (particles "
                    f"{format_indices(hit)})",
                    body=f"mpm body '{mpm_body.name}'",
                    field="particles",
                    hint="bodies in contact must start apart: move one of them, or sample the "
                    "particles outside the mesh",
                )
    bodies = model.fem_bodies
    for i, a in enumerate(bodies):
        for j, b in enumerate(bodies):
            if i == j:
                continue
            inside = np.flatnonzero(locate_points(meshes[j], fem_x[a.nodes]) >= 0)
            problem = ""
            if inside.size:
                problem = f"{inside.size} node(s) start inside fem body '{b.name}' (nodes "
                problem += f"{format_indices(inside)})"
            elif j > i or model.dim == 3:  # 3D: edges of a through faces of b, and back
                crossing = _fem_pair_crossing(model, a, b, fem_x)
                if crossing.size:
                    problem = f"{crossing.size} boundary edge(s) cross the boundary of fem body "
                    problem += f"'{b.name}'"
            if problem:
                raise SceneError(
                    problem,
                    body=f"fem body '{a.name}'",
                    field="mesh",
                    hint="bodies in contact must start apart: move one of them",
                )


def check_clearance(
    model: Model,
    dhat: float,
    fem_x: np.ndarray | None = None,
    mpm_x: np.ndarray | None = None,
) -> None:
    """Raise ``SceneError`` when a particle is closer than ``dhat`` to a FEM boundary.

    Args:
        model: the model.
        dhat: barrier activation distance in m.
        fem_x: FEM node positions ``(N, d)`` in m (default: rest positions).
        mpm_x: particle positions ``(P, d)`` in m (default: initial positions).
    """
    fem_x, mpm_x = _positions(model, fem_x, mpm_x)
    if model.n_particles == 0 or not model.fem_bodies:
        return
    facets = np.concatenate([b.boundary for b in model.fem_bodies])
    owner = np.concatenate([np.full(len(b.boundary), b.index) for b in model.fem_bodies])
    pairs = point_simplex_candidates(mpm_x, fem_x, facets, inflation=dhat)
    if pairs.size == 0:
        return
    dist = _facet_distance(model.dim, mpm_x[pairs[:, 0]], fem_x[facets[pairs[:, 1]]])
    close = dist < dhat
    if not close.any():
        return
    worst = int(np.argmin(np.where(close, dist, np.inf)))
    particle = int(pairs[worst, 0])
    mpm_body = model.mpm_bodies[int(model.mpm_particle_body[particle])]
    fem_body = model.fem_bodies[int(owner[pairs[worst, 1]])]
    mine = close & (model.mpm_particle_body[pairs[:, 0]] == mpm_body.index)
    particles = np.unique(pairs[mine, 0]) - mpm_body.particles.start
    body = f"mpm body '{mpm_body.name}'"
    d_min = float(dist[worst])
    raise _clearance_error("particle", particles, d_min, dhat, body, "particles", fem_body.name)


def _facet_distance(dim: int, p: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Distances (m) of points ``p (k, d)`` to facets with vertices ``f (k, d, d)``."""
    if dim == 2:
        return point_edge_distance(p, f[:, 0], f[:, 1])
    return point_triangle_distance(p, f[:, 0], f[:, 1], f[:, 2])


def check_fem_clearance(model: Model, dhat: float, fem_x: np.ndarray | None = None) -> None:
    """Raise ``SceneError`` when a FEM boundary node is closer than ``dhat`` to the boundary of
    another FEM body (it would start with an active barrier force), as for particles.

    Args:
        model: the model.
        dhat: barrier activation distance in m.
        fem_x: FEM node positions ``(N, d)`` in m (default: rest positions).
    """
    fem_x, _ = _positions(model, fem_x, None)
    bodies = model.fem_bodies
    if len(bodies) < 2:
        return
    node_body = np.empty(model.fem_X.shape[0], dtype=np.int64)
    for b in bodies:
        node_body[b.nodes] = b.index
    rigid = np.array([bool(model.fem_prescribed[b.nodes].all()) for b in bodies])
    points = np.unique(np.concatenate([b.boundary.ravel() for b in bodies]))
    facets = np.concatenate([b.boundary for b in bodies])
    owner = np.concatenate([np.full(len(b.boundary), b.index) for b in bodies])
    pairs = point_simplex_candidates(fem_x[points], fem_x, facets, inflation=dhat)
    if pairs.size == 0:
        return
    node, facet_body = points[pairs[:, 0]], owner[pairs[:, 1]]
    mine = node_body[node]
    keep = (mine != facet_body) & ~(rigid[mine] & rigid[facet_body])
    node, facet_body, facet = node[keep], facet_body[keep], pairs[keep, 1]
    dist = _facet_distance(model.dim, fem_x[node], fem_x[facets[facet]])
    close = dist < dhat
    if not close.any():
        return
    worst = int(np.argmin(np.where(close, dist, np.inf)))
    a, b = bodies[int(node_body[node[worst]])], bodies[int(facet_body[worst])]
    same = close & (node_body[node] == a.index) & (facet_body == b.index)
    nodes = np.unique(node[same]) - a.nodes.start
    d_min = float(dist[worst])
    raise _clearance_error("node", nodes, d_min, dhat, f"fem body '{a.name}'", "mesh", b.name)


def validate_initial(model: Model) -> None:
    """The checks of the initial configuration that apply to ``model``.

    With contact (``model.contact`` set): :func:`check_no_overlap`, then :func:`check_clearance`
    and :func:`check_fem_clearance` with the contact's ``dhat``. Without contact bodies may pass
    through each other, so nothing is checked.
    """
    contact = getattr(model, "contact", None)
    if contact is None:
        return
    check_no_overlap(model)
    check_clearance(model, float(contact.dhat))
    check_fem_clearance(model, float(contact.dhat))
    log.debug("initial configuration: no overlap, boundaries farther than dhat from other bodies")
