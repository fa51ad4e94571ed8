"""Geometry only: meshes, shape generators, grids, distances, CCD, broad phase, sampling,
level sets.

Imports numpy, numba, meshio and python-fcl; never imports ``solvers`` or ``bfemp``.
"""
