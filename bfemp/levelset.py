"""Analytic level sets for MPM grid boundaries (re-exported from ``geometry.levelset``).

Convention: ``value(x) < 0`` inside the obstacle, ``normal(x)`` points into free space. Use with
``scene.add_boundary(levelset, kind="sticky" | "slip" | "separate")``.

The dx gap: a level set constrains the MPM grid nodes inside it (``value <= 0`` at the node), not
the particles, and a particle feels a node through its quadratic B-spline stencil, which reaches
1.5 dx. So a body resting on a level-set floor stops about one grid cell above it, not on it.
Measured (``bfemp.sample.box`` block 0.5 x 0.3 m, 4 particles per cell, E = 1e6 Pa, dropped onto
a ``HalfPlane`` floor, sticky or slip alike, backward Euler): the lowest particles rest 1.09 dx
(dx = 0.05 m) and 1.11 dx (dx = 0.1 m) above it, the block's sampled bottom edge a quarter cell
lower (0.84 and 0.86 dx); where it lies depends on the stiffness and the load. A particle
sampled closer than that stays where it is (its stencil already holds a constrained node).
This is the gap that BFEMP's barrier coupling removes: against a FEM body (e.g. a floor with
``prescribed=bfemp.motion.Fixed()``) particles rest within d-hat of the FEM surface. Use a
level set where a gap of about dx does not matter (a container, a far wall), a FEM body where
the contact position does.
"""

from geometry.levelset import Box, Disk, HalfPlane, Inverted, Union

__all__ = ["Box", "Disk", "HalfPlane", "Inverted", "Union"]
