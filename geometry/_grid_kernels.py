"""numba kernels of :mod:`geometry.grid`: quadratic B-spline stencils of particles.

Private: array-in / array-out, no validation (the drivers in :mod:`geometry.grid` validate).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True)
def _bspline_1d(fx: float, inv_dx: float, w: np.ndarray, dw: np.ndarray) -> None:
    """Quadratic B-spline weights and derivatives of the nodes base, base+1, base+2 on one axis.

    ``fx = x/dx - base`` lies in [0.5, 1.5). With ``N(r) = 3/4 - r^2`` for ``|r| < 1/2`` and
    ``N(r) = (3/2 - |r|)^2 / 2`` for ``1/2 <= |r| < 3/2``, evaluated at ``r = fx - o`` (o = 0, 1, 2)
    this gives the three weights below; they sum to 1 for every fx. The derivatives are taken
    with respect to x, hence the factor ``1/dx`` (units 1/m).
    """
    a = 1.5 - fx
    b = fx - 1.0
    c = fx - 0.5
    w[0] = 0.5 * a * a
    w[1] = 0.75 - b * b
    w[2] = 0.5 * c * c
    dw[0] = -a * inv_dx
    dw[1] = -2.0 * b * inv_dx
    dw[2] = c * inv_dx


@njit(cache=True, parallel=True)
def _stencils(
    xi: np.ndarray,
    offsets: np.ndarray,
    inv_dx: float,
    base: np.ndarray,
    weights: np.ndarray,
    grads: np.ndarray,
) -> None:
    """Tensor-product quadratic B-spline stencils of P particles.

    Args:
        xi: (P, d) particle positions in grid units, ``(x - origin) / dx``.
        offsets: (K, d) int64 node offsets from the base node, K = 3**d.
        inv_dx: 1 / dx in 1/m.
        base: (P, d) int64 output, ``floor(xi - 0.5)``.
        weights: (P, K) output, ``w_ip = prod_a N(xi_a - ijk_a)``.
        grads: (P, K, d) output, ``d w_ip / d x_a = N'_a prod_{b != a} N_b`` in 1/m.

    Each particle writes only its own rows, so the loop over particles is race-free.
    """
    n_particles, dim = xi.shape
    n_stencil = offsets.shape[0]
    for p in prange(n_particles):
        w = np.empty((3, 3))
        dw = np.empty((3, 3))
        for a in range(dim):
            b = np.floor(xi[p, a] - 0.5)
            base[p, a] = np.int64(b)
            _bspline_1d(xi[p, a] - b, inv_dx, w[a], dw[a])
        for k in range(n_stencil):
            wk = 1.0
            for a in range(dim):
                wk *= w[a, offsets[k, a]]
            weights[p, k] = wk
            for a in range(dim):
                g = dw[a, offsets[k, a]]
                for b in range(dim):
                    if b != a:
                        g *= w[b, offsets[k, b]]
                grads[p, k, a] = g
