"""Uniform MPM background grid and quadratic B-spline particle stencils (paper section 3.2).

Grid node ``i`` has integer coordinates ``ijk`` (d,) and position ``origin + dx * ijk``. The grid
has no bounds: the *active* nodes of a step are those touched by the particle stencils of that
step, so the grid grows and shrinks as particles move.

Quadratic B-spline kernel. On each axis, with ``xi = (x - origin) / dx`` (grid units), the base
node is ``floor(xi - 0.5)`` and ``fx = xi - base`` lies in [0.5, 1.5); the nodes base, base+1,
base+2 get the weights ``0.5 (1.5 - fx)^2``, ``0.75 - (fx - 1)^2``, ``0.5 (fx - 0.5)^2`` and the
derivatives ``-(1.5 - fx) / dx``, ``-2 (fx - 1) / dx``, ``(fx - 0.5) / dx``. In d dimensions the
weight is the tensor product ``w_ip = prod_a N_a`` and ``d w_ip / d x_a = N'_a prod_{b != a} N_b``.
The kernel reproduces constants and linear functions exactly: ``sum_i w_ip = 1``,
``sum_i grad w_ip = 0``, ``sum_i w_ip x_i = x_p`` and ``sum_i x_i grad w_ip^T = I``.

Choices made here:

- Stencil ordering: entry ``k`` of a particle's stencil is the node ``base + offsets[k]`` where
  ``offsets = stencil_offsets(d)`` lists ``{0, 1, 2}^d`` lexicographically, first axis slowest
  (2D: k = 3 a + b for the offset (a, b); 3D: k = 9 a + 3 b + c). The centre node is
  ``k = (3**d - 1) / 2``.
- Active nodes are unique and sorted lexicographically by ``ijk`` (first axis slowest).
- Zero-weight entries: a particle exactly on a cell-centre plane (``fx = 0.5``, e.g. particles
  sampled at one particle per cell) has weight *and* gradient exactly 0 for the nodes
  ``base + 2`` on that axis. By default (``drop_zero_weights=True``) such entries point at the
  particle's centre node instead (still with weight 0 and gradient 0), so every active node gets
  a positive weight from some particle: no zero-mass grid DOF appears in an implicit solve.
  Sums over the stencil are unchanged; a stencil row may then repeat a node index.
- Compaction: node coordinates are linearised inside the bounding box of the stencils and made
  unique with a dense mark array (small boxes) or ``np.unique`` (large or sparse boxes).
"""

from __future__ import annotations

import itertools
import logging
import math
from dataclasses import dataclass, field

import numpy as np

from geometry._checks import points, positive, vector
from geometry._grid_kernels import _stencils

__all__ = [
    "Grid",
    "ParticleStencils",
    "grid_cell_counts",
    "particle_stencils",
    "particles_per_cell",
    "stencil_offsets",
]

logger = logging.getLogger(__name__)

# A bounding box of at most this many nodes is compacted with a dense mark array.
_DENSE_LIMIT = 1 << 22


@dataclass(frozen=True, kw_only=True)
class Grid:
    """Uniform unbounded background grid.

    Attributes:
        dx: node spacing in metres, finite and > 0.
        origin: (d,) position of the node ``ijk = 0`` in metres, d = 2 or 3.
    """

    dx: float
    origin: tuple[float, ...]

    def __post_init__(self) -> None:
        object.__setattr__(self, "dx", positive("Grid.dx", self.dx))
        origin = vector("Grid.origin", self.origin)
        object.__setattr__(self, "origin", tuple(float(v) for v in origin))

    @classmethod
    def make(cls, dx: float, dim: int, origin: tuple[float, ...] | None = None) -> Grid:
        """Grid of spacing ``dx`` (m) in ``dim`` = 2 or 3 dimensions; origin defaults to zeros."""
        if dim not in (2, 3):
            raise ValueError(f"Grid dim must be 2 or 3, got {dim!r}")
        if origin is None:
            origin = (0.0,) * dim
        if len(origin) != dim:
            raise ValueError(f"Grid.origin must have {dim} entries, got {origin!r}")
        return cls(dx=dx, origin=tuple(origin))

    @property
    def dim(self) -> int:
        """Spatial dimension d."""
        return len(self.origin)

    def node_positions(self, ijk: np.ndarray) -> np.ndarray:
        """Positions ``origin + dx * ijk`` (G, d) in metres of the nodes ``ijk`` (G, d) int."""
        arr = np.asarray(ijk)
        if arr.ndim != 2 or arr.shape[1] != self.dim or arr.dtype.kind not in "iu":
            raise ValueError(
                f"ijk must be an integer array of shape (G, {self.dim}), "
                f"got {arr.dtype} {arr.shape}"
            )
        return np.ascontiguousarray(np.asarray(self.origin) + self.dx * arr.astype(np.float64))

    def cells_of(self, x: np.ndarray) -> np.ndarray:
        """Integer coordinates (P, d) int64 of the cells containing the points x (P, d) in m.

        Cell ``c`` spans ``[origin + c dx, origin + (c + 1) dx)`` on each axis.
        """
        pts = points("x", x, self.dim, "P")
        return np.floor((pts - np.asarray(self.origin)) / self.dx).astype(np.int64)


@dataclass(frozen=True, eq=False)
class ParticleStencils:
    """Quadratic B-spline stencils of P particles on the active nodes of a :class:`Grid`.

    Attributes:
        nodes: (P, K) int64, index into ``active_ijk`` of stencil entry k of particle p;
            K = 3**d, entry order of :func:`stencil_offsets` (see the module docstring for the
            zero-weight redirection).
        weights: (P, K) float64 ``w_ip``, dimensionless, each row sums to 1.
        grads: (P, K, d) float64 ``grad w_ip`` in 1/m.
        active_ijk: (G, d) int64 integer coordinates of the active nodes, unique, sorted
            lexicographically.
        active_x: (G, d) float64 positions of the active nodes in m.
    """

    nodes: np.ndarray
    weights: np.ndarray
    grads: np.ndarray
    active_ijk: np.ndarray
    active_x: np.ndarray
    dim: int = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "dim", int(self.active_ijk.shape[1]))

    @property
    def n_particles(self) -> int:
        """Number of particles P."""
        return int(self.nodes.shape[0])

    @property
    def n_nodes(self) -> int:
        """Number of active grid nodes G."""
        return int(self.active_ijk.shape[0])


def stencil_offsets(dim: int) -> np.ndarray:
    """Node offsets (3**dim, dim) int64 from the base node: ``{0,1,2}^dim``, first axis slowest."""
    if dim not in (2, 3):
        raise ValueError(f"dim must be 2 or 3, got {dim!r}")
    return np.array(list(itertools.product(range(3), repeat=dim)), dtype=np.int64)


def _compact(lin: np.ndarray, box_size: int) -> tuple[np.ndarray, np.ndarray]:
    """Unique sorted values of ``lin`` (any shape, in [0, box_size)) and the inverse map."""
    if box_size <= _DENSE_LIMIT and box_size <= 8 * lin.size:
        mark = np.zeros(box_size, dtype=bool)
        mark[lin.ravel()] = True
        unique = np.flatnonzero(mark)
        remap = np.empty(box_size, dtype=np.int64)
        remap[unique] = np.arange(unique.size, dtype=np.int64)
        return unique, remap[lin]
    unique, inverse = np.unique(lin.ravel(), return_inverse=True)
    return unique, inverse.reshape(lin.shape).astype(np.int64)


def particle_stencils(
    grid: Grid, x: np.ndarray, *, drop_zero_weights: bool = True
) -> ParticleStencils:
    """Quadratic B-spline weights and gradients of particles x (P, d) in m, and active nodes.

    Args:
        grid: the background grid (its dimension must match x).
        x: (P, d) particle positions in metres.
        drop_zero_weights: redirect stencil entries of exactly zero weight and gradient to the
            particle's centre node so that no active node has only zero weights (see module).

    Returns:
        :class:`ParticleStencils` with nodes (P, K), weights (P, K), grads (P, K, d) in 1/m,
        active_ijk (G, d) and active_x (G, d) in m.
    """
    dim = grid.dim
    pts = points("x", x, dim, "P")
    offsets = stencil_offsets(dim)
    n_particles, n_stencil = pts.shape[0], offsets.shape[0]
    base = np.empty((n_particles, dim), dtype=np.int64)
    weights = np.empty((n_particles, n_stencil))
    grads = np.empty((n_particles, n_stencil, dim))
    if n_particles == 0:
        empty = np.empty((0, dim))
        return ParticleStencils(
            nodes=np.empty((0, n_stencil), dtype=np.int64),
            weights=weights,
            grads=grads,
            active_ijk=empty.astype(np.int64),
            active_x=empty,
        )
    xi = (pts - np.asarray(grid.origin)) / grid.dx
    if np.abs(xi).max() > 2.0**52:
        raise ValueError("x is too far from Grid.origin for the grid spacing dx (> 2^52 cells)")
    _stencils(xi, offsets, 1.0 / grid.dx, base, weights, grads)

    # Linearise base + offset inside the stencils' bounding box, first axis slowest, so that
    # the order of the linear index is the lexicographic order of ijk.
    lo = base.min(axis=0)
    extent = base.max(axis=0) - lo + 3
    box_size = math.prod(extent.tolist())
    if box_size >= 2**62:
        raise ValueError("particles are spread over more than 2^62 grid nodes: dx too small?")
    stride = np.ones(dim, dtype=np.int64)
    for a in range(dim - 2, -1, -1):
        stride[a] = stride[a + 1] * extent[a + 1]
    lin = ((base - lo) @ stride)[:, None] + (offsets @ stride)[None, :]
    if drop_zero_weights:
        zero = weights == 0.0
        if zero.any():
            zero[zero] = np.all(grads[zero] == 0.0, axis=1)
            centre = lin[:, (n_stencil - 1) // 2]
            lin = np.where(zero, centre[:, None], lin)
    unique, nodes = _compact(lin, box_size)
    active_ijk = np.stack(np.unravel_index(unique, extent), axis=1) + lo
    return ParticleStencils(
        nodes=np.ascontiguousarray(nodes),
        weights=weights,
        grads=grads,
        active_ijk=active_ijk,
        active_x=grid.node_positions(active_ijk),
    )


def grid_cell_counts(grid: Grid, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Occupied cells and their particle counts.

    Args:
        grid: the background grid.
        x: (P, d) particle positions in metres.

    Returns:
        ``(cell_ijk, counts)``: (C, d) int64 integer coordinates of the occupied cells (sorted
        lexicographically) and (C,) int64 number of particles in each.
    """
    cells = grid.cells_of(x)
    if cells.shape[0] == 0:
        return cells, np.zeros(0, dtype=np.int64)
    cell_ijk, counts = np.unique(cells, axis=0, return_counts=True)
    return np.ascontiguousarray(cell_ijk), counts.astype(np.int64)


def particles_per_cell(grid: Grid, x: np.ndarray, volume: np.ndarray | None = None) -> float:
    """Particle density of a body relative to the grid: particles per cell.

    Args:
        grid: the background grid.
        x: (P, d) particle positions in metres.
        volume: optional (P,) particle volumes (m^2 in 2D, m^3 in 3D).

    Returns:
        With ``volume``: ``P dx^d / sum(volume)``, the number of particles per cell of the
        body's volume. Below 1 the grid is finer than the particle spacing and cells inside the
        body go empty (numerical fracture); with sampling spacing ``dx_s / k`` it equals
        ``(k dx / dx_s)^d``. Without ``volume``: the mean count over occupied cells, which is at
        least 1 by construction and measures how many particles share a cell. 0.0 for P = 0.
    """
    pts = points("x", x, grid.dim, "P")
    if pts.shape[0] == 0:
        return 0.0
    if volume is None:
        return float(grid_cell_counts(grid, pts)[1].mean())
    vol = np.asarray(volume, dtype=np.float64)
    if vol.shape != (pts.shape[0],) or not np.all(np.isfinite(vol)) or np.any(vol <= 0.0):
        raise ValueError(f"volume must be (P,) = ({pts.shape[0]},) finite positive values")
    ppc = pts.shape[0] * grid.dx**grid.dim / float(vol.sum())
    if ppc < 1.0:
        logger.debug("%.3g particles per cell: grid dx=%g finer than the particles", ppc, grid.dx)
    return ppc
