"""An oracle for crossings and inversions, independent of the library's own checks (issue 44).

The library decides a step's crossing with CCD of its straight-line motion
(``bfemp.contact.intersection.trajectory_crossing``) and its inversions with its own det F. This
module judges the same step by other means, so that the fuzz benchmark (``benchmarks.fuzz``) can
tell a silent crossing the library missed:

- **inside**: barycentric coordinates of every FEM node and particle in every cell of every other
  FEM body (all pairs, numpy), at the step's end and at interior samples of the straight-line
  motion ``x(s) = (1 - s) x0 + s x1``. The samples are spaced so that no point moves, relative
  to any FEM node, more than a quarter of ``min_feature`` (the thinnest part of any body,
  given by the scene) between two of them: a pass through a body at least ``min_feature``
  thick is seen (capped at ``MAX_SAMPLES``; the record counts capped steps).
- **inversion**: J of every FEM cell (numpy's det of the deformed over the rest edge matrix) and
  det F of every particle, after a converged step: ``J <= 0`` is an inversion.

A point inside another body somewhere along its chord but outside at both ends is one of two
things. A sliding point's chord cuts a convex corner of the boundary it slides on (the solver's
iterates move around the corner, the chord between them does not): BFEMP's straight-line check
allows that cut (``contact._tunneling._corner_cuts``, a rule the paper leaves open). Or the point
passed through the body. The oracle tells them apart with its own rule, stated here and in the
record:

- a **pass** when the outward normals of the host body's boundary facets nearest to the point
  just before it enters and just after it leaves point apart (dot product below
  ``PASS_NORMAL_DOT``: through a plate, the two faces' normals are opposite) or when the run
  inside goes deeper than ``max(dhat, min(L / 2, a quarter of the host's mean boundary edge))``
  (``L`` the point's move relative to the host): the library's own corner allowance;
- a **corner cut** otherwise (counted, with its depth, not a crossing).

Shapes: ``x`` arrays are ``(n, d)`` positions in m; cells ``(C, d + 1)`` node indices.
"""

from __future__ import annotations

import numpy as np

#: interior samples of a step's motion at most (the record counts steps that needed more)
MAX_SAMPLES = 2048
#: entry and exit normals with a dot product below this are a pass through the body
PASS_NORMAL_DOT = -0.5
#: barycentric margin: a point counts as inside a cell when its smallest coordinate exceeds this
INSIDE_MARGIN = 1e-12
#: points x cells per chunk of the barycentric test (memory bound)
_CHUNK = 2_000_000


def cell_jacobians(x: np.ndarray, X: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """J = det(D_s) / det(D_m) of every cell ``(C,)``: deformed ``x`` against rest ``X``."""
    if cells.shape[0] == 0:
        return np.zeros(0)
    v, rest = x[cells], X[cells]
    ds = np.transpose(v[:, 1:] - v[:, :1], (0, 2, 1))
    dm = np.transpose(rest[:, 1:] - rest[:, :1], (0, 2, 1))
    return np.linalg.det(ds) / np.linalg.det(dm)


def boundary_facets(cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Facets of ``cells (C, d + 1)`` that belong to one cell only: ``(F, d)`` node indices and
    ``(F,)`` the node of that cell opposite each facet (inside the body, for its orientation)."""
    d1 = cells.shape[1]
    faces = np.concatenate([np.delete(cells, k, axis=1) for k in range(d1)])
    opposite = np.concatenate([cells[:, k] for k in range(d1)])
    key = np.sort(faces, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    once = counts[inverse.ravel()] == 1
    return faces[once], opposite[once]


class Bodies:
    """The FEM bodies of a model, as the oracle sees them: cells, owners, boundary facets.

    Args:
        model: a ``bfemp`` model (``fem_cells (C, d + 1)``, ``fem_cell_body (C,)``,
            ``fem_bodies`` with ``index``/``n_nodes``/``name``, ``fem_X (N, d)``,
            ``n_particles``, ``mpm_particle_body (P,)``).
    """

    def __init__(self, model) -> None:
        self.dim = model.dim
        self.cells = np.asarray(model.fem_cells)
        self.cell_body = np.asarray(model.fem_cell_body)
        self.names = [b.name for b in model.fem_bodies]
        owner = np.repeat(
            [b.index for b in model.fem_bodies], [b.n_nodes for b in model.fem_bodies]
        )
        if model.n_particles:
            owner = np.concatenate([owner, -1 - np.asarray(model.mpm_particle_body)])
        self.point_owner = owner  # FEM body index of a node, -1 - MPM body index of a particle
        self.rest = np.asarray(model.fem_X)  # (N, d) rest positions, m
        self.facets, self.facet_inner = [], []
        self.mean_edge = np.zeros(len(self.names))
        for b in range(len(self.names)):
            f, inner = boundary_facets(self.cells[self.cell_body == b])
            self.facets.append(f)
            self.facet_inner.append(inner)
            corners = model.fem_X[f]
            self.mean_edge[b] = np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2).mean()

    def host(self, points: np.ndarray, fem_x: np.ndarray, which: np.ndarray) -> np.ndarray:
        """For ``points (n, d)`` (the points ``which (n,)`` of the model, FEM nodes first), the
        index of another FEM body whose cell strictly contains each, else -1: ``(n,)``."""
        out = np.full(points.shape[0], -1)
        if points.shape[0] == 0 or self.cells.shape[0] == 0:
            return out
        v = fem_x[self.cells]
        edges = np.transpose(v[:, 1:] - v[:, :1], (0, 2, 1))  # (C, d, d)
        # a flat cell (zero measure, e.g. mid-way through an inversion) contains no point
        scale = np.abs(edges).max(axis=(1, 2)) ** self.dim
        flat = np.abs(np.linalg.det(edges)) <= 1e-12 * scale
        edges[flat] = np.eye(self.dim)
        inv = np.linalg.inv(edges)  # (C, d, d)
        inv[flat] = np.nan  # its barycentric coordinates are NaN: never inside
        step = max(1, _CHUNK // self.cells.shape[0])
        for lo in range(0, points.shape[0], step):
            p = points[lo : lo + step]
            lam = np.einsum("cij,pcj->pci", inv, p[:, None, :] - v[None, :, 0])
            bary = np.minimum(1.0 - lam.sum(axis=2), lam.min(axis=2))
            inside = (bary > INSIDE_MARGIN) & (
                self.point_owner[which[lo : lo + step], None] != self.cell_body[None, :]
            )
            hit = inside.any(axis=1)
            out[lo : lo + step][hit] = self.cell_body[inside[hit].argmax(axis=1)]
        return out

    def nearest_facet(
        self, p: np.ndarray, fem_x: np.ndarray, body: int
    ) -> tuple[float, np.ndarray]:
        """Distance in m from ``p (d,)`` to body ``body``'s boundary, and the outward unit normal
        ``(d,)`` of the nearest boundary facet (the plane's normal, turned away from the cell
        the facet bounds)."""
        f = self.facets[body]
        corners = fem_x[f]  # (F, d, d)
        closest = _closest_on_simplices(p, corners)
        dist = np.linalg.norm(p[None] - closest, axis=1)
        k = int(np.argmin(dist))
        a = corners[k]
        if self.dim == 2:
            t = a[1] - a[0]
            n = np.array([-t[1], t[0]])
        else:
            n = np.cross(a[1] - a[0], a[2] - a[0])
        if np.dot(n, fem_x[self.facet_inner[body][k]] - a[0]) > 0.0:
            n = -n
        return float(dist[k]), n / np.linalg.norm(n)


def _closest_on_simplices(p: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """Closest points ``(F, d)`` to ``p (d,)`` on segments (2D) or triangles (3D) ``corners
    (F, d, d)``: the exact projection where it falls inside, else the closest point on the
    facet's edges."""
    if corners.shape[1] == 2:
        return _closest_on_segments(p, corners[:, 0], corners[:, 1])
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    n = np.cross(b - a, c - a)
    nn = np.einsum("fi,fi->f", n, n)
    q = p[None] - (np.einsum("fi,fi->f", p[None] - a, n) / nn)[:, None] * n

    # barycentric coordinates of the projection q
    def area(u, v, w):
        return np.einsum("fi,fi->f", np.cross(v - u, w - u), n)

    inside = (area(q, b, c) >= 0) & (area(a, q, c) >= 0) & (area(a, b, q) >= 0)
    edges = np.stack(
        [_closest_on_segments(p, u, v) for u, v in ((a, b), (b, c), (c, a))]
    )  # (3, F, d)
    d_edge = np.linalg.norm(p[None, None] - edges, axis=2)
    best = edges[d_edge.argmin(axis=0), np.arange(a.shape[0])]
    return np.where(inside[:, None], q, best)


def _closest_on_segments(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Closest points ``(F, d)`` to ``p (d,)`` on the segments ``a``-``b`` ``(F, d)``."""
    ab = b - a
    t = np.einsum("fi,fi->f", p[None] - a, ab) / np.maximum(np.einsum("fi,fi->f", ab, ab), 1e-300)
    return a + np.clip(t, 0.0, 1.0)[:, None] * ab


def judge_step(bodies: Bodies, start, end, min_feature: float, dhat: float) -> dict:
    """Judge one converged step from ``start`` to ``end`` (``bfemp`` states).

    Returns a dict: ``inverted`` (cells or particles with J <= 0 at the end), ``min_J``,
    ``end_inside`` (points inside another body at the end), ``passes`` (points that passed
    through or went deeper than the corner allowance during the motion), ``corner_cuts``
    (shallow chords that cut a corner), ``max_cut_depth_m``, ``samples`` (interior samples
    used), ``capped`` (whether more than ``MAX_SAMPLES`` were needed) and ``first`` (a line
    naming the first offending point and body, or None).
    """
    J = cell_jacobians(end.fem_x, bodies.rest, bodies.cells)
    if end.mpm_x.shape[0]:
        J = np.concatenate([J, np.linalg.det(end.mpm_F)])
    out = {
        "min_J": float(J.min()) if J.size else 1.0,
        "inverted": int((J <= 0.0).sum()),
        "end_inside": 0,
        "passes": 0,
        "corner_cuts": 0,
        "max_cut_depth_m": 0.0,
        "samples": 0,
        "capped": False,
        "first": None,
    }
    x0 = _points(start)
    x1 = _points(end)
    which = np.arange(x0.shape[0])
    end_host = bodies.host(x1, end.fem_x, which)
    out["end_inside"] = int((end_host >= 0).sum())
    if out["end_inside"]:
        i = int(np.flatnonzero(end_host >= 0)[0])
        out["first"] = f"point {i} ends inside body '{bodies.names[end_host[i]]}'"
    # samples: relative motion between two samples below a quarter of the thinnest feature
    move_points = np.linalg.norm(x1 - x0, axis=1).max(initial=0.0)
    move_nodes = np.linalg.norm(end.fem_x - start.fem_x, axis=1).max(initial=0.0)
    needed = int(np.ceil(4.0 * (move_points + move_nodes) / min_feature))
    n_samples = min(max(needed, 8), MAX_SAMPLES)
    out["samples"], out["capped"] = n_samples, needed > MAX_SAMPLES
    s_values = np.linspace(0.0, 1.0, n_samples + 1)
    hosts = np.full((n_samples + 1, x0.shape[0]), -1)
    hosts[-1] = end_host
    for k, s in enumerate(s_values[1:-1], start=1):
        hosts[k] = bodies.host((1 - s) * x0 + s * x1, (1 - s) * start.fem_x + s * end.fem_x, which)
    flagged = np.flatnonzero((hosts[1:-1] >= 0).any(axis=0))
    for i in flagged:  # the few points inside somewhere along their chord
        verdict = _classify_runs(bodies, i, hosts[:, i], s_values, start, end, x0, x1, dhat)
        for kind, depth, body in verdict:
            if kind == "pass":
                out["passes"] += 1
                if out["first"] is None:
                    out["first"] = (
                        f"point {i} passes through body '{bodies.names[body]}' ({depth:.3g} m deep)"
                    )
            else:
                out["corner_cuts"] += 1
                out["max_cut_depth_m"] = max(out["max_cut_depth_m"], depth)
    return out


def _points(state) -> np.ndarray:
    return np.concatenate([state.fem_x, state.mpm_x]) if state.mpm_x.shape[0] else state.fem_x


def _classify_runs(bodies, i, host, s_values, start, end, x0, x1, dhat):
    """Each run of samples where point ``i`` is inside a body that ends before the step does:
    ``[(kind, depth_m, body)]`` with kind ``"pass"`` or ``"cut"`` (module docstring)."""
    runs, k, n = [], 1, host.shape[0] - 1
    while k < n:
        if host[k] < 0:
            k += 1
            continue
        body, lo = host[k], k
        while k < n and host[k] == body:
            k += 1
        if host[k] == body:  # ends inside: counted by end_inside
            break
        runs.append((body, lo, k))  # inside on samples lo .. k - 1; outside at lo - 1 and k
    verdicts = []
    for body, lo, hi in runs:

        def at(j):
            s = s_values[j]
            return (1 - s) * x0[i] + s * x1[i], (1 - s) * start.fem_x + s * end.fem_x

        depth = max(bodies.nearest_facet(*at(j), body)[0] for j in range(lo, hi))
        n_in = bodies.nearest_facet(*at(lo - 1), body)[1]
        n_out = bodies.nearest_facet(*at(hi), body)[1]
        nodes = np.unique(bodies.facets[body])
        rel = (x1[i] - x0[i]) - (end.fem_x[nodes] - start.fem_x[nodes]).mean(axis=0)
        L = float(np.linalg.norm(rel))
        allowance = max(dhat, min(0.5 * L, 0.25 * bodies.mean_edge[body]))
        through = float(np.dot(n_in, n_out)) < PASS_NORMAL_DOT or depth > allowance
        verdicts.append(("pass" if through else "cut", depth, int(body)))
    return verdicts
