"""Particles and volumes for MPM bodies (re-exported from ``geometry.sampling``).

Particles sit at regular sub-cell centres of the MPM grid (``ppc = k**d`` per cell), each with the
volume ``(dx / k)^d``, with optional jitter::

    x, vol = bfemp.sample.mesh(bfemp.shapes.ring((0, 0), 3.0, 4.0, h=0.1), dx=0.1, ppc=4)
    x, vol = bfemp.sample.box((0, 0), (1, 1), dx=0.02, ppc=4)
    x, vol = bfemp.sample.levelset(bfemp.levelset.Disk(center=(0, 0), radius=1), lower, upper,
                                   dx=0.025, ppc=4)
"""

from geometry.sampling import sample_box as box
from geometry.sampling import sample_inside as inside
from geometry.sampling import sample_levelset as levelset
from geometry.sampling import sample_mesh as mesh

__all__ = ["box", "inside", "levelset", "mesh"]
