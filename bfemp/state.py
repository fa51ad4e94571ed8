"""The time-varying part of a simulation: positions, velocities, accelerations, time.

Everything static (rest shapes, masses, materials, boundary conditions) lives in ``Model``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

__all__ = ["State"]


def _empty(*shape: int) -> np.ndarray:
    return np.zeros(shape, dtype=np.float64)


@dataclass
class State:
    """Simulation state at time ``t`` (s).

    Attributes:
        t: simulated time in s.
        step: number of completed time steps.
        fem_x: FEM node positions ``(N, d)`` in m.
        fem_v: FEM node velocities ``(N, d)`` in m/s.
        fem_a: FEM node accelerations ``(N, d)`` in m/s^2 (Newmark needs a^n; BFEMP eq. 21).
        mpm_x: particle positions ``(P, d)`` in m.
        mpm_v: particle velocities ``(P, d)`` in m/s.
        mpm_F: particle deformation gradients ``(P, d, d)``.
        mpm_C: APIC affine velocity matrices ``(P, d, d)`` in 1/s.
        mpm_a: particle accelerations ``(P, d)`` in m/s^2 (Newmark; transferred like velocities).
        mpm_Ca: APIC affine acceleration matrices ``(P, d, d)`` in 1/s^2 (Newmark with APIC).
        aug_B: augury APIC matrices B of the FEM nodes ``(N, d, d)`` in m^2/s (``"augury"``,
            AUG eq. 21; zero off the foreground; empty for other strategies).
        aug_Bp: augury APIC matrices B of the particles ``(P, d, d)`` in m^2/s (``"augury"``
            with MPM foreground; separate from ``mpm_C``; empty otherwise).
    """

    t: float
    fem_x: np.ndarray
    fem_v: np.ndarray
    fem_a: np.ndarray
    step: int = 0
    mpm_x: np.ndarray = field(default_factory=lambda: _empty(0, 2))
    mpm_v: np.ndarray = field(default_factory=lambda: _empty(0, 2))
    mpm_F: np.ndarray = field(default_factory=lambda: _empty(0, 2, 2))
    mpm_C: np.ndarray = field(default_factory=lambda: _empty(0, 2, 2))
    mpm_a: np.ndarray = field(default_factory=lambda: _empty(0, 2))
    mpm_Ca: np.ndarray = field(default_factory=lambda: _empty(0, 2, 2))
    aug_B: np.ndarray = field(default_factory=lambda: _empty(0, 2, 2))
    aug_Bp: np.ndarray = field(default_factory=lambda: _empty(0, 2, 2))

    def copy(self) -> State:
        """A deep copy (arrays copied)."""
        kwargs = {}
        for f in fields(self):
            value = getattr(self, f.name)
            kwargs[f.name] = value.copy() if isinstance(value, np.ndarray) else value
        return State(**kwargs)

    def arrays(self) -> dict[str, np.ndarray]:
        """All array fields by name (for checkpoints and comparisons)."""
        return {
            f.name: getattr(self, f.name)
            for f in fields(self)
            if isinstance(getattr(self, f.name), np.ndarray)
        }
