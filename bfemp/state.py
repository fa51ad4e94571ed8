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
        carried: strategy-owned arrays by name that travel with the state, so that stepping
            the same state twice gives the same result and a checkpoint resumes bit for bit
            (written as ``state.carried.<name>``). ``"augury"`` keeps its APIC matrices B
            (AUG eq. 21) here: ``"aug_B"`` of the FEM nodes ``(N, d, d)`` in m^2/s (zero off
            the foreground) and ``"aug_Bp"`` of the particles ``(P, d, d)`` in m^2/s (MPM
            foreground; separate from ``mpm_C``). Other strategies carry nothing. A step
            builds a new dict and never writes a carried array in place.
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
    carried: dict[str, np.ndarray] = field(default_factory=dict)

    def copy(self) -> State:
        """A deep copy (arrays and the ``carried`` dict copied)."""
        kwargs = {}
        for f in fields(self):
            value = getattr(self, f.name)
            kwargs[f.name] = value.copy() if isinstance(value, np.ndarray) else value
        kwargs["carried"] = {name: value.copy() for name, value in self.carried.items()}
        return State(**kwargs)

    def arrays(self) -> dict[str, np.ndarray]:
        """All array fields by name, the carried ones as ``carried.<name>`` (for checkpoints
        and comparisons)."""
        out = {
            f.name: getattr(self, f.name)
            for f in fields(self)
            if isinstance(getattr(self, f.name), np.ndarray)
        }
        out.update({f"carried.{name}": value for name, value in self.carried.items()})
        return out
