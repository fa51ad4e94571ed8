"""Numerics only: projected Newton, line search, linear solvers, sparse assembly, PSD projection.

Imports numpy, scipy, scikit-sparse and numba; never imports ``geometry`` or ``bfemp``.
"""
