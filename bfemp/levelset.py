"""Analytic level sets for MPM grid boundaries (re-exported from ``geometry.levelset``).

Convention: ``value(x) < 0`` inside the obstacle, ``normal(x)`` points into free space. Use with
``scene.add_boundary(levelset, kind="sticky" | "slip" | "separate")``.

The dx gap: a level set constrains the MPM grid nodes inside it (``value <= 0`` at the node), not
the particles, and a particle feels a node through its quadratic B-spline stencil, which reaches
1.5 dx. So a body resting on a level-set floor stops about one grid cell above it, not on it
(measured: ``docs/guide/scenes.md``). A particle sampled closer than that stays where it is (its
stencil already holds a constrained node).
This is the gap that BFEMP's barrier coupling removes: against a FEM body (e.g. a floor with
``prescribed=bfemp.motion.Fixed()``) particles rest within d-hat of the FEM surface. Use a
level set where a gap of about dx does not matter (a container, a far wall), a FEM body where
the contact position does.
"""

from geometry.levelset import Box, Disk, HalfPlane, Inverted, Union

__all__ = ["Box", "Disk", "HalfPlane", "Inverted", "Union"]
