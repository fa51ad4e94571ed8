"""Continuous collision detection (CCD) of linearly moving contact primitives.

Vertices move on straight lines, ``x(t) = x + t dx`` for ``t`` in ``[0, t_max]`` (positions
``x`` in m, displacements ``dx`` in m per unit ``t``; for a line search ``dx`` is the search
direction and ``t`` the step length). Each function returns, per pair, a time of impact
``toi (n,)``:

- Conservative: the pair's exact distance (exact arithmetic on the float inputs) stays above
  ``min_distance`` on ``[0, toi]``, and at ``toi`` it is still at least ``min_distance +
  tolerance * g0`` with ``g0`` the certified starting gap (``d(0) - min_distance`` less its
  rounding bound). The true first time of impact is never earlier than ``toi`` (false positives,
  never false negatives: the reported time may be earlier than the true one, never later).
- ``toi = t_max`` when the pair is certified not to come within ``min_distance`` on ``[0,
  t_max]`` (no ``inf``: the result can be used as a step bound directly). A pass closer than
  ``tolerance * g0`` may report less than ``t_max`` (a false positive by design).
- ``toi = 0`` when the pair starts at or below ``min_distance`` *or within the rounding of the
  distance test* (about ``32 u`` times the pair's extent, ``u = 2^-53``; more for slivers and
  near-parallel edges, see :mod:`geometry._ccd_kernels`). Below that level the computed
  distance is noise: stepping on it let a point starting 1.3e-17 m above a segment pass through
  it (issue 44, defect 3).

Method: additive CCD (ACCD, Li, Kaufman & Jiang 2021) on certified lower bounds of the distance,
plus a separating-plane step and, for 2D point-edge pairs, a line step (both this module's
choices; the steps and the issue 44 figures are in :mod:`geometry._ccd_kernels`). ACCD steps by
``(1 - tolerance) * gap / l_p`` (``l_p`` bounds the relative speed) and stops once the gap has
shrunk below ``tolerance`` times the initial gap, so with the default ``tolerance = 0.1`` a
head-on approach reports roughly 90 % of the true time. Motion parallel to a segment, face or
edge, and in 2D an edge turning near a point, finish in one step whatever the gap. In 3D, motion
with a turning separating direction (a triangle or edge tilting close to a point or edge) still
takes about ``l_p / gap`` steps; ``max_iterations`` caps them and returns the current, still
safe, time (with a logged warning).

A line search takes ``alpha0 = min(1, 0.9 * earliest_impact(...))`` or similar (the caller
decides the safety factor; this module reports the conservative time itself).
"""

from __future__ import annotations

import logging

import numpy as np

from geometry._ccd_kernels import _accd
from geometry._checks import indices
from geometry._distance_kernels import KIND_EE, KIND_PE, KIND_PT
from geometry.distance import _NAMES, _stack_pairs

__all__ = ["earliest_impact", "edge_edge_ccd", "point_edge_ccd", "point_triangle_ccd"]

logger = logging.getLogger(__name__)

_N_SIDE_A = {KIND_PE: 1, KIND_PT: 1, KIND_EE: 2}


def _check_options(
    t_max: float, min_distance: float, tolerance: float, max_iterations: int
) -> None:
    if not (np.isfinite(t_max) and t_max > 0.0):
        raise ValueError(f"t_max must be finite and > 0, got {t_max}")
    if not (np.isfinite(min_distance) and min_distance >= 0.0):
        raise ValueError(f"min_distance must be finite and >= 0, got {min_distance}")
    if not (0.0 < tolerance < 1.0):
        raise ValueError(f"tolerance must be in (0, 1), got {tolerance}")
    if int(max_iterations) != max_iterations or max_iterations < 1:
        raise ValueError(f"max_iterations must be an integer >= 1, got {max_iterations}")


def _ccd(
    kind: int,
    arrays: tuple[np.ndarray, ...],
    t_max: float,
    min_distance: float,
    tolerance: float,
    max_iterations: int,
) -> np.ndarray:
    _check_options(t_max, min_distance, tolerance, max_iterations)
    names = _NAMES[kind]
    k = len(names)
    V = _stack_pairs(kind, arrays[:k], names)
    for name, d in zip(names, arrays[k:], strict=True):
        if np.shape(d) != V.shape[::2]:
            raise ValueError(
                f"d{name} must have shape {V.shape[::2]} like {name}, got {np.shape(d)}"
            )
    dV = _stack_pairs(kind, arrays[k:], tuple("d" + name for name in names))
    eta = float(tolerance)
    toi, n_iter = _accd(
        V, dV, kind, _N_SIDE_A[kind], float(t_max), float(min_distance), eta, int(max_iterations)
    )
    capped = np.flatnonzero((n_iter >= max_iterations) & (toi < t_max))
    if capped.size:
        logger.warning(
            "CCD: %d pair(s) hit max_iterations=%d (grazing motion); returning their current "
            "conservative times, e.g. pair %d at t=%.3g",
            capped.size,
            max_iterations,
            capped[0],
            toi[capped[0]],
        )
    return toi


def point_edge_ccd(
    p: np.ndarray,
    e0: np.ndarray,
    e1: np.ndarray,
    dp: np.ndarray,
    de0: np.ndarray,
    de1: np.ndarray,
    *,
    t_max: float = 1.0,
    min_distance: float = 0.0,
    tolerance: float = 0.1,
    max_iterations: int = 1_000_000,
) -> np.ndarray:
    """Conservative times of impact (n,) of points p moving by dp against segments e0-e1.

    Arguments are (n, d) arrays in m, d = 2 (the BFEMP particle-segment pairs) or 3. See the
    module docstring for the meaning of the result and of ``t_max`` (dimensionless upper time),
    ``min_distance`` (m), ``tolerance`` (final gap fraction, in (0, 1)) and ``max_iterations``.
    """
    arrays = (p, e0, e1, dp, de0, de1)
    return _ccd(KIND_PE, arrays, t_max, min_distance, tolerance, max_iterations)


def point_triangle_ccd(
    p: np.ndarray,
    t0: np.ndarray,
    t1: np.ndarray,
    t2: np.ndarray,
    dp: np.ndarray,
    dt0: np.ndarray,
    dt1: np.ndarray,
    dt2: np.ndarray,
    *,
    t_max: float = 1.0,
    min_distance: float = 0.0,
    tolerance: float = 0.1,
    max_iterations: int = 1_000_000,
) -> np.ndarray:
    """Conservative times of impact (n,) of points p moving by dp against triangles t0t1t2.

    Arguments are (n, 3) arrays in m; options as in :func:`point_edge_ccd`.
    """
    arrays = (p, t0, t1, t2, dp, dt0, dt1, dt2)
    return _ccd(KIND_PT, arrays, t_max, min_distance, tolerance, max_iterations)


def edge_edge_ccd(
    ea0: np.ndarray,
    ea1: np.ndarray,
    eb0: np.ndarray,
    eb1: np.ndarray,
    dea0: np.ndarray,
    dea1: np.ndarray,
    deb0: np.ndarray,
    deb1: np.ndarray,
    *,
    t_max: float = 1.0,
    min_distance: float = 0.0,
    tolerance: float = 0.1,
    max_iterations: int = 1_000_000,
) -> np.ndarray:
    """Conservative times of impact (n,) of segments ea0-ea1 and eb0-eb1 moving by dea*, deb*.

    Arguments are (n, 3) arrays in m; options as in :func:`point_edge_ccd`.
    """
    arrays = (ea0, ea1, eb0, eb1, dea0, dea1, deb0, deb1)
    return _ccd(KIND_EE, arrays, t_max, min_distance, tolerance, max_iterations)


def earliest_impact(
    x: np.ndarray,
    dx: np.ndarray,
    *,
    point_edge: np.ndarray | None = None,
    point_triangle: np.ndarray | None = None,
    edge_edge: np.ndarray | None = None,
    t_max: float = 1.0,
    min_distance: float = 0.0,
    tolerance: float = 0.1,
    max_iterations: int = 1_000_000,
) -> float:
    """Smallest conservative time of impact over candidate pairs of vertices ``x + t dx``.

    ``x``, ``dx`` (n_vertices, d) in m; ``point_edge`` (m, 3) rows ``(p, e0, e1)``,
    ``point_triangle`` (m, 4) rows ``(p, t0, t1, t2)``, ``edge_edge`` (m, 4) rows
    ``(ea0, ea1, eb0, eb1)``, all int vertex indices (point-triangle and edge-edge need d = 3).
    Returns ``t_max`` when there is no pair or no impact; options as in :func:`point_edge_ccd`.
    """
    x = np.asarray(x, dtype=np.float64)
    dx = np.asarray(dx, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] not in (2, 3):
        raise ValueError(f"x must have shape (n_vertices, 2 or 3), got {x.shape}")
    if dx.shape != x.shape:
        raise ValueError(f"dx must have shape {x.shape} like x, got {dx.shape}")
    _check_options(t_max, min_distance, tolerance, max_iterations)
    options = dict(
        t_max=t_max, min_distance=min_distance, tolerance=tolerance, max_iterations=max_iterations
    )
    toi = float(t_max)
    groups = (
        ("point_edge", point_edge, 3, point_edge_ccd),
        ("point_triangle", point_triangle, 4, point_triangle_ccd),
        ("edge_edge", edge_edge, 4, edge_edge_ccd),
    )
    for name, pairs, width, ccd in groups:
        if pairs is None:
            continue
        idx = indices(name, pairs, x.shape[0], width)
        if width == 4 and x.shape[1] != 3:
            raise ValueError(f"{name} pairs need 3D positions, x has shape {x.shape}")
        if idx.shape[0] == 0:
            continue
        cols = [x[idx[:, j]] for j in range(width)] + [dx[idx[:, j]] for j in range(width)]
        toi = min(toi, float(ccd(*cols, **options).min()))
    return toi
