"""The classes of an ellipse packing as MPM bodies of a ``bfemp.Scene`` (``lr_ellipses``).

Geometry (packing, particles, colouring, interpenetration) lives in :mod:`geometry.ellipses` and
:mod:`geometry.ellipse_classes`; this module only hands each class's particles to
``Scene.add_mpm``: one body per class, its particles the union of its ellipses' particles.
"""

from __future__ import annotations

import numpy as np

import bfemp
from geometry.ellipse_classes import EllipseParticles, class_particles

__all__ = ["add_ellipse_classes"]


def add_ellipse_classes(
    scene: bfemp.Scene,
    particles: EllipseParticles,
    classes: np.ndarray,
    material: bfemp.materials.Material,
    *,
    velocity: tuple[float, float] | None = None,
    prefix: str = "class",
) -> list[bfemp.MpmBody]:
    """Add one MPM body per class (named ``f"{prefix}{k}"``) and return their handles.

    Args:
        scene: a 2D scene.
        particles: the particles of every ellipse (``sample_ellipses``).
        classes: (E,) class of each ellipse (``colour_ellipses``).
        material: the material of every class (LR: one law, many classes).
        velocity: initial velocity (2,) in m/s of every particle; default zero.
        prefix: body name prefix.

    Raises:
        ValueError: a class without particles (its ellipses are too small for the grid).
    """
    bodies = []
    for k, (x, vol) in enumerate(class_particles(particles, classes)):  # classes (<= 20)
        if x.shape[0] == 0:
            raise ValueError(
                f"add_ellipse_classes: class {k} has no particle: its ellipses are smaller than "
                "the particle spacing"
            )
        bodies.append(
            scene.add_mpm(x, vol, material=material, velocity=velocity, name=f"{prefix}{k}")
        )
    return bodies
