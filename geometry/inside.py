"""Is a point inside a simplex? The one point-in-body test of the library.

A FEM body is a union of simplices (triangles in 2D, tetrahedra in 3D), so "is point y inside
the body" is "is y inside one of its cells". :func:`simplex_depth` answers it for one cell by
the smallest barycentric coordinate of y, a dimensionless depth:

- ``> 0``: strictly inside the cell (1 / (d + 1) at its centroid);
- ``0``: on a face, edge or vertex;
- ``< 0``: outside.

On-boundary convention: the caller picks it with the sign of a small tolerance (1e-12):

- inclusive, ``depth >= -tol``: a point on the boundary belongs to the body. Locating and
  sampling use it (:func:`geometry.sampling.locate_points`, ``points_in_mesh``);
- strict, ``depth > tol``: touching is not penetrating. The intersection check uses it
  (``bfemp.contact.intersection.points_inside``).

A degenerate cell (zero volume) contains nothing: its depth is -1.

The formulas are the closed forms of Cramer's rule (2D: cross products; 3D: scalar triple
products), without allocation, so that parallel numba loops over points or (point, cell) pairs
can call it.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["simplex_depth"]


@njit(cache=True)
def simplex_depth(y: np.ndarray, v: np.ndarray) -> float:
    """Smallest barycentric coordinate of point ``y (d,)`` in the simplex ``v (d + 1, d)``.

    Positions in m, d = 2 or 3; the result is dimensionless (see the module docstring for its
    sign and the on-boundary convention). -1.0 for a degenerate simplex (determinant 0).
    """
    if y.shape[0] == 2:
        a0, a1 = v[1, 0] - v[0, 0], v[1, 1] - v[0, 1]
        b0, b1 = v[2, 0] - v[0, 0], v[2, 1] - v[0, 1]
        r0, r1 = y[0] - v[0, 0], y[1] - v[0, 1]
        det = a0 * b1 - a1 * b0
        if det == 0.0:
            return -1.0
        l1 = (r0 * b1 - r1 * b0) / det
        l2 = (a0 * r1 - a1 * r0) / det
        return min(1.0 - l1 - l2, l1, l2)
    a0, a1, a2 = v[1, 0] - v[0, 0], v[1, 1] - v[0, 1], v[1, 2] - v[0, 2]
    b0, b1, b2 = v[2, 0] - v[0, 0], v[2, 1] - v[0, 1], v[2, 2] - v[0, 2]
    c0, c1, c2 = v[3, 0] - v[0, 0], v[3, 1] - v[0, 1], v[3, 2] - v[0, 2]
    r0, r1, r2 = y[0] - v[0, 0], y[1] - v[0, 1], y[2] - v[0, 2]
    # b x c, c x a, a x b: det = a.(b x c); lambda_1 = r.(b x c) / det, and so on
    bc0, bc1, bc2 = b1 * c2 - b2 * c1, b2 * c0 - b0 * c2, b0 * c1 - b1 * c0
    ca0, ca1, ca2 = c1 * a2 - c2 * a1, c2 * a0 - c0 * a2, c0 * a1 - c1 * a0
    ab0, ab1, ab2 = a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0
    det = a0 * bc0 + a1 * bc1 + a2 * bc2
    if det == 0.0:
        return -1.0
    l1 = (r0 * bc0 + r1 * bc1 + r2 * bc2) / det
    l2 = (r0 * ca0 + r1 * ca1 + r2 * ca2) / det
    l3 = (r0 * ab0 + r1 * ab1 + r2 * ab2) / det
    return min(1.0 - l1 - l2 - l3, l1, l2, l3)
