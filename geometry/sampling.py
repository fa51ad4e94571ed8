"""MPM particle sampling: regular sub-cell centres inside boxes, implicit shapes, meshes.

Lattice. ``ppc`` (particles per cell) must be ``k**d``: 1, 4, 9, 16, ... in 2D and 1, 8, 27,
64, ... in 3D. Each grid cell ``c`` (spanning ``[origin + c dx, origin + (c + 1) dx)`` on each
axis, origin zeros unless given) holds ``k`` particles per axis at the sub-cell centres
``origin + c dx + (j + 0.5) dx / k``, j = 0..k-1, i.e. a lattice of spacing ``s = dx / k``
aligned with the MPM grid. Every particle carries the volume ``s^d`` (m^2 in 2D per unit
thickness, m^3 in 3D), so the total volume is exact for a box whose faces lie on the sub-cell
lattice and otherwise within one sub-layer of the boundary. A sub-centre ``y`` is kept when
``lower <= y < upper`` and the shape contains it; particles are ordered lexicographically by
their lattice index (first axis slowest).

Jitter (optional): each candidate moves by a uniform offset in ``[-jitter s / 2, jitter s / 2)``
per axis *before* the inside test, so jittered particles are still inside the shape and stay in
their own sub-cell for ``jitter <= 1``. The default generator is ``np.random.default_rng(0)``:
sampling is reproducible unless a generator (or seed) is passed.

Point location in meshes (:func:`locate_points`) is the barycentric test of
:func:`geometry.inside.simplex_depth` with a uniform bucketing of the cells (see
:mod:`geometry._sampling_kernels`), O(points + cells).
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np

from geometry._checks import positive
from geometry._checks import vector as _vector
from geometry._sampling_kernels import _bin_cells, _locate
from geometry.levelset import LevelSet
from geometry.mesh import TetMesh, TriMesh

__all__ = [
    "locate_points",
    "points_in_mesh",
    "sample_box",
    "sample_inside",
    "sample_levelset",
    "sample_mesh",
]

# Refuse to build more candidate points than this (memory guard against a tiny dx).
_MAX_CANDIDATES = 50_000_000
_BARY_TOL = 1e-12


def _per_axis(ppc: object, dim: int) -> int:
    """k with ``k**dim == ppc``, else ValueError naming ppc and the valid values."""
    valid = [k**dim for k in range(1, 5)]
    if isinstance(ppc, (bool, np.bool_)) or not isinstance(ppc, (int, np.integer)) or ppc < 1:
        raise ValueError(f"ppc must be a positive integer k**{dim} ({valid}, ...), got {ppc!r}")
    k = int(round(float(ppc) ** (1.0 / dim)))
    for cand in (k - 1, k, k + 1):
        if cand >= 1 and cand**dim == ppc:
            return cand
    raise ValueError(f"ppc must be k**{dim} in {dim}D ({valid}, ...), got {ppc}")


def _lattice(
    lower: object,
    upper: object,
    dx: object,
    ppc: object,
    jitter: float,
    rng: np.random.Generator | int | None,
    origin: object,
) -> tuple[np.ndarray, float]:
    """Candidate sub-cell centres (n, d) in ``[lower, upper)`` (jittered) and the spacing s."""
    lo = _vector("lower", lower)
    dim = lo.shape[0]
    hi = _vector("upper", upper, dim)
    if not np.all(hi > lo):
        raise ValueError(f"upper must exceed lower componentwise, got lower={lo}, upper={hi}")
    h = positive("dx", dx)
    k = _per_axis(ppc, dim)
    if not (np.isfinite(jitter) and 0.0 <= jitter <= 1.0):
        raise ValueError(f"jitter must be in [0, 1] (fraction of the sub-spacing), got {jitter}")
    org = np.zeros(dim) if origin is None else _vector("origin", origin, dim)
    s = h / k
    # Sub-centre m sits at origin + (m + 1/2) s; keep lower <= y < upper.
    m_lo = np.ceil((lo - org) / s - 0.5).astype(np.int64)
    m_hi = np.ceil((hi - org) / s - 0.5).astype(np.int64)
    counts = np.maximum(m_hi - m_lo, 0)
    total = int(np.prod(counts.astype(np.float64)))
    if total > _MAX_CANDIDATES:
        raise ValueError(
            f"dx={h} with ppc={ppc} gives {total} candidate particles in the box: dx too small?"
        )
    axes = [org[a] + (np.arange(m_lo[a], m_hi[a]) + 0.5) * s for a in range(dim)]
    mesh = np.meshgrid(*axes, indexing="ij")
    pts = np.ascontiguousarray(np.stack([g.ravel() for g in mesh], axis=1))
    if jitter > 0.0 and pts.shape[0]:
        gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng or 0)
        pts += (gen.random(pts.shape) - 0.5) * (jitter * s)
    return pts, s


def _finish(x: np.ndarray, s: float) -> tuple[np.ndarray, np.ndarray]:
    if x.shape[0] == 0:
        raise ValueError("no particle inside: dx too coarse for the shape?")
    return np.ascontiguousarray(x), np.full(x.shape[0], s ** x.shape[1])


def sample_inside(
    inside: Callable[[np.ndarray], np.ndarray],
    lower: tuple[float, ...],
    upper: tuple[float, ...],
    dx: float,
    ppc: int,
    *,
    jitter: float = 0.0,
    rng: np.random.Generator | int | None = None,
    origin: tuple[float, ...] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Particles at the sub-cell centres in the box ``[lower, upper)`` where ``inside`` holds.

    Args:
        inside: vectorised predicate, points (n, d) in m -> (n,) bool.
        lower, upper: (d,) corners of the box searched, m (d = 2 or 3).
        dx: grid cell size in m (> 0).
        ppc: particles per cell, ``k**d``.
        jitter: random offset as a fraction of the sub-spacing ``dx / k``, in [0, 1].
        rng: generator or seed for the jitter (default: seed 0).
        origin: (d,) grid origin the lattice is aligned to, m (default zeros).

    Returns:
        ``(x, volume)``: positions (P, d) in m and volumes (P,) in m^d, each ``(dx / k)^d``.
    """
    pts, s = _lattice(lower, upper, dx, ppc, jitter, rng, origin)
    keep = np.asarray(inside(pts))
    if keep.shape != (pts.shape[0],) or keep.dtype != np.bool_:
        raise ValueError(
            f"inside must return a (n,) bool array for (n, d) points, got {keep.dtype} "
            f"{keep.shape} for n = {pts.shape[0]}"
        )
    return _finish(pts[keep], s)


def sample_box(
    lower: tuple[float, ...],
    upper: tuple[float, ...],
    dx: float,
    ppc: int,
    *,
    jitter: float = 0.0,
    rng: np.random.Generator | int | None = None,
    origin: tuple[float, ...] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Particles filling the box ``[lower, upper)`` (m); see :func:`sample_inside` for the rest.

    For a box whose faces lie on the grid (multiples of dx from the origin) the count is
    exactly ``ppc`` per cell and the volumes sum to the box volume.
    """
    pts, s = _lattice(lower, upper, dx, ppc, jitter, rng, origin)
    return _finish(pts, s)


def sample_levelset(
    levelset: LevelSet,
    lower: tuple[float, ...],
    upper: tuple[float, ...],
    dx: float,
    ppc: int,
    *,
    jitter: float = 0.0,
    rng: np.random.Generator | int | None = None,
    origin: tuple[float, ...] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Particles where ``levelset.value(x) < 0`` inside the box ``[lower, upper)``.

    With the obstacle convention of :mod:`geometry.levelset` this samples the solid:
    ``Disk(...)`` gives a disk of particles, ``Inverted(...)`` the complement.
    See :func:`sample_inside` for the arguments and the returned ``(x (P, d), volume (P,))``.
    """
    if not callable(getattr(levelset, "value", None)):
        raise ValueError("levelset must have a value(x) method")

    def inside(y: np.ndarray) -> np.ndarray:
        return np.asarray(levelset.value(y)) < 0.0

    return sample_inside(inside, lower, upper, dx, ppc, jitter=jitter, rng=rng, origin=origin)


def locate_points(mesh: TriMesh | TetMesh, x: np.ndarray) -> np.ndarray:
    """Index of a mesh cell containing each point, -1 outside the mesh.

    Args:
        mesh: triangle (2D) or tetrahedron (3D) mesh, points in m.
        x: (P, d) query points in m.

    Returns:
        (P,) int64 cell indices; points on a shared facet get the lowest-numbered cell of
        their bucket that contains them (barycentric tolerance 1e-12). Degenerate cells are
        skipped.
    """
    if not isinstance(mesh, (TriMesh, TetMesh)):
        raise ValueError(f"mesh must be a TriMesh or TetMesh, got {type(mesh).__name__}")
    dim = mesh.dim
    pts = np.ascontiguousarray(x, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != dim:
        raise ValueError(f"x must have shape (P, {dim}) for a {dim}D mesh, got {pts.shape}")
    verts = np.ascontiguousarray(mesh.points[mesh.cells])  # (m, d+1, d)
    dm = verts[:, 1:] - verts[:, :1]  # rows are edges
    cell_lo, cell_hi = verts.min(axis=1), verts.max(axis=1)
    size = float((cell_hi - cell_lo).max(axis=1).mean())
    valid = np.abs(np.linalg.det(dm)) > 1e-12 * size**dim

    # Bucketing grid over the mesh's bounding box: bins about one cell wide, at most ~4 m bins.
    lo, hi = mesh.points.min(axis=0), mesh.points.max(axis=0)
    span = np.maximum(hi - lo, 1e-300)
    bin_size = max(size, float(np.prod(span) / (4.0 * mesh.n_cells + 64)) ** (1.0 / dim))
    n_bins = np.maximum(np.ceil(span / bin_size), 1).astype(np.int64)
    pad = 1e-9 * size  # so that points on a cell's bounding box see the cell
    lo_bin = np.floor((cell_lo - pad - lo) / bin_size).astype(np.int64)
    hi_bin = np.floor((cell_hi + pad - lo) / bin_size).astype(np.int64)
    start, items = _bin_cells(
        np.clip(lo_bin, 0, n_bins - 1), np.clip(hi_bin, 0, n_bins - 1), n_bins
    )
    out = np.empty(pts.shape[0], dtype=np.int64)
    _locate(pts, lo, 1.0 / bin_size, n_bins, start, items, verts, valid, _BARY_TOL, out)
    return out


def points_in_mesh(mesh: TriMesh | TetMesh, x: np.ndarray) -> np.ndarray:
    """(P,) bool: whether each point of x (P, d) in m lies in a cell of the mesh.

    Inclusive: a point on the mesh's boundary (within a barycentric 1e-12) is inside
    (:mod:`geometry.inside`'s convention).
    """
    return locate_points(mesh, x) >= 0


def sample_mesh(
    mesh: TriMesh | TetMesh,
    dx: float,
    ppc: int,
    *,
    jitter: float = 0.0,
    rng: np.random.Generator | int | None = None,
    origin: tuple[float, ...] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Particles at the sub-cell centres inside a triangle (2D) or tetrahedron (3D) mesh.

    Args:
        mesh: the body, points in m.
        dx, ppc, jitter, rng, origin: as in :func:`sample_inside`.

    Returns:
        ``(x, volume)``: positions (P, d) in m and volumes (P,) in m^d, each ``(dx / k)^d``.
    """
    if not isinstance(mesh, (TriMesh, TetMesh)):
        raise ValueError(f"mesh must be a TriMesh or TetMesh, got {type(mesh).__name__}")
    lo, hi = tuple(mesh.points.min(axis=0)), tuple(mesh.points.max(axis=0))
    inside = functools.partial(points_in_mesh, mesh)
    return sample_inside(inside, lo, hi, dx, ppc, jitter=jitter, rng=rng, origin=origin)
