"""Helpers shared by the geometry tests."""

import numpy as np


def cols(X):
    """(n, k, d) -> tuple of k arrays (n, d): the argument convention of geometry.distance."""
    return tuple(np.ascontiguousarray(X[:, j]) for j in range(X.shape[1]))


def triangle_samples(X, N):
    """Points of triangles ``X[:, 1:4]`` (X (n, 4, 3)) on the barycentric lattice i/N, j/N
    (i + j <= N), ``(n, M, 3)``, and each triangle's longest edge ``(n,)`` (the lattice's spacing
    along an edge is that over N)."""
    i, j = np.meshgrid(np.arange(N + 1), np.arange(N + 1), indexing="ij")
    keep = i + j <= N
    b1, b2 = i[keep] / N, j[keep] / N
    u, v = X[:, 2] - X[:, 1], X[:, 3] - X[:, 1]
    pts = X[:, None, 1] + b1[None, :, None] * u[:, None] + b2[None, :, None] * v[:, None]
    longest = np.linalg.norm(X[:, [2, 3, 3]] - X[:, [1, 1, 2]], axis=-1).max(axis=1)
    return pts, longest
