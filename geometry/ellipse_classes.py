"""Particles, material classes and interpenetration of an ellipse packing (``lr_ellipses``).

- :func:`sample_ellipses`: the MPM particles of each ellipse, the points of the grid's sub-cell
  lattice (``ppc = k^2`` per cell, spacing ``dx / k``, volume ``(dx / k)^2`` each, as
  :mod:`geometry.sampling`) strictly inside it; ellipses do not overlap, so no point is shared.
- :func:`colour_ellipses`: material classes by greedy colouring (DSatur: next the uncoloured
  ellipse with the most distinct colours among its neighbours, ties by degree, then index) of
  the contact graph, two ellipses being adjacent when they are not certified ``distance`` apart
  (:func:`geometry.ellipses.close_pairs`: every pair closer than ``distance`` is an edge, a
  slightly farther one may be). LR shaded its 20 materials so that "all contact would be between
  different material classes". Among the colours none of its neighbours has, an ellipse takes
  (``spread=True``, the default) the one whose closest member is farthest from it (bounding
  circles' gap; an unused colour first), so that all classes are used and ellipses of one class
  lie as far apart as the greedy order allows: compression brings ellipses that start more than
  ``distance`` apart into contact, and one class has no contact with itself. With
  ``spread=False`` it takes the smallest such colour (fewest classes).
- :func:`class_particles`: one particle set per class, the union of its ellipses' particles.
- :func:`interpenetrating`: the particles that have a particle of another class within
  ``r_p = 0.5 * spacing * sqrt(J_p)`` of their centre (``spacing`` = dx / 2 at 2 x 2 PPC: half
  the current particle size), found with the broad phase's spatial hash on the boxes
  ``x_p +- r_p`` and the exact distance test.
"""

from __future__ import annotations

import numpy as np

from geometry.broadphase import box_overlap_pairs
from geometry.ellipses import EllipsePacking, close_pairs
from geometry.sampling import sample_box

__all__ = [
    "EllipseParticles",
    "class_particles",
    "colour_ellipses",
    "interpenetrating",
    "sample_ellipses",
]


class EllipseParticles:
    """Particles of the ellipses of a packing.

    Attributes:
        x: (P, 2) positions in m, ellipse by ellipse (lattice order within each).
        volume: (P,) volumes in m^2 (per unit thickness), ``(dx / k)^2`` each.
        ellipse: (P,) int64 index of the ellipse holding each particle.
        n_ellipses: E, the number of ellipses of the packing.
    """

    __slots__ = ("ellipse", "n_ellipses", "volume", "x")

    def __init__(self, x: np.ndarray, volume: np.ndarray, ellipse: np.ndarray, n: int) -> None:
        self.x, self.volume, self.ellipse, self.n_ellipses = x, volume, ellipse, n

    def counts(self) -> np.ndarray:
        """(E,) particles per ellipse."""
        return np.bincount(self.ellipse, minlength=self.n_ellipses)

    def positions(self) -> list[np.ndarray]:
        """Per ellipse, its particle positions (p_e, 2) in m (p_e may be 0 for a tiny one)."""
        bounds = np.concatenate([[0], np.cumsum(self.counts())])
        return [self.x[bounds[e] : bounds[e + 1]] for e in range(self.n_ellipses)]


def sample_ellipses(
    packing: EllipsePacking,
    dx: float,
    ppc: int = 4,
    origin: tuple[float, float] | None = None,
) -> EllipseParticles:
    """The lattice points of a grid of cell ``dx`` (m) with ``ppc`` per cell inside each ellipse.

    Args:
        packing: the ellipses.
        dx: grid cell size in m.
        ppc: particles per cell, ``k^2`` (LR: 4).
        origin: (2,) grid origin the lattice is aligned to, m (default zeros).

    Returns:
        The particles, ellipse by ellipse.
    """
    pts, vol = sample_box(packing.lower, packing.upper, dx, ppc, origin=origin)
    owner = packing.inside(pts)
    keep = np.flatnonzero(owner >= 0)
    order = keep[np.argsort(owner[keep], kind="stable")]
    return EllipseParticles(
        np.ascontiguousarray(pts[order]), vol[order], owner[order], packing.n_ellipses
    )


def colour_ellipses(
    packing: EllipsePacking, distance: float, max_classes: int, *, spread: bool = True
) -> np.ndarray:
    """(E,) classes in ``0 .. max_classes - 1``, no two ellipses closer than ``distance`` alike.

    Args:
        packing: the ellipses.
        distance: gap in m under which two ellipses are adjacent (LR benchmark: 2 cells).
        max_classes: number of classes available (20 full, 6 quick).
        spread: among the allowed classes take the one whose closest member is farthest
            (True, all classes used), or the smallest (False, fewest classes).

    Raises:
        ValueError: ``distance`` or ``max_classes`` invalid, or ``max_classes`` classes are not
            enough for the greedy colouring (the message names the ellipse and its degree).
    """
    if not (np.isfinite(distance) and distance >= 0.0):
        raise ValueError(f"colour_ellipses: distance must be finite and >= 0 (m), got {distance}")
    if isinstance(max_classes, bool) or not isinstance(max_classes, int | np.integer):
        raise ValueError(f"colour_ellipses: max_classes must be an integer, got {max_classes!r}")
    if max_classes < 1:
        raise ValueError(f"colour_ellipses: max_classes must be >= 1, got {max_classes}")
    n = packing.n_ellipses
    pairs = close_pairs(packing.centers, packing.semi_axes, packing.angles, float(distance))
    adjacent = np.zeros((n, n), dtype=bool)
    adjacent[pairs[:, 0], pairs[:, 1]] = True
    adjacent[pairs[:, 1], pairs[:, 0]] = True
    degree = adjacent.sum(axis=1)
    # gap of the bounding circles (radius a), a lower bound of the true gap
    a = packing.semi_axes[:, 0]
    centre_gap = np.linalg.norm(packing.centers[:, None] - packing.centers[None], axis=2)
    circle_gap = centre_gap - a[:, None] - a[None]
    colour = np.full(n, -1, dtype=np.int64)
    # seen[e, c]: a neighbour of e has colour c (one column more than allowed, to detect need)
    seen = np.zeros((n, max_classes + 1), dtype=bool)
    for _ in range(n):  # DSatur over the ellipses (tens to hundreds), each step vectorised
        saturation = np.where(colour < 0, seen.sum(axis=1), -1)
        best = np.flatnonzero(saturation == saturation.max())
        e = int(best[np.argmax(degree[best])])
        free = np.flatnonzero(~seen[e, :max_classes])
        if free.size == 0:
            raise ValueError(
                f"colour_ellipses: {max_classes} classes are not enough: ellipse {e} "
                f"(degree {degree[e]}) has neighbours of every class at distance < {distance} m"
            )
        if spread:
            # the closest member of each free colour (inf for an unused one)
            closest = np.full(free.size, np.inf)
            for m, c in enumerate(free):  # colours (<= max_classes)
                members = colour == c
                if members.any():
                    closest[m] = circle_gap[e, members].min()
            colour[e] = int(free[np.argmax(closest)])
        else:
            colour[e] = int(free[0])
        seen[adjacent[e], colour[e]] = True
    return colour


def class_particles(
    particles: EllipseParticles, classes: np.ndarray
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per class ``k = 0 .. max(classes)``: ``(x (p_k, 2) in m, volume (p_k,) in m^2)``, the
    union of the particles of the ellipses of that class (in ellipse order)."""
    classes = np.asarray(classes, dtype=np.int64)
    if classes.shape != (particles.n_ellipses,):
        raise ValueError(
            f"class_particles: classes must have shape ({particles.n_ellipses},), "
            f"got {classes.shape}"
        )
    of_particle = classes[particles.ellipse]
    masks = [of_particle == k for k in range(int(classes.max()) + 1 if classes.size else 0)]
    return [(particles.x[mask], particles.volume[mask]) for mask in masks]


def interpenetrating(
    x: np.ndarray, classes: np.ndarray, J: np.ndarray, spacing: float
) -> np.ndarray:
    """(P,) True for the particles with a particle of another class within ``r_p`` of them.

    Args:
        x: (P, 2) particle positions in m.
        classes: (P,) class (material) of each particle.
        J: (P,) det F of each particle (> 0).
        spacing: initial particle spacing in m (dx / 2 at 2 x 2 PPC);
            ``r_p = 0.5 * spacing * sqrt(J_p)``.

    A particle counts when ``|x_q - x_p| < r_p`` for some q of another class (the radius is
    that of the particle counted, so the relation is not symmetric).
    """
    x = np.ascontiguousarray(x, dtype=np.float64)
    n = x.shape[0]
    if x.ndim != 2 or x.shape[1] != 2:
        raise ValueError(f"interpenetrating: x must have shape (P, 2), got {x.shape}")
    classes = np.asarray(classes)
    J = np.asarray(J, dtype=np.float64)
    if classes.shape != (n,) or J.shape != (n,):
        raise ValueError(
            f"interpenetrating: classes and J must have shape ({n},), got {classes.shape} "
            f"and {J.shape}"
        )
    if not np.all(J > 0.0):
        raise ValueError("interpenetrating: J must be > 0 at every particle")
    if not (np.isfinite(spacing) and spacing > 0.0):
        raise ValueError(f"interpenetrating: spacing must be finite and > 0 (m), got {spacing}")
    hit = np.zeros(n, dtype=bool)
    if n == 0:
        return hit
    r = 0.5 * spacing * np.sqrt(J)
    pairs = box_overlap_pairs(x - r[:, None], x + r[:, None], x, x)
    p, q = pairs[:, 0], pairs[:, 1]
    other = classes[p] != classes[q]
    p, q = p[other], q[other]
    close = np.einsum("nd,nd->n", x[q] - x[p], x[q] - x[p]) < r[p] ** 2
    hit[p[close]] = True
    return hit
