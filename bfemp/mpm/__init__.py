"""MPM on a quadratic B-spline background grid: particle-grid transfers (``bfemp.mpm.transfer``).

The transfers take plain arrays (particle stencils from ``geometry``'s grid, particle and grid
fields); the strategies in ``bfemp.steppers`` call them around the implicit grid solve.
"""
