"""Mesh generators for common benchmark shapes (re-exported from ``geometry.shapes``).

Each takes a target edge length ``h`` in m and returns a ``TriMesh`` (2D) or ``TetMesh`` (3D).
"""

from geometry.shapes import (
    box,
    disk,
    rectangle,
    ring,
    semicircular_ring,
    sine_strip,
    spherical_shell,
)

__all__ = [
    "box",
    "disk",
    "rectangle",
    "ring",
    "semicircular_ring",
    "sine_strip",
    "spherical_shell",
]
