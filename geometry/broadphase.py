"""Contact broad phase: candidate pairs whose (swept, inflated) axis-aligned boxes overlap.

BFEMP's barrier acts between MPM particles (points) and FEM boundary simplices (segments in 2D,
triangles in 3D) closer than ``dhat``; CCD needs every pair that can touch along a linear motion.
Both are served by one conservative filter on axis-aligned bounding boxes (AABBs):

- the box of a primitive is the box of its vertices; with ``*_end`` positions it is the box of
  the start *and* end positions (the swept box, which contains the whole linear motion);
- the second primitive's box (the simplex, or the edge of ``edges_b``) is inflated by
  ``inflation`` on every side and rounded outward by one ulp; the first one's is not. Two boxes
  are candidates when they overlap as closed intervals on every axis:

      a_lo[k] <= b_hi[k] + inflation   and   b_lo[k] - inflation <= a_hi[k]   for every axis k,

  i.e. when their per-axis gap is at most ``inflation``. Hence every pair whose true distance is
  <= ``inflation`` at the start, and every pair that can touch along the linear motion, is
  returned (the gap on each axis is at most the Euclidean distance). Inflating both boxes by
  ``dhat / 2`` (ipc-toolkit's convention) gives the same pairs as ``inflation=dhat`` here.
  No pair is removed for sharing a vertex (edge-edge callers filter adjacency themselves).

All the implementations return exactly the same pairs because they end with the same floating
point predicate (checked by the tests):

- ``"hash"``: numba uniform spatial hash (:mod:`geometry._hash_kernels`): cell size = mean
  largest extent of the inflated simplex boxes (doubled while the number of visited cells exceeds
  16 (P + S)), simplex boxes counting-sorted into a power-of-two bucket table (CSR), point boxes
  queried in parallel, pairs deduplicated with ``np.unique`` on the key ``i * S + j``.
- ``"fcl"``: python-fcl, one ``DynamicAABBTreeCollisionManager`` of ``fcl.Box`` objects per side
  (boxes grown by a few ulps so that fcl's own rounding cannot lose a pair), manager-vs-manager
  ``collide`` with a callback collecting the overlapping leaves, then the exact predicate. Building
  the fcl objects and the callback are Python-level per box / per pair (python-fcl offers nothing
  else); this is the independent cross-check, not the production path.
- ``"brute"``: O(P S) numpy broadcasting in chunks; the reference for small inputs.
- ``"scan"``: O(P S) numba loop over every pair, output in order: no set-up at all.
- ``"auto"``: ``"scan"`` up to ``P S = 100,000`` box pairs, ``"hash"`` above: the hash is 10-100x
  faster than fcl (``benchmarks.perf_broadphase``), but its set-up costs 0.2 ms at any size, where
  scanning 20,000 pairs takes 0.02 ms (2 cores; ``docs/guide/performance.md``).

Output: (n, 2) int64 rows ``(index in the first set, index in the second set)``, unique and
sorted lexicographically. Memory is proportional to the number of pairs: a huge inflation makes
every pair a candidate.
"""

from __future__ import annotations

import logging

import fcl
import numpy as np

from geometry import _hash_kernels as hk
from geometry._checks import indices
from geometry._checks import points as _positions

__all__ = [
    "METHODS",
    "box_overlap_pairs",
    "edge_edge_candidates",
    "point_simplex_candidates",
    "unique_keys",
]

logger = logging.getLogger(__name__)

#: Accepted values of the ``method`` argument.
METHODS = ("auto", "scan", "hash", "fcl", "brute")
_SCAN_PAIRS = 100_000  # "auto" scans every pair up to this many (P S), hashes above
# Elements of the (chunk, S, d) comparison array of the brute force, per chunk.
_BRUTE_CHUNK = 1 << 22
# The hash doubles its cell size while it would visit more than this many cells per box.
_CELL_BUDGET = 16


def point_simplex_candidates(
    points: np.ndarray,
    simplex_vertices: np.ndarray,
    simplices: np.ndarray,
    *,
    inflation: float = 0.0,
    points_end: np.ndarray | None = None,
    vertices_end: np.ndarray | None = None,
    groups: tuple[np.ndarray, np.ndarray] | None = None,
    method: str = "auto",
) -> np.ndarray:
    """Candidate (point, simplex) pairs whose swept boxes are within ``inflation`` of each other.

    Args:
        points: (P, d) point positions in m, d = 2 or 3 (MPM particles, FEM boundary nodes).
        simplex_vertices: (V, d) vertex positions in m.
        simplices: (S, k) int vertex indices (segments k = 2, triangles k = 3; any k >= 1).
        inflation: distance in m (>= 0) by which the simplex boxes are grown, typically ``dhat``.
        points_end: (P, d) end positions in m of a linear motion, or None for static points.
        vertices_end: (V, d) end positions in m of a linear motion, or None.
        groups: ``(point_group (P,), simplex_group (S,))`` integer labels (bodies): only pairs
            of different groups, one pass per simplex group on the other groups' points (a
            body's own nodes would each meet the simplices around them); None: every pair.
        method: one of :data:`METHODS` (see the module docstring).

    Returns:
        (n, 2) int64 rows ``(point index, simplex index)``, unique, sorted lexicographically.
        Every pair at distance <= ``inflation`` at the start, or that can touch along the
        linear motion, is included (extra pairs are possible).
    """
    method = _check_method(method)
    inflation = _check_inflation(inflation)
    points = _positions("points", points)
    dim = points.shape[1]
    simplex_vertices = _positions("simplex_vertices", simplex_vertices, dim)
    simplices = indices("simplices", simplices, simplex_vertices.shape[0])
    points_end = _end("points_end", points_end, "points", points)
    vertices_end = _end("vertices_end", vertices_end, "simplex_vertices", simplex_vertices)
    if groups is None:
        a = (points, points_end, None)
        return _swept_pairs(a, (simplex_vertices, vertices_end, simplices), inflation, method)
    point_group, simplex_group = (np.asarray(g) for g in groups)
    if point_group.shape != points.shape[:1] or simplex_group.shape != simplices.shape[:1]:
        raise ValueError(
            f"groups must be ({points.shape[0]},) and ({simplices.shape[0]},) labels of the points "
            f"and simplices, got {point_group.shape} and {simplex_group.shape}"
        )
    found = [np.zeros((0, 2), dtype=np.int64)]
    for group in np.unique(simplex_group):  # a loop over groups (bodies)
        si, pi = np.flatnonzero(simplex_group == group), np.flatnonzero(point_group != group)
        a = (points[pi], points_end[pi], None)
        cand = _swept_pairs(a, (simplex_vertices, vertices_end, simplices[si]), inflation, method)
        found.append(np.column_stack([pi[cand[:, 0]], si[cand[:, 1]]]))
    rows = np.concatenate(found)
    return np.ascontiguousarray(rows[np.lexsort((rows[:, 1], rows[:, 0]))])


def edge_edge_candidates(
    vertices: np.ndarray,
    edges_a: np.ndarray,
    edges_b: np.ndarray,
    *,
    inflation: float = 0.0,
    vertices_end: np.ndarray | None = None,
    method: str = "auto",
) -> np.ndarray:
    """Candidate (edge in a, edge in b) pairs whose swept boxes are within ``inflation``.

    Args:
        vertices: (V, d) vertex positions in m, d = 3 (edge-edge contact) or 2.
        edges_a: (A, 2) int vertex indices of the first edge set.
        edges_b: (B, 2) int vertex indices of the second edge set (may be ``edges_a``).
        inflation: distance in m (>= 0) by which the boxes of ``edges_b`` are grown.
        vertices_end: (V, d) end positions in m of a linear motion, or None.
        method: one of :data:`METHODS` (see the module docstring).

    Returns:
        (n, 2) int64 rows ``(index in edges_a, index in edges_b)``, unique, sorted. Pairs of
        edges sharing a vertex (and ``(i, i)`` when both sets are the same) are not removed.
    """
    method = _check_method(method)
    inflation = _check_inflation(inflation)
    vertices = _positions("vertices", vertices)
    edges_a = indices("edges_a", edges_a, vertices.shape[0], 2)
    edges_b = indices("edges_b", edges_b, vertices.shape[0], 2)
    vertices_end = _end("vertices_end", vertices_end, "vertices", vertices)
    a, b = (vertices, vertices_end, edges_a), (vertices, vertices_end, edges_b)
    return _swept_pairs(a, b, inflation, method)


def box_overlap_pairs(
    a_lo: np.ndarray,
    a_hi: np.ndarray,
    b_lo: np.ndarray,
    b_hi: np.ndarray,
    *,
    method: str = "auto",
) -> np.ndarray:
    """All pairs of overlapping closed boxes, ``a_lo <= b_hi`` and ``b_lo <= a_hi`` on every axis.

    Args:
        a_lo, a_hi: (P, d) lower / upper corners in m of the first box set, d = 2 or 3.
        b_lo, b_hi: (S, d) lower / upper corners in m of the second box set.
        method: one of :data:`METHODS` (see the module docstring).

    Returns:
        (n, 2) int64 rows ``(index in a, index in b)``, unique, sorted lexicographically.
    """
    method = _check_method(method)
    a_lo = _positions("a_lo", a_lo)
    dim = a_lo.shape[1]
    a_hi = _end("a_hi", a_hi, "a_lo", a_lo)
    b_lo = _positions("b_lo", b_lo, dim)
    b_hi = _end("b_hi", b_hi, "b_lo", b_lo)
    for name, lo, hi in (("a", a_lo, a_hi), ("b", b_lo, b_hi)):
        bad = np.flatnonzero(np.any(lo > hi, axis=1))
        if bad.size:
            raise ValueError(f"{name}_lo > {name}_hi in boxes {bad[:10].tolist()}")
    return _pairs(*(_pad3(x) for x in (a_lo, a_hi, b_lo, b_hi)), method)


# ---------------------------------------------------------------------------- validation


def _check_method(method: str) -> str:
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    return method


def _check_inflation(inflation: float) -> float:
    value = float(inflation)
    if not np.isfinite(value) or value < 0.0:
        raise ValueError(f"inflation must be finite and >= 0, got {inflation!r}")
    return value


def _end(name: str, array: np.ndarray | None, like_name: str, like: np.ndarray) -> np.ndarray:
    if array is None:
        return like
    out = _positions(name, array, like.shape[1])
    if out.shape != like.shape:
        raise ValueError(f"{name} must have the shape of {like_name} {like.shape}, got {out.shape}")
    return out


# ---------------------------------------------------------------------------- boxes


def _primitive_boxes(
    x0: np.ndarray, x1: np.ndarray, cells: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray]:
    """(N, 3) corners of the boxes of the start and end positions of each primitive's vertices.

    2D boxes get a zero z interval; the overlap predicate is unchanged by it.
    """
    if cells is None:
        cells = np.arange(x0.shape[0], dtype=np.int64)[:, None]
    lo = np.empty((cells.shape[0], 3))
    hi = np.empty((cells.shape[0], 3))
    hk._boxes(x0, x1, cells, lo, hi)
    return lo, hi


def _swept_pairs(a: tuple, b: tuple, inflation: float, method: str) -> np.ndarray:
    """Overlapping pairs of the swept boxes of primitives ``a`` and ``b``, each given as the
    arguments of :func:`_primitive_boxes`, those of ``b`` grown by ``inflation``."""
    a_lo, a_hi = _primitive_boxes(*a)
    b_lo, b_hi = _inflate(*_primitive_boxes(*b), inflation)
    return _pairs(a_lo, a_hi, b_lo, b_hi, method)


def _inflate(lo: np.ndarray, hi: np.ndarray, inflation: float) -> tuple[np.ndarray, np.ndarray]:
    """Grow boxes by ``inflation`` on every side, then by one ulp outward.

    Rounding to nearest is monotone, so ``fl(hi + inflation)`` already admits every float within
    ``inflation`` of ``hi``; the extra ulp is a margin for the rounding of the caller's distances.
    """
    if inflation == 0.0:
        return lo, hi
    return np.nextafter(lo - inflation, -np.inf), np.nextafter(hi + inflation, np.inf)


def _pad3(a: np.ndarray) -> np.ndarray:
    """Checked corners ``a (n, d)`` (C-contiguous float64) with zero columns up to d = 3."""
    return a if a.shape[1] == 3 else np.pad(a, ((0, 0), (0, 3 - a.shape[1])))


def _overlapping(
    a_lo: np.ndarray, a_hi: np.ndarray, b_lo: np.ndarray, b_hi: np.ndarray
) -> np.ndarray:
    """The shared predicate: closed-interval overlap on every axis (broadcasts)."""
    return np.all((a_lo <= b_hi) & (b_lo <= a_hi), axis=-1)


def unique_keys(keys: np.ndarray) -> np.ndarray:
    """Sorted unique values of the int64 ``keys (n,)``: a sort and a mask (numpy 2's
    ``np.unique`` hashes first, 30x slower on these keys)."""
    keys = np.sort(keys)
    return keys[np.concatenate(([True], keys[1:] != keys[:-1]))] if keys.size else keys


def _sorted_unique(ia: np.ndarray, ib: np.ndarray, n_b: int) -> np.ndarray:
    keys = unique_keys(ia.astype(np.int64) * n_b + ib)
    return np.ascontiguousarray(np.stack([keys // n_b, keys % n_b], axis=1))


def _pairs(
    a_lo: np.ndarray, a_hi: np.ndarray, b_lo: np.ndarray, b_hi: np.ndarray, method: str
) -> np.ndarray:
    if a_lo.shape[0] == 0 or b_lo.shape[0] == 0:
        return np.empty((0, 2), dtype=np.int64)
    if method == "auto":
        method = "scan" if a_lo.shape[0] * b_lo.shape[0] <= _SCAN_PAIRS else "hash"
    impl = {"scan": hk._scan, "hash": _hash_pairs, "fcl": _fcl_pairs, "brute": _brute_pairs}[method]
    return impl(a_lo, a_hi, b_lo, b_hi)


# ---------------------------------------------------------------------------- brute force


def _brute_pairs(
    a_lo: np.ndarray, a_hi: np.ndarray, b_lo: np.ndarray, b_hi: np.ndarray
) -> np.ndarray:
    n_b, dim = b_lo.shape
    chunk = max(1, _BRUTE_CHUNK // (n_b * dim))
    found = []
    for start in range(0, a_lo.shape[0], chunk):  # chunks of boxes, bounded memory
        stop = start + chunk
        hit = _overlapping(a_lo[start:stop, None], a_hi[start:stop, None], b_lo, b_hi)
        ia, ib = np.nonzero(hit)
        found.append(np.stack([ia + start, ib], axis=1))
    return np.ascontiguousarray(np.concatenate(found).astype(np.int64))


# ---------------------------------------------------------------------------- spatial hash


def _hash_pairs(
    a_lo: np.ndarray, a_hi: np.ndarray, b_lo: np.ndarray, b_hi: np.ndarray
) -> np.ndarray:
    n_a, n_b = a_lo.shape[0], b_lo.shape[0]
    origin = b_lo.min(axis=0)
    top = b_hi.max(axis=0)
    extent = (b_hi - b_lo).max(axis=1).mean()
    dim = max(1, int(np.count_nonzero(top > origin)))
    h = extent if extent > 0.0 else (top - origin).max() / n_b ** (1.0 / dim)
    h = h if h > 0.0 else 1.0
    a_cl, a_ch = np.empty((n_a, 3), np.int64), np.empty((n_a, 3), np.int64)
    b_cl, b_ch = np.empty((n_b, 3), np.int64), np.empty((n_b, 3), np.int64)
    a_active, b_active = np.empty(n_a, np.bool_), np.empty(n_b, np.bool_)
    while True:
        inv_h = 1.0 / h
        n_max = np.floor((top - origin) * inv_h)
        if n_max.max() > 2.0**40:
            h *= 2.0
            continue
        n_insert = hk._cell_ranges(b_lo, b_hi, origin, top, inv_h, n_max, b_cl, b_ch, b_active)
        n_visit = hk._cell_ranges(a_lo, a_hi, origin, top, inv_h, n_max, a_cl, a_ch, a_active)
        if n_insert + n_visit <= _CELL_BUDGET * (n_a + n_b) or not n_max.any():
            break
        h *= 2.0
    n_buckets = 1 << max(1, int(np.ceil(np.log2(2.0 * n_insert + 1.0))))
    logger.debug("spatial hash: cell %.3g m, %d buckets, %d insertions", h, n_buckets, n_insert)
    start, items = hk._build_table(b_cl, b_ch, n_buckets - 1)
    counts, ib = hk._query(
        a_lo, a_hi, a_cl, a_ch, a_active, b_lo, b_hi, b_cl, start, items, n_buckets - 1
    )
    ia = np.repeat(np.arange(n_a, dtype=np.int64), counts)
    return _sorted_unique(ia, ib, n_b)


# ---------------------------------------------------------------------------- python-fcl


def _fcl_groups(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Boxes grouped by centre: (G, 3) centres, (G, 3) enclosing half sides, (N,) group of box.

    The half sides are grown by a few ulps of ``|centre| + half`` so that fcl's ``centre - half``
    and ``centre + half`` enclose ``lo`` and ``hi`` despite rounding. Grouping makes the centre a
    unique key of the fcl object, which is all the collision callback can see of it.
    """
    centre = 0.5 * (lo + hi) + 0.0  # + 0.0 turns -0.0 into 0.0 (one key per value)
    half = np.maximum(centre - lo, hi - centre)
    half = half + 4.0 * np.finfo(np.float64).eps * (np.abs(centre) + half) + 1e-300
    centres, group = np.unique(centre, axis=0, return_inverse=True)
    group = group.reshape(-1)
    halves = np.zeros_like(centres)
    np.maximum.at(halves, group, half)
    return np.ascontiguousarray(centres), halves, group


def _fcl_manager(centres: np.ndarray, halves: np.ndarray) -> fcl.DynamicAABBTreeCollisionManager:
    objects = [
        fcl.CollisionObject(fcl.Box(*(2.0 * h)), fcl.Transform(c))
        for c, h in zip(centres, halves, strict=True)
    ]
    manager = fcl.DynamicAABBTreeCollisionManager()
    manager.registerObjects(objects)
    manager.setup()
    return manager


def _members(group: np.ndarray, n_groups: int) -> tuple[np.ndarray, np.ndarray]:
    """CSR of group members: (G + 1,) offsets and (N,) box indices ordered by group."""
    order = np.argsort(group, kind="stable")
    offsets = np.zeros(n_groups + 1, dtype=np.int64)
    np.cumsum(np.bincount(group, minlength=n_groups), out=offsets[1:])
    return offsets, order


def _fcl_pairs(
    a_lo: np.ndarray, a_hi: np.ndarray, b_lo: np.ndarray, b_hi: np.ndarray
) -> np.ndarray:
    a_c, a_h, a_group = _fcl_groups(a_lo, a_hi)
    b_c, b_h, b_group = _fcl_groups(b_lo, b_hi)
    key_a = {c.tobytes(): g for g, c in enumerate(a_c)}
    key_b = {c.tobytes(): g for g, c in enumerate(b_c)}
    found: list[tuple[int, int]] = []

    def collect(o1: fcl.CollisionObject, o2: fcl.CollisionObject, _data: object) -> bool:
        # manager_a.collide(manager_b) passes an object of a first, one of b second
        found.append((key_a[o1.getTranslation().tobytes()], key_b[o2.getTranslation().tobytes()]))
        return False  # keep traversing

    manager_a = _fcl_manager(a_c, a_h)
    manager_b = _fcl_manager(b_c, b_h)
    manager_a.collide(manager_b, None, collect)
    if not found:
        return np.empty((0, 2), dtype=np.int64)
    ga, gb = np.array(found, dtype=np.int64).T
    # expand each group pair to all member pairs (groups are singletons unless centres repeat)
    a_off, a_order = _members(a_group, a_c.shape[0])
    b_off, b_order = _members(b_group, b_c.shape[0])
    na = a_off[ga + 1] - a_off[ga]
    nb = b_off[gb + 1] - b_off[gb]
    size = na * nb
    which = np.repeat(np.arange(ga.size), size)
    local = np.arange(size.sum()) - np.repeat(np.cumsum(size) - size, size)
    ia = a_order[a_off[ga][which] + local // nb[which]]
    ib = b_order[b_off[gb][which] + local % nb[which]]
    keep = _overlapping(a_lo[ia], a_hi[ia], b_lo[ib], b_hi[ib])
    return _sorted_unique(ia[keep], ib[keep], b_lo.shape[0])
