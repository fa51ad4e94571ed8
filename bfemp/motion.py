"""Prescribed motions for scripted FEM nodes (Dirichlet boundary conditions on positions).

A motion maps the positions of a set of nodes at the time the motion starts, ``x0 (n, d)`` in m,
and the elapsed time ``tau`` in s to their positions ``(n, d)`` and velocities ``(n, d)`` in m/s.
Motions are rigid, so a body whose every node is prescribed moves as a rigid body (section 4.4 of
the BFEMP paper uses such bodies as separable frictional boundaries for MPM).

``Sequence`` chains motions in time (the paper's twist example presses down, then rotates; the sine
boundary goes down, left, then up): each segment starts from the positions where the previous one
ended, and the last segment continues forever.
"""

from __future__ import annotations

import math
from collections.abc import Sequence as _Seq
from dataclasses import dataclass, field

import numpy as np

from geometry._checks import vector

__all__ = ["Motion", "Fixed", "Linear", "Rotation", "Sequence"]


class Motion:
    """Base class: ``positions(x0, tau)`` and ``velocities(x0, tau)``."""

    def positions(self, x0: np.ndarray, tau: float) -> np.ndarray:
        """Positions ``(n, d)`` in m after ``tau`` s, starting from ``x0 (n, d)``."""
        raise NotImplementedError

    def velocities(self, x0: np.ndarray, tau: float) -> np.ndarray:
        """Velocities ``(n, d)`` in m/s at elapsed time ``tau`` s, starting from ``x0 (n, d)``."""
        raise NotImplementedError


@dataclass(frozen=True, kw_only=True)
class Fixed(Motion):
    """Nodes stay where they are."""

    def positions(self, x0: np.ndarray, tau: float) -> np.ndarray:
        """Positions ``(n, d)``: ``x0`` itself."""
        return np.array(x0, dtype=np.float64, copy=True)

    def velocities(self, x0: np.ndarray, tau: float) -> np.ndarray:
        """Velocities ``(n, d)``: zero."""
        return np.zeros_like(np.asarray(x0, dtype=np.float64))


@dataclass(frozen=True)
class Linear(Motion):
    """Translation at a constant ``velocity (d,)`` in m/s: ``Linear((0.0, -0.1))`` or
    ``Linear(velocity=(0.0, -0.1))``."""

    velocity: tuple[float, ...]

    def __post_init__(self) -> None:
        v = vector("Linear.velocity", self.velocity)
        object.__setattr__(self, "velocity", tuple(float(c) for c in v))

    def _v(self, x0: np.ndarray) -> np.ndarray:
        v = np.asarray(self.velocity)
        if v.size != x0.shape[1]:
            raise ValueError(
                f"Linear.velocity has {v.size} components but the nodes are {x0.shape[1]}D"
            )
        return v

    def positions(self, x0: np.ndarray, tau: float) -> np.ndarray:
        """Positions ``x0 + tau v``, shape ``(n, d)``."""
        x0 = np.asarray(x0, dtype=np.float64)
        return x0 + tau * self._v(x0)

    def velocities(self, x0: np.ndarray, tau: float) -> np.ndarray:
        """Velocities ``(n, d)``: ``v`` at every node."""
        x0 = np.asarray(x0, dtype=np.float64)
        return np.broadcast_to(self._v(x0), x0.shape).copy()


def _rotation_matrix(axis: np.ndarray, angle: float, dim: int) -> np.ndarray:
    """Rotation by ``angle`` rad: about the origin in 2D, about unit ``axis (3,)`` in 3D."""
    c, s = math.cos(angle), math.sin(angle)
    if dim == 2:
        return np.array([[c, -s], [s, c]])
    k = axis
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + s * kx + (1.0 - c) * (kx @ kx)


@dataclass(frozen=True)
class Rotation(Motion):
    """Rigid rotation about ``center`` at ``angular_velocity`` rad/s (counter-clockwise positive):
    ``Rotation(center, angular_velocity, axis)``, positional or by keyword.

    In 3D the rotation is about the line through ``center`` along ``axis`` (normalised here);
    in 2D (a 2-component ``center``) ``axis`` is ignored (rotation in the plane): it is not
    checked, and one that is not a non-zero 3-vector is replaced by the default.
    """

    center: tuple[float, ...]
    angular_velocity: float
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)

    def __post_init__(self) -> None:
        c = vector("Rotation.center", self.center)
        if not math.isfinite(self.angular_velocity):
            raise ValueError(
                f"Rotation.angular_velocity must be finite, got {self.angular_velocity!r}"
            )
        try:
            a = np.asarray(self.axis, dtype=np.float64)
        except (TypeError, ValueError):
            a = np.zeros(0)
        norm = float(np.linalg.norm(a)) if a.shape == (3,) else 0.0
        if not (norm > 0.0 and math.isfinite(norm)):
            if c.size == 3:
                raise ValueError(f"Rotation.axis must be a non-zero 3-vector, got {self.axis!r}")
            a, norm = np.array([0.0, 0.0, 1.0]), 1.0  # 2D: the axis is ignored
        object.__setattr__(self, "center", tuple(float(x) for x in c))
        object.__setattr__(self, "axis", tuple(float(x) for x in a / norm))

    def _frame(self, x0: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
        dim = x0.shape[1]
        c = np.asarray(self.center)
        if c.size != dim:
            raise ValueError(f"Rotation.center has {c.size} components but the nodes are {dim}D")
        return c, np.asarray(self.axis), dim

    def positions(self, x0: np.ndarray, tau: float) -> np.ndarray:
        """Positions ``c + R(omega tau)(x0 - c)``, shape ``(n, d)``."""
        x0 = np.asarray(x0, dtype=np.float64)
        c, axis, dim = self._frame(x0)
        rot = _rotation_matrix(axis, self.angular_velocity * tau, dim)
        return c + (x0 - c) @ rot.T

    def velocities(self, x0: np.ndarray, tau: float) -> np.ndarray:
        """Velocities ``omega x (x - c)``, shape ``(n, d)``."""
        x = self.positions(x0, tau)
        c, axis, dim = self._frame(np.asarray(x0, dtype=np.float64))
        r = x - c
        w = self.angular_velocity
        if dim == 2:
            return w * np.column_stack([-r[:, 1], r[:, 0]])
        return w * np.cross(axis, r)


@dataclass(frozen=True)
class Sequence(Motion):
    """Piecewise motion: ``segments`` is a list of ``(duration_s, motion)``, positional or by
    keyword.

    Segment k starts from the positions reached at the end of segment k - 1. After the last finite
    segment ends the last motion continues (give it ``math.inf`` to make that explicit).
    """

    segments: tuple[tuple[float, Motion], ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        if isinstance(self.segments, _Seq) and len(self.segments) == 0:
            raise ValueError("Sequence.segments must hold at least one (duration, motion) pair")
        segs = []
        for k, seg in enumerate(self.segments):
            if len(seg) != 2 or not isinstance(seg[1], Motion):
                raise ValueError(f"Sequence.segments[{k}] must be (duration, Motion), got {seg!r}")
            duration = float(seg[0])
            if not duration > 0.0:
                raise ValueError(f"Sequence.segments[{k}] duration must be > 0, got {seg[0]!r}")
            segs.append((duration, seg[1]))
        object.__setattr__(self, "segments", tuple(segs))

    def _locate(self, x0: np.ndarray, tau: float) -> tuple[np.ndarray, float, Motion]:
        """Start positions, local time and motion of the segment active at ``tau``."""
        x = np.asarray(x0, dtype=np.float64)
        start = 0.0
        for duration, motion in self.segments[:-1]:
            if tau <= start + duration:
                return x, tau - start, motion
            x = motion.positions(x, duration)
            start += duration
        return x, tau - start, self.segments[-1][1]  # the last segment continues forever

    def positions(self, x0: np.ndarray, tau: float) -> np.ndarray:
        """Positions ``(n, d)`` at elapsed time ``tau``."""
        x, local, motion = self._locate(x0, tau)
        return motion.positions(x, local)

    def velocities(self, x0: np.ndarray, tau: float) -> np.ndarray:
        """Velocities ``(n, d)`` at time ``tau`` (a segment's end belongs to that segment)."""
        x, local, motion = self._locate(x0, tau)
        return motion.velocities(x, local)
