"""MPM on a quadratic B-spline background grid: particle-grid transfers (``bfemp.mpm.transfer``).

The transfers take plain arrays (particle stencils from ``geometry``'s grid, particle and grid
fields); the implicit strategies call them around the grid solve, the explicit ones take their
variants (``bfemp.mpm.transfer``'s family: fused with forces, dense 2D, one field per body).
"""
