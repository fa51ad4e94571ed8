"""Analytic signed distance functions for obstacles and containers.

Convention: ``value(x) < 0`` inside the OBSTACLE (the region particles must not enter) and
``> 0`` in free space, in metres; ``normal(x)`` is the unit gradient of the value, pointing into
free space. All classes are frozen dataclasses, work in 2D and 3D and evaluate batches of
points ``x`` (n, d) with vectorised numpy.

- :class:`HalfPlane` (a half-space in 3D): the obstacle lies on the side opposite to ``normal``.
- :class:`Box`: a solid axis-aligned box; exact signed distance (inside: minus the distance to
  the nearest face).
- :class:`Disk`: a solid disk (2D) or ball (3D).
- :class:`Union`: the union of obstacles, ``min`` of the values; the normal is that of the part
  attaining the minimum (exact distance outside all parts, a bound inside overlaps).
- :class:`Inverted`: the complement, ``-value``; ``Inverted(Box(...))`` is a container that keeps
  particles inside a box.

Where the gradient is undefined (the centre of a disk, the medial set of a box, ties of a union)
the normal is that of a consistent choice: the first axis, the first face, the first part.
``HalfPlane``, ``Box`` and ``Disk`` take keyword arguments; the combinators take their parts
positionally (``Union(a, b)``, ``Inverted(a)``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from geometry._checks import positive, vector

__all__ = ["Box", "Disk", "HalfPlane", "Inverted", "LevelSet", "Union"]


@runtime_checkable
class LevelSet(Protocol):
    """Signed distance function: negative inside the obstacle (m), unit normal into free space."""

    @property
    def dim(self) -> int | None:
        """Spatial dimension d, or None when the level set works in any dimension."""
        ...

    def value(self, x: np.ndarray) -> np.ndarray:
        """Signed distance (n,) in m at the points x (n, d) in m."""
        ...

    def normal(self, x: np.ndarray) -> np.ndarray:
        """Unit gradient of the signed distance (n, d) at the points x (n, d) in m."""
        ...


def _vector(owner: str, name: str, value: object, dim: int | None = None) -> tuple[float, ...]:
    """``value`` as a tuple of 2 or 3 (or ``dim``) finite floats, else ValueError naming it."""
    return tuple(float(v) for v in vector(f"{owner}.{name}", value, dim))


def _points(x: np.ndarray, dim: int | None, owner: str) -> np.ndarray:
    """``x`` as a float64 array (n, dim), else ValueError naming the level set."""
    arr = np.asarray(x, dtype=np.float64)
    if arr.ndim != 2 or (dim is not None and arr.shape[1] != dim):
        raise ValueError(f"{owner}: x must have shape (n, {dim}), got {arr.shape}")
    return arr


@dataclass(frozen=True, init=False)
class HalfPlane:
    """Half-plane (2D) / half-space (3D) obstacle ``{x : (x - point) . n < 0}``.

    Constructed as ``HalfPlane(point=..., normal=...)``; the direction is stored normalised as
    ``unit_normal`` because ``normal`` is the level-set method.

    Attributes:
        point: (d,) a point on the boundary plane, m.
        unit_normal: (d,) unit direction into free space.
    """

    point: tuple[float, ...]
    unit_normal: tuple[float, ...]

    def __init__(self, *, point: tuple[float, ...], normal: tuple[float, ...]) -> None:
        pt = _vector("HalfPlane", "point", point)
        direction = np.asarray(_vector("HalfPlane", "normal", normal, len(pt)))
        length = float(np.linalg.norm(direction))
        if not length > 0.0:
            raise ValueError(f"HalfPlane.normal must be non-zero, got {normal!r}")
        object.__setattr__(self, "point", pt)
        object.__setattr__(self, "unit_normal", tuple(float(v) for v in direction / length))

    @property
    def dim(self) -> int:
        """Spatial dimension d."""
        return len(self.point)

    def value(self, x: np.ndarray) -> np.ndarray:
        """Signed distance ``(x - point) . n`` (n,) in m at x (n, d)."""
        pts = _points(x, self.dim, "HalfPlane")
        return (pts - np.asarray(self.point)) @ np.asarray(self.unit_normal)

    def normal(self, x: np.ndarray) -> np.ndarray:
        """The constant unit normal (n, d) at x (n, d)."""
        pts = _points(x, self.dim, "HalfPlane")
        return np.ascontiguousarray(np.broadcast_to(np.asarray(self.unit_normal), pts.shape))


@dataclass(frozen=True, kw_only=True)
class Box:
    """Solid axis-aligned box obstacle ``lower <= x <= upper``.

    Attributes:
        lower: (d,) lower corner, m.
        upper: (d,) upper corner, m; ``upper > lower`` componentwise.
    """

    lower: tuple[float, ...]
    upper: tuple[float, ...]

    def __post_init__(self) -> None:
        lower = _vector("Box", "lower", self.lower)
        upper = _vector("Box", "upper", self.upper, len(lower))
        if not all(u > lo for lo, u in zip(lower, upper, strict=True)):
            raise ValueError(f"Box.upper must exceed Box.lower componentwise, got {upper}")
        object.__setattr__(self, "lower", lower)
        object.__setattr__(self, "upper", upper)

    @property
    def dim(self) -> int:
        """Spatial dimension d."""
        return len(self.lower)

    def _q(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``q = |x - c| - h`` (n, d) with centre c, half-size h, and ``sign(x - c)`` (0 -> +1)."""
        pts = _points(x, self.dim, "Box")
        lower, upper = np.asarray(self.lower), np.asarray(self.upper)
        rel = pts - 0.5 * (lower + upper)
        return np.abs(rel) - 0.5 * (upper - lower), np.where(rel < 0.0, -1.0, 1.0)

    def value(self, x: np.ndarray) -> np.ndarray:
        """Signed distance (n,) in m at x (n, d): ``|max(q, 0)| + min(max_a q_a, 0)``."""
        q, _ = self._q(x)
        return np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)

    def normal(self, x: np.ndarray) -> np.ndarray:
        """Unit outward normal (n, d): towards the nearest point outside, or the nearest face."""
        q, sign = self._q(x)
        outside = np.maximum(q, 0.0)
        length = np.linalg.norm(outside, axis=1)
        inner = np.zeros_like(q)
        inner[np.arange(q.shape[0]), np.argmax(q, axis=1)] = 1.0
        out = np.where(
            (length > 0.0)[:, None], outside / np.maximum(length, 1e-300)[:, None], inner
        )
        return out * sign


@dataclass(frozen=True, kw_only=True)
class Disk:
    """Solid disk (2D) or ball (3D) obstacle ``|x - center| <= radius``.

    Attributes:
        center: (d,) centre, m.
        radius: radius in m, > 0.
    """

    center: tuple[float, ...]
    radius: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", _vector("Disk", "center", self.center))
        object.__setattr__(self, "radius", positive("Disk.radius", self.radius))

    @property
    def dim(self) -> int:
        """Spatial dimension d."""
        return len(self.center)

    def value(self, x: np.ndarray) -> np.ndarray:
        """Signed distance ``|x - center| - radius`` (n,) in m at x (n, d)."""
        pts = _points(x, self.dim, "Disk")
        return np.linalg.norm(pts - np.asarray(self.center), axis=1) - self.radius

    def normal(self, x: np.ndarray) -> np.ndarray:
        """Unit radial direction (n, d) at x (n, d); the first axis at the centre itself."""
        rel = _points(x, self.dim, "Disk") - np.asarray(self.center)
        length = np.linalg.norm(rel, axis=1)
        at_centre = length == 0.0
        rel[at_centre, 0] = 1.0
        length[at_centre] = 1.0
        return rel / length[:, None]


def _common_dim(parts: tuple[LevelSet, ...], owner: str) -> int | None:
    """The dimension shared by all parts that have one (None if none has), else ValueError."""
    dims = {p.dim for p in parts if p.dim is not None}
    if len(dims) > 1:
        raise ValueError(f"{owner} parts have different dimensions {sorted(dims)}")
    return dims.pop() if dims else None


def _check_levelset(owner: str, obj: object, name: str) -> None:
    if not all(callable(getattr(obj, m, None)) for m in ("value", "normal")):
        raise ValueError(f"{owner}: {name} must be a level set with value() and normal()")


@dataclass(frozen=True, init=False)
class Union:
    """Union of obstacles: ``value = min_k parts[k].value``, normal of the minimising part.

    Attributes:
        parts: the level sets, at least one, all of the same dimension.
    """

    parts: tuple[LevelSet, ...]

    def __init__(self, *parts: LevelSet) -> None:
        if not parts:
            raise ValueError("Union.parts must contain at least one level set")
        for k, part in enumerate(parts):
            _check_levelset("Union", part, f"parts[{k}]")
        _common_dim(tuple(parts), "Union")
        object.__setattr__(self, "parts", tuple(parts))

    @property
    def dim(self) -> int | None:
        """Common dimension of the parts (None if no part fixes it)."""
        return _common_dim(self.parts, "Union")

    def _values(self, x: np.ndarray) -> np.ndarray:
        pts = _points(x, self.dim, "Union")
        return np.stack([p.value(pts) for p in self.parts], axis=0)

    def value(self, x: np.ndarray) -> np.ndarray:
        """Minimum of the parts' signed distances (n,) in m at x (n, d)."""
        return self._values(x).min(axis=0)

    def normal(self, x: np.ndarray) -> np.ndarray:
        """Normal (n, d) of the part with the smallest value at each point x (n, d)."""
        pts = _points(x, self.dim, "Union")
        which = np.argmin(self._values(pts), axis=0)
        out = np.empty(pts.shape)
        for k, part in enumerate(self.parts):  # a loop over the parts, not over points
            sel = which == k
            if sel.any():
                out[sel] = part.normal(pts[sel])
        return out


@dataclass(frozen=True)
class Inverted:
    """Complement of a level set: ``value = -levelset.value``, ``normal = -levelset.normal``.

    ``Inverted(Box(lower=..., upper=...))`` is a container: particles stay inside the box.

    Attributes:
        levelset: the level set to invert.
    """

    levelset: LevelSet

    def __post_init__(self) -> None:
        _check_levelset("Inverted", self.levelset, "levelset")

    @property
    def dim(self) -> int | None:
        """Dimension of the inverted level set."""
        return self.levelset.dim

    def value(self, x: np.ndarray) -> np.ndarray:
        """Negated signed distance (n,) in m at x (n, d)."""
        return -self.levelset.value(x)

    def normal(self, x: np.ndarray) -> np.ndarray:
        """Negated normal (n, d) at x (n, d): points into the kept region's interior."""
        return -self.levelset.normal(x)
