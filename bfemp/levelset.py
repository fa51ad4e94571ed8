"""Analytic level sets for MPM grid boundaries (re-exported from ``geometry.levelset``).

Convention: ``value(x) < 0`` inside the obstacle, ``normal(x)`` points into free space. Use with
``scene.add_boundary(levelset, kind="sticky" | "slip" | "separate")``.
"""

from geometry.levelset import Box, Disk, HalfPlane, Inverted, Union

__all__ = ["Box", "Disk", "HalfPlane", "Inverted", "Union"]
