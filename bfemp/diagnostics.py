"""Physical diagnostics of a state: energies, linear and angular momentum.

2D quantities are per unit thickness (J/m, kg m/s/m).
"""

from __future__ import annotations

import numpy as np

from bfemp.model import Model
from bfemp.state import State

__all__ = ["kinetic_energy", "gravity_energy", "load_energy", "linear_momentum", "angular_momentum"]


def kinetic_energy(model: Model, state: State) -> float:
    """1/2 sum_i m_i |v_i|^2 in J over FEM nodes."""
    return 0.5 * float(np.dot(model.fem_mass, np.einsum("ij,ij->i", state.fem_v, state.fem_v)))


def gravity_energy(model: Model, state: State) -> float:
    """-sum_i m_i g . x_i in J (zero reference at the origin)."""
    return -float(np.dot(model.fem_mass, state.fem_x @ model.gravity))


def load_energy(model: Model, state: State) -> float:
    """-sum_i f_i . x_i in J for the constant external nodal forces."""
    return -float(np.sum(model.fem_load * state.fem_x))


def linear_momentum(model: Model, state: State) -> np.ndarray:
    """sum_i m_i v_i ``(d,)`` in kg m/s."""
    return model.fem_mass @ state.fem_v


def angular_momentum(model: Model, state: State) -> np.ndarray:
    """sum_i m_i x_i x v_i about the origin: ``(1,)`` (z) in 2D, ``(3,)`` in 3D, kg m^2/s."""
    x, v, m = state.fem_x, state.fem_v, model.fem_mass
    if model.dim == 2:
        return np.array([float(np.dot(m, x[:, 0] * v[:, 1] - x[:, 1] * v[:, 0]))])
    return m @ np.cross(x, v)
