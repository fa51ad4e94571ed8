"""The pointwise log-barrier of BFEMP eq. 27 and the contact integration weights of section 4.2.

Barrier (BFEMP eq. 27, after IPC). With ``r = d / dhat``::

    b(d)   = -kappa (r - 1)^2 ln r                                       0 < d < dhat
    b'(d)  = -kappa / dhat   [2 (r - 1) ln r + (r - 1)^2 / r]
    b''(d) = -kappa / dhat^2 [2 ln r + 4 (r - 1) / r - (r - 1)^2 / r^2]

and ``b = b' = b'' = 0`` for ``d >= dhat``. All three vanish as ``r -> 1``, so the clamped barrier
is C2 at ``dhat``; ``b -> +inf`` as ``d -> 0``. For ``d <= 0`` (touching or crossed, which the CCD
line search never lets happen) the limits are returned: ``b = +inf``, ``b' = -inf``,
``b'' = +inf``. NaN distances propagate as NaN so that the Newton solver reports a non-finite
energy rather than this kernel raising mid-iteration.

``kappa`` is in Pa: ``b`` is an energy density per unit boundary measure (BFEMP eq. 26), the weight
``omega`` of each collision point carries the measure (m in 2D per unit thickness, m^2 in 3D).

Weights (section 4.2): an MPM particle of volume ``V`` gets the largest cross-section of a disk
(2D: its diameter ``2 sqrt(V / pi)``) or a sphere (3D: ``pi (3 V / (4 pi))^(2/3)``) of that
volume. An FEM boundary node gets its lumped share of the boundary measure: half the length of
each incident boundary edge (2D) or a third of the area of each incident boundary triangle (3D).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "barrier",
    "barrier_derivative",
    "barrier_second_derivative",
    "boundary_vertex_weights",
    "particle_contact_weight",
]


def _check_parameters(dhat: float, kappa: float) -> tuple[float, float]:
    """Validate the scalar barrier parameters (positive, finite) and return them as floats."""
    for name, value in (("dhat", dhat), ("kappa", kappa)):
        if not (isinstance(value, int | float | np.floating | np.integer)) or isinstance(
            value, bool
        ):
            raise ValueError(f"{name} must be a number, got {value!r}")
        if not (math.isfinite(value) and value > 0.0):
            raise ValueError(f"{name} must be positive and finite, got {value!r}")
    return float(dhat), float(kappa)


def _split(d: np.ndarray, dhat: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``d`` as float64, the ratio ``r = d / dhat`` on the active set, and the masks
    (active ``0 < d < dhat``, crossed ``d <= 0``)."""
    d = np.asarray(d, dtype=np.float64)
    active = (d > 0.0) & (d < dhat)
    crossed = d <= 0.0
    r = np.where(active, d / dhat, 1.0)
    return d, r, active, crossed


def barrier(d: np.ndarray, dhat: float, kappa: float) -> np.ndarray:
    """Barrier energy density b(d) (n,) in Pa of distances ``d`` (n,) in m (BFEMP eq. 27).

    ``dhat`` is the activation distance in m and ``kappa`` the stiffness in Pa. Zero for
    ``d >= dhat``, positive and decreasing on ``(0, dhat)``, ``+inf`` for ``d <= 0``.
    """
    dhat, kappa = _check_parameters(dhat, kappa)
    d, r, active, crossed = _split(d, dhat)
    out = np.where(active, -kappa * (r - 1.0) ** 2 * np.log(r), 0.0)
    out[crossed] = np.inf
    return np.where(np.isnan(d), np.nan, out)


def barrier_derivative(d: np.ndarray, dhat: float, kappa: float) -> np.ndarray:
    """db/dd (n,) in Pa/m of distances ``d`` (n,) in m; 0 for ``d >= dhat``, -inf for d <= 0."""
    dhat, kappa = _check_parameters(dhat, kappa)
    d, r, active, crossed = _split(d, dhat)
    rm1 = r - 1.0
    out = np.where(active, -kappa / dhat * (2.0 * rm1 * np.log(r) + rm1 * rm1 / r), 0.0)
    out[crossed] = -np.inf
    return np.where(np.isnan(d), np.nan, out)


def barrier_second_derivative(d: np.ndarray, dhat: float, kappa: float) -> np.ndarray:
    """d^2b/dd^2 (n,) in Pa/m^2 of distances ``d`` (n,) in m; 0 for d >= dhat, +inf for d <= 0.

    Non-negative on ``(0, dhat)``: the barrier is convex in the distance.
    """
    dhat, kappa = _check_parameters(dhat, kappa)
    d, r, active, crossed = _split(d, dhat)
    rm1 = r - 1.0
    q = rm1 / r
    out = np.where(active, -kappa / dhat**2 * (2.0 * np.log(r) + 4.0 * q - q * q), 0.0)
    out[crossed] = np.inf
    return np.where(np.isnan(d), np.nan, out)


def particle_contact_weight(volume: np.ndarray, dim: int) -> np.ndarray:
    """Contact integration weight omega_q (n,) of MPM particles of volume ``volume`` (n,).

    ``volume`` is in m^2 (2D, per unit thickness) or m^3 (3D); the weight is the largest
    cross-section of a disk / sphere of that volume (section 4.2): ``2 sqrt(V / pi)`` in m (2D)
    or ``pi (3 V / (4 pi))^(2/3)`` in m^2 (3D). Raises ValueError for ``dim`` not 2 or 3 or for
    negative or non-finite volumes (naming the first offending indices).
    """
    if dim not in (2, 3) or isinstance(dim, bool):
        raise ValueError(f"dim must be 2 or 3, got {dim!r}")
    volume = np.asarray(volume, dtype=np.float64)
    if volume.ndim != 1:
        raise ValueError(f"volume must have shape (n,), got {volume.shape}")
    bad = ~(np.isfinite(volume) & (volume >= 0.0))
    if bad.any():
        raise ValueError(
            f"volume must be finite and >= 0; bad entries at indices {np.flatnonzero(bad)[:10]}"
        )
    if dim == 2:
        return 2.0 * np.sqrt(volume / np.pi)
    return np.pi * np.cbrt(3.0 * volume / (4.0 * np.pi)) ** 2


def boundary_vertex_weights(points: np.ndarray, facets: np.ndarray) -> np.ndarray:
    """Lumped boundary measure (V,) at each of the ``V`` points of a boundary mesh.

    ``points (V, d)`` in m; ``facets (F, d)`` int vertex indices: boundary edges in 2D, boundary
    triangles in 3D. Each facet gives ``1/d`` of its length (2D, m) or area (3D, m^2) to each of
    its vertices, so the weights sum to the perimeter / surface area; vertices in no facet get 0.
    """
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] not in (2, 3):
        raise ValueError(f"points must have shape (V, 2) or (V, 3), got {points.shape}")
    dim = points.shape[1]
    facets = np.asarray(facets)
    if facets.ndim != 2 or facets.shape[1] != dim:
        raise ValueError(f"facets must have shape (F, {dim}) for {dim}D points, got {facets.shape}")
    if facets.size and not np.issubdtype(facets.dtype, np.integer):
        raise ValueError(f"facets must be integer vertex indices, got dtype {facets.dtype}")
    facets = facets.astype(np.int64, copy=False)
    bad = ((facets < 0) | (facets >= points.shape[0])).any(axis=1)
    if bad.any():
        raise ValueError(
            f"facets reference vertices outside [0, {points.shape[0]}) in rows "
            f"{np.flatnonzero(bad)[:10]}"
        )
    corners = points[facets]  # (F, d, d)
    if dim == 2:
        measure = np.linalg.norm(corners[:, 1] - corners[:, 0], axis=1)
    else:
        normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        measure = 0.5 * np.linalg.norm(normal, axis=1)
    share = np.repeat(measure / dim, dim)
    return np.bincount(facets.ravel(), weights=share, minlength=points.shape[0])
