"""Random packings of non-overlapping ellipses in a 2D box (the LR ``lr_ellipses`` benchmark).

An ellipse ``e`` has centre ``c_e (2,)`` in m, semi-axes ``a_e >= b_e > 0`` in m and angle
``theta_e`` in rad (the direction of its major axis from +x); its interior is
``|diag(1/a, 1/b) R(theta)^T (x - c)| < 1``.

Overlap test (conservative, no false negatives). Every ellipse is replaced by the convex N-gon
circumscribing it: the affine image ``c + R diag(a, b) u`` of the regular N-gon circumscribing
the unit circle (vertices at radius ``1 / cos(pi / N)``), which contains the ellipse because the
affine map preserves containment. Two polygons are *certified apart by g* when their projections
on one of their 2N edge normals leave a gap of at least ``g`` (separating-axis theorem); a gap
``g`` along a unit axis bounds the Euclidean distance from below, so certified polygons, and a
fortiori the ellipses inside them, are at least ``g`` apart. The test never accepts an
overlapping pair; it may reject a pair whose true gap is slightly above ``g`` (the polygons are
at most ``1 / cos(pi / N) - 1`` = 0.86 % larger than the ellipses for N = 24). Pairs whose
bounding circles (radius ``a``) are farther apart than ``g`` are certified without polygons.

Packing: random sequential addition, largest first, then shaking and growing. Each round draws
sizes (aspect ``a / b`` uniform in ``[1, max_aspect]``, then ``a`` uniform in
``[min_semi_axis * aspect, max_semi_axis]``, so both semi-axes lie in
``[min_semi_axis, max_semi_axis]``) until their area covers what misses of the target, sorts them
by decreasing area and tries each at up to ``max_attempts`` random centres and angles. A size
for which no room is left is first shrunk (same aspect, down to the smallest semi-axis) to the
largest clearance there is; the last one is shrunk to what misses. Centres are proposed where
there is room: at raster points (spacing a third of the smallest semi-axis) whose approximate
clearance, the distance to the walls and to the polygons placed so far, is at least
``b + min_gap``; proposals only steer the search, the certified test decides. A round that
ends short of the target shakes (each ellipse moves by a small random step where that stays
certified free) and grows (each ellipse is scaled, same aspect, by the largest certified-free
factor bisection finds, ``a <= max_semi_axis``), which opens and fills room for the next round.
Rounds repeat until the solid fraction reaches the target (within 0.1 %) or ``max_rounds``.
The loops run over ellipses (tens to hundreds), each step vectorised over proposals, raster
points and neighbours.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from geometry.broadphase import box_overlap_pairs

__all__ = [
    "EllipsePacking",
    "certified_apart",
    "close_pairs",
    "ellipse_polygons",
    "inside_ellipse",
    "pack_ellipses",
]

logger = logging.getLogger(__name__)

#: sides of the circumscribed polygons of the overlap test
POLYGON_SIDES = 24
#: candidate centres tried together (one vectorised test)
_BATCH = 64
#: the target fraction counts as reached within this relative shortfall
_REACHED = 1e-3


@dataclass(frozen=True)
class EllipsePacking:
    """Ellipses in the box ``[lower, upper]``.

    Attributes:
        centers: (E, 2) centres in m.
        semi_axes: (E, 2) semi-axes ``(a, b)``, ``a >= b``, in m.
        angles: (E,) direction of the major axis from +x, rad.
        lower, upper: (2,) corners of the box in m.
        min_gap: the gap in m certified between any two ellipses (and to the walls).
    """

    centers: np.ndarray
    semi_axes: np.ndarray
    angles: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    min_gap: float = 0.0

    @property
    def n_ellipses(self) -> int:
        """Number of ellipses E."""
        return int(self.centers.shape[0])

    @property
    def areas(self) -> np.ndarray:
        """(E,) areas pi a b in m^2."""
        return math.pi * self.semi_axes[:, 0] * self.semi_axes[:, 1]

    @property
    def fraction(self) -> float:
        """Solid fraction: total ellipse area over the box area."""
        return float(self.areas.sum() / np.prod(self.upper - self.lower))

    def inside(self, x: np.ndarray) -> np.ndarray:
        """(P,) index of the ellipse containing each point of ``x (P, 2)`` (m), -1 if none."""
        owner = np.full(x.shape[0], -1, dtype=np.int64)
        for e in range(self.n_ellipses):  # ellipses, each test vectorised over the points
            hit = inside_ellipse(x, self.centers[e], self.semi_axes[e], self.angles[e])
            owner[hit] = e
        return owner


# ---------------------------------------------------------------------------- primitives


def inside_ellipse(
    x: np.ndarray, center: np.ndarray, semi_axes: np.ndarray, angle: float
) -> np.ndarray:
    """(P,) True where the points ``x (P, 2)`` (m) lie strictly inside the ellipse."""
    c, s = math.cos(angle), math.sin(angle)
    d = np.asarray(x, dtype=np.float64) - center
    u = (c * d[:, 0] + s * d[:, 1]) / semi_axes[0]
    v = (-s * d[:, 0] + c * d[:, 1]) / semi_axes[1]
    return u * u + v * v < 1.0


def _half_extents(semi_axes: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """(E, 2) half-widths in m of the axis-aligned boxes of the ellipses (exact)."""
    a, b = semi_axes[:, 0], semi_axes[:, 1]
    c2, s2 = np.cos(angles) ** 2, np.sin(angles) ** 2
    return np.stack([np.sqrt(a * a * c2 + b * b * s2), np.sqrt(a * a * s2 + b * b * c2)], axis=1)


def ellipse_polygons(
    centers: np.ndarray, semi_axes: np.ndarray, angles: np.ndarray, sides: int = POLYGON_SIDES
) -> np.ndarray:
    """(E, sides, 2) convex polygons in m, counter-clockwise, each containing its ellipse.

    Vertices ``c + R(theta) diag(a, b) u_k / cos(pi / sides)`` with ``u_k`` at the angles
    ``(k + 1/2) 2 pi / sides``: the affine image of the regular polygon circumscribing the unit
    circle.
    """
    t = (np.arange(sides) + 0.5) * (2.0 * math.pi / sides)
    r = 1.0 / math.cos(math.pi / sides)
    u = np.stack([np.cos(t), np.sin(t)], axis=1) * r  # (N, 2)
    local = u[None] * semi_axes[:, None, :]  # (E, N, 2)
    c, s = np.cos(angles)[:, None], np.sin(angles)[:, None]
    x = c * local[..., 0] - s * local[..., 1]
    y = s * local[..., 0] + c * local[..., 1]
    return np.stack([x, y], axis=2) + centers[:, None, :]


def _edge_normals(poly: np.ndarray) -> np.ndarray:
    """(..., N, 2) outward unit normals of the edges of counter-clockwise polygons."""
    e = np.roll(poly, -1, axis=-2) - poly
    n = np.stack([e[..., 1], -e[..., 0]], axis=-1)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def certified_apart(poly_a: np.ndarray, poly_b: np.ndarray, gap: float) -> np.ndarray:
    """(n,) True where the convex polygons ``poly_a[i]``, ``poly_b[i]`` (each (n, N, 2), m) are
    proven at least ``gap`` (m, >= 0) apart by a separating axis among their edge normals.

    False may still be a pair farther apart than ``gap`` (the test is conservative).
    """
    axes = np.concatenate([_edge_normals(poly_a), _edge_normals(poly_b)], axis=1)  # (n, 2N, 2)
    pa = np.einsum("nkd,nvd->nkv", axes, poly_a)
    pb = np.einsum("nkd,nvd->nkv", axes, poly_b)
    sep = np.maximum(pb.min(axis=2) - pa.max(axis=2), pa.min(axis=2) - pb.max(axis=2))
    return sep.max(axis=1) >= gap


def close_pairs(
    centers: np.ndarray,
    semi_axes: np.ndarray,
    angles: np.ndarray,
    gap: float,
    sides: int = POLYGON_SIDES,
) -> np.ndarray:
    """(n, 2) pairs ``i < j`` of ellipses not certified at least ``gap`` (m) apart.

    Every pair whose true gap is below ``gap`` is listed (no false negatives); a few slightly
    farther pairs may be too. Candidates come from the broad phase on the ellipses' boxes.
    """
    half = _half_extents(semi_axes, angles)
    lo, hi = centers - half, centers + half
    pairs = box_overlap_pairs(lo - 0.5 * gap, hi + 0.5 * gap, lo - 0.5 * gap, hi + 0.5 * gap)
    pairs = pairs[pairs[:, 0] < pairs[:, 1]]
    if pairs.shape[0] == 0:
        return pairs
    poly = ellipse_polygons(centers, semi_axes, angles, sides)
    apart = certified_apart(poly[pairs[:, 0]], poly[pairs[:, 1]], gap)
    return np.ascontiguousarray(pairs[~apart])


# ---------------------------------------------------------------------------- packing


def _check_positive(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating | np.integer):
        raise ValueError(f"pack_ellipses: {name} must be a number, got {value!r}")
    value = float(value)
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"pack_ellipses: {name} must be finite and > 0, got {value}")
    return value


def _draw_sizes(
    rng: np.random.Generator, area: float, s_min: float, s_max: float, max_aspect: float
) -> np.ndarray:
    """(k, 2) semi-axes (a, b) with total area >= ``area``, sorted by decreasing area."""
    mean_area = math.pi * (0.5 * (s_min + s_max)) ** 2 / max(1.0, 0.5 * (1.0 + max_aspect))
    k = max(4, int(2.0 * area / mean_area) + 4)
    while True:
        aspect = rng.uniform(1.0, max_aspect, k)
        a = rng.uniform(s_min * aspect, s_max)
        sizes = np.stack([a, a / aspect], axis=1)
        cum = np.cumsum(math.pi * sizes[:, 0] * sizes[:, 1])
        if cum[-1] >= area:
            sizes = sizes[: int(np.searchsorted(cum, area)) + 1]
            order = np.argsort(-(sizes[:, 0] * sizes[:, 1]), kind="stable")
            return sizes[order]
        k *= 2


class _Raster:
    """Raster points (M, 2) with their approximate clearance (M,) in m: the distance to the
    walls and to the polygons placed so far (0 inside them)."""

    def __init__(self, lower: np.ndarray, upper: np.ndarray, spacing: float) -> None:
        n = np.maximum(1, np.floor((upper - lower) / spacing).astype(np.int64))
        axes = [lower[k] + (np.arange(n[k]) + 0.5) * (upper[k] - lower[k]) / n[k] for k in (0, 1)]
        gx, gy = np.meshgrid(*axes, indexing="ij")
        self.points = np.stack([gx.ravel(), gy.ravel()], axis=1)
        self.spacing = float(spacing)
        to_wall = np.minimum(self.points - lower, upper - self.points)
        self.clearance = to_wall.min(axis=1)

    def add(self, poly: np.ndarray, center: np.ndarray, semi_axes: np.ndarray, angle: float):
        """Lower the clearance by the distance to the polygon ``poly (N, 2)`` (0 inside)."""
        reach = semi_axes[0] * 1.1 + self.clearance.max()
        near = np.flatnonzero(np.abs(self.points - center).max(axis=1) < reach)
        if near.size == 0:
            return
        p = self.points[near]
        a, b = poly, np.roll(poly, -1, axis=0)
        ab = b - a  # (N, 2)
        ap = p[:, None, :] - a[None]  # (m, N, 2)
        t = np.clip(np.einsum("mnd,nd->mn", ap, ab) / np.einsum("nd,nd->n", ab, ab), 0.0, 1.0)
        dist = np.linalg.norm(ap - t[..., None] * ab[None], axis=2).min(axis=1)
        dist[inside_ellipse(p, center, semi_axes, angle)] = 0.0
        self.clearance[near] = np.minimum(self.clearance[near], dist)


class _Placed:
    """The ellipses placed so far, as growing arrays, and the certified free-space test."""

    def __init__(self, lo: np.ndarray, hi: np.ndarray, gap: float) -> None:
        self.lo, self.hi, self.gap = lo, hi, gap
        self.centers = np.empty((0, 2))
        self.axes = np.empty((0, 2))
        self.angles = np.empty(0)
        self.polys = np.empty((0, POLYGON_SIDES, 2))

    @property
    def area(self) -> float:
        return float(math.pi * np.dot(self.axes[:, 0], self.axes[:, 1]))

    def free(
        self, c: np.ndarray, sizes: np.ndarray, theta: np.ndarray, skip: int = -1
    ) -> tuple[np.ndarray, np.ndarray]:
        """(k,) True where the proposals (centres (k, 2), semi-axes (k, 2), angles (k,)) fit in
        the box and are certified ``gap`` apart from every placed ellipse but ``skip``; and
        their polygons (k, N, 2)."""
        half = _half_extents(sizes, theta)
        ok = np.all((c - half >= self.lo + self.gap) & (c + half <= self.hi - self.gap), axis=1)
        poly = ellipse_polygons(c, sizes, theta)
        if self.centers.shape[0] and ok.any():
            # neighbours: bounding circles closer than the gap
            dist = np.linalg.norm(c[:, None, :] - self.centers[None], axis=2)
            near = dist < sizes[:, :1] + self.axes[None, :, 0] + self.gap
            if skip >= 0:
                near[:, skip] = False
            near &= ok[:, None]
            ic, ip = np.nonzero(near)
            if ic.size:
                apart = certified_apart(poly[ic], self.polys[ip], self.gap)
                ok[ic[~apart]] = False
        return ok, poly

    def add(self, c: np.ndarray, size: np.ndarray, theta: float, poly: np.ndarray) -> None:
        self.centers = np.vstack([self.centers, c[None]])
        self.axes = np.vstack([self.axes, size[None]])
        self.angles = np.append(self.angles, theta)
        self.polys = np.concatenate([self.polys, poly[None]])

    def set(self, e: int, c: np.ndarray, size: np.ndarray, theta: float, poly: np.ndarray):
        self.centers[e], self.axes[e], self.angles[e], self.polys[e] = c, size, theta, poly


def pack_ellipses(
    lower: tuple[float, float],
    upper: tuple[float, float],
    *,
    min_semi_axis: float = 0.05e-3,
    max_semi_axis: float = 0.2e-3,
    max_aspect: float = 2.5,
    fraction: float = 0.6,
    min_gap: float = 0.0,
    max_attempts: int = 2000,
    max_rounds: int = 30,
    rng: np.random.Generator | int | None = 0,
) -> EllipsePacking:
    """A seeded random packing of non-overlapping ellipses inside the box ``[lower, upper]``.

    Args:
        lower, upper: (2,) corners of the box in m.
        min_semi_axis, max_semi_axis: range of both semi-axes in m (LR: 0.05-0.2 mm).
        max_aspect: largest ratio a / b (>= 1; LR: 2.5); needs ``min * max_aspect <= max``.
        fraction: target solid fraction (area of the ellipses over the box), in (0, 0.9].
        min_gap: gap in m certified between any two ellipses and between an ellipse and the
            walls (0: they may touch at a point).
        max_attempts: centres tried per ellipse before it is dropped.
        max_rounds: rounds (insertion, then shaking and growing) at most.
        rng: generator or seed (default 0): the packing is reproducible.

    Returns:
        The packing; its ``fraction`` is the target within 0.1 % (the last ellipse is shrunk to
        what misses, or grown; it may overshoot when shrinking would take it out of range), or
        below it when the box jammed (logged as a warning).

    Raises:
        ValueError: a bad argument, named.
    """
    lo = np.asarray(lower, dtype=np.float64)
    hi = np.asarray(upper, dtype=np.float64)
    if lo.shape != (2,) or hi.shape != (2,) or not np.all(np.isfinite(np.r_[lo, hi])):
        raise ValueError(f"pack_ellipses: lower and upper must be 2 finite numbers, got {lower}")
    if not np.all(hi > lo):
        raise ValueError(f"pack_ellipses: upper must exceed lower, got {lower} and {upper}")
    s_min = _check_positive("min_semi_axis", min_semi_axis)
    s_max = _check_positive("max_semi_axis", max_semi_axis)
    aspect = _check_positive("max_aspect", max_aspect)
    target = _check_positive("fraction", fraction)
    if aspect < 1.0:
        raise ValueError(f"pack_ellipses: max_aspect must be >= 1, got {aspect}")
    if s_min * aspect > s_max * (1.0 + 1e-12):
        raise ValueError(
            f"pack_ellipses: min_semi_axis * max_aspect ({s_min * aspect:.3g} m) exceeds "
            f"max_semi_axis ({s_max:.3g} m): no ellipse has both semi-axes in range"
        )
    if target > 0.9:
        raise ValueError(f"pack_ellipses: fraction must be <= 0.9, got {target}")
    if not (math.isfinite(min_gap) and min_gap >= 0.0):
        raise ValueError(f"pack_ellipses: min_gap must be finite and >= 0, got {min_gap}")
    if 2.0 * s_min + 2.0 * min_gap > (hi - lo).min():
        raise ValueError("pack_ellipses: the box is smaller than the smallest ellipse")
    for name, value in (("max_attempts", max_attempts), ("max_rounds", max_rounds)):
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
            raise ValueError(f"pack_ellipses: {name} must be an integer >= 1, got {value!r}")
    gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)

    goal = target * float(np.prod(hi - lo))
    placed = _Placed(lo, hi, float(min_gap))
    for _ in range(max_rounds):
        if placed.area >= goal * (1.0 - _REACHED):
            break
        raster = _Raster(lo + min_gap, hi - min_gap, s_min / 3.0)
        for e in range(placed.centers.shape[0]):
            raster.add(placed.polys[e], placed.centers[e], placed.axes[e], placed.angles[e])
        _insert(gen, placed, raster, goal, s_min, s_max, aspect, max_attempts)
        if placed.area < goal:
            _shake_and_grow(gen, placed, goal, s_max)
    packing = EllipsePacking(
        centers=placed.centers,
        semi_axes=placed.axes,
        angles=placed.angles,
        lower=lo,
        upper=hi,
        min_gap=float(min_gap),
    )
    if packing.fraction < target * (1.0 - _REACHED):
        logger.warning(
            "pack_ellipses: jammed at solid fraction %.3f below the target %.3f (%d ellipses)",
            packing.fraction,
            target,
            packing.n_ellipses,
        )
    return packing


def _insert(
    gen: np.random.Generator,
    placed: _Placed,
    raster: _Raster,
    goal: float,
    s_min: float,
    s_max: float,
    aspect: float,
    max_attempts: int,
) -> None:
    """Random sequential addition, largest first, of sizes covering what misses of ``goal``."""
    for size in _draw_sizes(gen, goal - placed.area, s_min, s_max, aspect):
        if placed.area >= goal:
            return
        # where no room is left for this size, shrink it (same aspect) to the largest room
        # there is, down to the smallest semi-axis allowed
        room = raster.clearance.max() - placed.gap
        if room < size[1]:
            if room < s_min:
                return
            size = size * (room / size[1])
        # the last one: no larger than what misses (if that keeps it in range)
        missing = goal - placed.area
        area = math.pi * size[0] * size[1]
        if area > missing and size[1] * math.sqrt(missing / area) >= s_min:
            size = size * math.sqrt(missing / area)
        found = _place_one(gen, size, raster, placed, max_attempts)
        if found is None:
            continue
        c, theta, poly = found
        placed.add(c, size, theta, poly)
        raster.add(poly, c, size, theta)


def _place_one(
    gen: np.random.Generator, size: np.ndarray, raster: _Raster, placed: _Placed, max_attempts: int
) -> tuple[np.ndarray, float, np.ndarray] | None:
    """A certified free position (centre (2,), angle, polygon (N, 2)) for an ellipse of
    semi-axes ``size (2,)``, or None after ``max_attempts`` proposals."""
    room = np.flatnonzero(raster.clearance >= size[1] + placed.gap - raster.spacing)
    if room.size == 0:
        return None
    tried = 0
    while tried < max_attempts:
        k = min(_BATCH, max_attempts - tried)
        tried += k
        c = raster.points[gen.choice(room, size=k)]
        c = c + gen.uniform(-0.5, 0.5, (k, 2)) * raster.spacing
        theta = gen.uniform(0.0, math.pi, k)
        ok, poly = placed.free(c, np.broadcast_to(size, (k, 2)), theta)
        if ok.any():
            j = int(np.flatnonzero(ok)[0])
            return c[j], float(theta[j]), poly[j]
    return None


def _shake_and_grow(gen: np.random.Generator, placed: _Placed, goal: float, s_max: float) -> None:
    """One pass of a jammed box: each ellipse moves by a small random step where that is free
    (16 proposals, steps of 0.2 b, turns of 0.2 rad), then grows (same aspect, a <= s_max) as
    far as is certified free (bisection, 12 steps), until the placed area reaches ``goal``."""
    k = 16
    for e in gen.permutation(placed.centers.shape[0]):
        size = placed.axes[e]
        c = placed.centers[e] + gen.normal(0.0, 0.2 * size[1], (k, 2))
        theta = placed.angles[e] + gen.normal(0.0, 0.2, k)
        ok, poly = placed.free(c, np.broadcast_to(size, (k, 2)), theta, skip=int(e))
        if ok.any():
            j = int(np.flatnonzero(ok)[0])
            placed.set(e, c[j], size, float(theta[j]), poly[j])
    for e in gen.permutation(placed.centers.shape[0]):
        size, c, theta = placed.axes[e].copy(), placed.centers[e], placed.angles[e]
        f_lo, f_hi = 1.0, s_max / size[0]
        # no more growth than the goal needs
        area = math.pi * size[0] * size[1]
        f_hi = min(f_hi, math.sqrt(1.0 + max(goal - placed.area, 0.0) / area))
        if f_hi <= 1.0:
            continue
        for _ in range(12):
            f = 0.5 * (f_lo + f_hi)
            ok, _ = placed.free(c[None], (f * size)[None], np.array([theta]), skip=int(e))
            f_lo, f_hi = (f, f_hi) if ok[0] else (f_lo, f)
        if f_lo > 1.0:
            grown = f_lo * size
            poly = ellipse_polygons(c[None], grown[None], np.array([theta]))[0]
            placed.set(e, c, grown, theta, poly)
        if placed.area >= goal:
            return
