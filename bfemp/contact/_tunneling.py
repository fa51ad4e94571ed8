"""The trajectory half of the intersection check: a crossing along the step's straight-line
motion, by continuous collision detection with no false negative (see
:mod:`bfemp.contact.intersection`)."""

from __future__ import annotations

import logging

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from bfemp.contact._end_state import (
    Intersection,
    _node_name,
    _point_name,
    end_of_step_points,
    points_inside,
)
from bfemp.contact.collision import CollisionSet, facet_edge_lengths
from bfemp.contact.pairs import candidate_pairs, edge_edge_active, edge_edge_pairs
from bfemp.errors import warn_user
from bfemp.model import Model
from bfemp.state import State
from geometry.ccd import edge_edge_ccd, point_edge_ccd, point_triangle_ccd
from geometry.distance import edge_edge_distance, point_edge_distance, point_triangle_distance

__all__ = ["FLOOR_REL", "MAX_ROUNDS", "trajectory_crossing"]

log = logging.getLogger("bfemp.contact.intersection")


#: Crossing floor relative to the step's largest coordinate magnitude (dimensionless): a pair
#: whose straight-line motion comes within 2 x FLOOR_REL x max|x| counts as a crossing. Far above
#: the rounding of a distance (~1e-16 max|x|, where CCD itself is unreliable: issue 44, defect
#: 3) and far below any gap the barrier leaves (d / d-hat ~ 1e-3 and up). A choice of ours.
FLOOR_REL = 1e-10

#: CCD restarts per pair before an undecided pair counts as a crossing (conservative).
MAX_ROUNDS = 100

#: ACCD iteration cap per round (the round returns a safe time; the next round goes on).
_CCD_ITERATIONS = 100_000

#: kind -> (CCD, distance) of :mod:`geometry` for the trajectory check.
_CCD = {
    "pe": (point_edge_ccd, point_edge_distance),
    "pt": (point_triangle_ccd, point_triangle_distance),
    "ee": (edge_edge_ccd, edge_edge_distance),
}


def _floor(y0: np.ndarray, y1: np.ndarray) -> float:
    """The crossing floor in m: ``FLOOR_REL`` x the largest coordinate magnitude of the step."""
    scale = max(float(np.abs(y0).max(initial=0.0)), float(np.abs(y1).max(initial=0.0)))
    return FLOOR_REL * max(scale, np.finfo(float).tiny)


def _certify(kind: str, X0: np.ndarray, dX: np.ndarray, floor: float) -> np.ndarray:
    """First time in [0, 1] at which each pair comes within ``2 floor`` (its crossing time), inf
    where the pair is certified clear on the whole step.

    Pairs ``X0 (n, m, d)`` move linearly by ``dX (n, m, d)`` over the step (point first, then the
    facet's vertices; or edge a, edge b). Rounds of the conservative CCD of :mod:`geometry.ccd`
    with ``min_distance = floor``, each restarted where the last stopped on the remaining part
    of the step (rescaled to ``t_max = 1``): a round reaching 1 certifies the pair clear (CCD
    never reports a later time than the true impact, so no crossing is missed); one starting
    within ``2 floor`` (distance) is a crossing. A pair still undecided after ``MAX_ROUNDS``
    (grazing motion at a gap near the floor) counts as a crossing: conservative.
    """
    ccd, dist = _CCD[kind]
    m = X0.shape[1]
    n = X0.shape[0]
    tau = np.zeros(n)
    hit = np.full(n, np.inf)
    active = np.arange(n)
    for _ in range(MAX_ROUNDS):
        X = X0[active] + tau[active, None, None] * dX[active]
        d = dist(*(X[:, a] for a in range(m)))
        near = d <= 2.0 * floor
        hit[active[near]] = tau[active[near]]
        active, X = active[~near], X[~near]
        if active.size == 0:
            return hit
        rest = (1.0 - tau[active])[:, None, None] * dX[active]
        toi = ccd(
            *(X[:, a] for a in range(m)),
            *(rest[:, a] for a in range(m)),
            min_distance=floor,
            max_iterations=_CCD_ITERATIONS,
        )
        clear = toi >= 1.0
        stuck = toi <= 0.0  # starts within the floor (the CCD's contract): a crossing
        hit[active[stuck]] = tau[active[stuck]]
        tau[active] += toi * (1.0 - tau[active])
        active = active[~clear & ~stuck]
        if active.size == 0:
            return hit
    warn_user(
        f"CCD_UNCERTIFIED: end-of-step check: {active.size} {kind} pair(s) not certified clear "
        f"after {MAX_ROUNDS} CCD rounds (grazing motion near the floor {floor:.3g} m): counted "
        "as crossings",
        logger=log,
    )
    hit[active] = tau[active]
    return hit


#: samples along a chord when measuring how deep a corner cut goes (interior points)
_CUT_SAMPLES = 16


def _corner_cuts(
    model: Model,
    cs: CollisionSet,
    pairs: np.ndarray,
    chords: tuple[np.ndarray, np.ndarray],
    states: tuple[State, State],
    floor: float,
) -> np.ndarray:
    """Which crossing (point, facet) ``pairs (n, 2)`` are a sliding point cutting a convex
    corner of the body on its chord, not a pass through it: ``(n,)`` bool.

    A point sliding along a faceted boundary moves around a convex vertex (2D) or edge (3D)
    between the solver's iterates, but its chord x^n -> x^{n+1} cuts the corner: it enters
    through one facet and leaves through a neighbour. That is no crossing of the body. A pair
    counts as such a cut when all of these hold (else it stays a crossing):

    - the point is in contact with the body at the start or at the end of the step (within
      d-hat, or a quarter of the body's mean boundary edge without contact settings): it slides
      along it, or flies off one of its corners;
    - its move L relative to the entry facet is below half the body's extent (a longer chord
      is no cut of one corner);
    - it leaves through a facet (the exit facet: the first one hit along the reversed chord)
      no farther along the body's boundary from the entry facet than its move L (path through
      facets sharing vertices, centroid to centroid): around a corner or over a crest. A pass
      through a plate leaves through the far side, around the plate's end from the entry;
    - nowhere along the chord does it lie deeper inside the body than a corner's cut allows:
      the larger of that contact distance and min(L / 2, a quarter of the body's mean boundary
      edge) (the cut of a corner of turn angle theta is (L / 2) tan(theta / 2): L / 2 covers
      turns up to 90 degrees; the cap keeps a cut near its corner; the rule of the sampled
      check this one replaced) (``_CUT_SAMPLES`` interior samples: those strictly inside a
      cell of the body at that time, by their distance to the body's boundary).

    ``chords``: the collision points' positions ``(C, d)`` at the start and the end of the
    step; ``states``: the step's start and end states (for the cells along the chord).
    """
    y0, y1 = chords
    x0, x1 = states[0].fem_x, states[1].fem_x
    ts = np.arange(1, _CUT_SAMPLES + 1) / (_CUT_SAMPLES + 1)
    out = np.zeros(pairs.shape[0], dtype=bool)
    kind = "pe" if model.dim == 2 else "pt"
    dist = _CCD[kind][1]
    # each body's mean rest boundary-edge length in m, by body index
    edge = [facet_edge_lengths(model.fem_X, b.boundary).mean() for b in model.fem_bodies]
    reach = model.contact.dhat if model.contact is not None else None
    for i, (point, facet) in enumerate(pairs):  # crossings: a handful per failing step
        body = int(cs.facet_body[facet])
        near = reach if reach is not None else 0.25 * edge[body]
        own = cs.facets[cs.facet_body == body]
        k = own.shape[0]

        def gaps(y: np.ndarray, point: int = point, own: np.ndarray = own, k: int = k) -> float:
            return float(
                dist(
                    np.repeat(y[point][None], k, 0), *(y[own[:, a]] for a in range(own.shape[1]))
                ).min()
            )

        if min(gaps(y0), gaps(y1)) > near:
            continue  # in contact at neither end: flying through, not sliding along
        rows = np.column_stack([np.full(k, point), own])
        back = _certify(kind, y1[rows], y0[rows] - y1[rows], floor)
        if not np.isfinite(back).any():
            continue
        exit_index = int(np.argmin(back))
        entry_index = int(np.flatnonzero(np.all(own == cs.facets[facet], axis=1))[0])
        move = (y1[point] - y0[point]) - (y1[cs.facets[facet]] - y0[cs.facets[facet]]).mean(0)
        chord = float(np.linalg.norm(move))
        extent = y1[own.ravel()].max(axis=0) - y1[own.ravel()].min(axis=0)
        if chord > 0.5 * float(np.linalg.norm(extent)):
            continue  # moved farther than the body is wide: not around one of its corners
        if _boundary_path(own, y1, entry_index, exit_index, chord) > chord:
            continue  # leaves far along the boundary from where it entered: through the body
        allowance = max(near, min(0.5 * chord, 0.25 * edge[body]))
        deepest = 0.0
        for t in ts:  # 16 samples of one chord
            y = (1.0 - t) * y0[point] + t * y1[point]
            x = (1.0 - t) * x0 + t * x1
            cell = points_inside(y[None], np.array([-1]), x, model.fem_cells, model.fem_cell_body)
            if cell[0] >= 0 and model.fem_cell_body[cell[0]] == body:
                deepest = max(deepest, gaps((1.0 - t) * y0 + t * y1))
        out[i] = deepest <= allowance
    return out


def _boundary_path(facets: np.ndarray, y: np.ndarray, a: int, b: int, limit: float) -> float:
    """Length in m of the boundary between facets ``a`` and ``b`` of ``facets (k, d)``: the
    summed sizes of the facets a shortest chain of vertex-sharing facets passes through between
    them (0 for neighbours; sizes: the mean edge of each facet at positions ``y``); inf beyond
    ``limit``."""
    if a == b:
        return 0.0
    k, m = facets.shape
    v = y[facets]
    size = np.linalg.norm(v - np.roll(v, 1, axis=1), axis=2).mean(axis=1)
    incidence = coo_matrix(
        (np.ones(k * m), (np.repeat(np.arange(k), m), facets.ravel())), shape=(k, y.shape[0])
    ).tocsr()
    touching = (incidence @ incidence.T).tocoo()
    # a step i -> j costs half of each size: the chain a .. b costs its inner facets' sizes
    # plus half of a's and b's, taken off at the end
    weight = 0.5 * (size[touching.row] + size[touching.col]) + 1e-300
    graph = coo_matrix((weight, (touching.row, touching.col)), shape=(k, k)).tocsr()
    ends = 0.5 * (size[a] + size[b])
    return max(0.0, float(dijkstra(graph, indices=a, limit=limit + ends)[b]) - ends)


def trajectory_crossing(model: Model, start: State, end: State) -> Intersection | None:
    """The first crossing of a FEM boundary along the step's straight-line motion, or None.

    Every FEM boundary node and particle against the boundary facets of every other FEM body
    (point-edge in 2D, point-triangle in 3D) and, in 3D, the boundary edges of different FEM
    bodies against each other, all moving linearly ``x^n -> x^{n+1}`` (section 5's path, taken
    over the whole step): candidates from the swept-box broad phase
    (``bfemp.contact.pairs``), then :func:`_certify` per pair (CCD with no false negative).

    Returns:
        An ``Intersection`` with status ``"TUNNELED"`` at the earliest crossing time found
        (``s`` in [0, 1]), naming the point (or edge) and the body it passes into; None when
        every pair is certified clear.
    """
    if len(model.fem_bodies) == 0:
        return None
    cs = end_of_step_points(model)
    if cs.facets.shape[0] == 0:
        return None
    x0 = np.concatenate([start.fem_x, start.mpm_x]) if model.n_particles else start.fem_x
    x1 = np.concatenate([end.fem_x, end.mpm_x]) if model.n_particles else end.fem_x
    y0, y1 = cs.positions(x0), cs.positions(x1)
    floor = _floor(y0, y1)
    found: list[tuple[float, int, str, str]] = []  # (time, count, what, into which body)
    kind = "pe" if model.dim == 2 else "pt"
    cand = candidate_pairs(cs, y0, 0.0, y1)
    if cand.shape[0]:
        rows = np.column_stack([cand[:, 0], cs.facets[cand[:, 1]]])
        hit = _certify(kind, y0[rows], y1[rows] - y0[rows], floor)
        crossing = np.flatnonzero(np.isfinite(hit))
        if crossing.size:
            cut = _corner_cuts(model, cs, cand[crossing], (y0, y1), (start, end), floor)
            crossing = crossing[~cut]
        if crossing.size:
            i = crossing[np.argmin(hit[crossing])]
            body = model.fem_bodies[int(cs.facet_body[cand[i, 1]])].name
            what = _point_name(model, cs, int(cand[i, 0]))
            n_points = np.unique(cand[crossing, 0]).size
            found.append((float(hit[i]), n_points, what, body))
    if model.dim == 3 and edge_edge_active(cs):
        ee, _ = edge_edge_pairs(cs, y0, 0.0, y1)
        if ee.shape[0]:
            hit = _certify("ee", y0[ee], y1[ee] - y0[ee], floor)
            crossing = np.flatnonzero(np.isfinite(hit))
            if crossing.size:
                i = crossing[np.argmin(hit[crossing])]
                a = [_node_name(model, int(cs.nodes[c, 0])) for c in ee[i]]
                what = f"the boundary edge of {a[0][0]} and {a[1][0].split(' of ')[0]}"
                found.append((float(hit[i]), crossing.size, what, a[2][1]))
    if not found:
        return None
    s, n, what, body = min(found)
    return Intersection(status="TUNNELED", s=s, n_points=n, point=what, body=body)
