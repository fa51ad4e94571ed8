"""Physical diagnostics of a state: energies, linear and angular momentum (FEM + MPM).

2D quantities are per unit thickness (J/m, kg m/s/m). With APIC each particle carries, besides
1/2 m_p |v_p|^2, the kinetic energy of its affine velocity 1/2 m_p tr(C_p D_p C_p^T), and its spin
m_p eps : (C_p D_p)^T adds to the angular momentum (D_p = dx^2/4 I for quadratic B-splines): these
are the quantities APIC transfers conserve.
"""

from __future__ import annotations

import numpy as np

from bfemp.model import Model
from bfemp.state import State
from bfemp.terms.elasticity import fem_elastic_groups, stencil_energy

__all__ = [
    "angular_momentum",
    "fem_elastic_energy",
    "gravity_energy",
    "kinetic_energy",
    "linear_momentum",
    "load_energy",
    "mpm_elastic_energy",
]


def _sq(v: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", v, v)


def kinetic_energy(model: Model, state: State, transfer: str = "apic") -> float:
    """1/2 sum m |v|^2 in J over FEM nodes and particles (+ the APIC affine part)."""
    total = np.dot(model.fem_mass, _sq(state.fem_v)) + np.dot(model.mpm_mass, _sq(state.mpm_v))
    if model.n_particles and transfer == "apic":
        c2 = np.einsum("pij,pij->p", state.mpm_C, state.mpm_C)
        total += model.grid.dx**2 / 4.0 * np.dot(model.mpm_mass, c2)
    return 0.5 * float(total)


def gravity_energy(model: Model, state: State) -> float:
    """-sum m g . x in J over FEM nodes and particles (zero reference at the origin)."""
    return -float(
        np.dot(model.fem_mass, state.fem_x @ model.gravity)
        + np.dot(model.mpm_mass, state.mpm_x @ model.gravity)
    )


def load_energy(model: Model, state: State) -> float:
    """-sum_i f_i . x_i in J for the constant external nodal forces."""
    return -float(np.sum(model.fem_load * state.fem_x))


def fem_elastic_energy(model: Model, state: State, groups: list | None = None) -> float:
    """sum_e V_e psi(F_e) in J (J/m in 2D) over the FEM cells that can deform.

    Cells whose every node is scripted are left out (scripted motions are rigid: no energy).
    ``groups``: ``bfemp.terms.fem_elastic_groups(model)``, computed here when None (pass it to
    evaluate many states of one model).
    """
    groups = fem_elastic_groups(model) if groups is None else groups
    return float(sum(stencil_energy(law, st, state.fem_x) for law, st in groups))


def mpm_elastic_energy(model: Model, state: State) -> float:
    """sum_p V_p^0 psi(F_p) in J over the particles."""
    total = 0.0
    for body in model.mpm_bodies:  # a few bodies; vectorised over particles
        sl = body.particles
        n = body.n_particles
        mat = body.material
        psi = mat.law.energy_density(state.mpm_F[sl], np.full(n, mat.mu), np.full(n, mat.lam))
        total += float(np.dot(model.mpm_volume[sl], psi))
    return total


def linear_momentum(model: Model, state: State) -> np.ndarray:
    """sum m v ``(d,)`` in kg m/s over FEM nodes and particles."""
    return model.fem_mass @ state.fem_v + model.mpm_mass @ state.mpm_v


def _cross(x: np.ndarray, v: np.ndarray, m: np.ndarray) -> np.ndarray:
    if x.shape[1] == 2:
        return np.array([float(np.dot(m, x[:, 0] * v[:, 1] - x[:, 1] * v[:, 0]))])
    return m @ np.cross(x, v)


def angular_momentum(model: Model, state: State, transfer: str = "apic") -> np.ndarray:
    """sum m x x v about the origin, ``(1,)`` (z) in 2D or ``(3,)`` in 3D, kg m^2/s.

    With APIC the particles' spin m_p eps : (C_p D_p)^T is included.
    """
    total = _cross(state.fem_x, state.fem_v, model.fem_mass)
    if model.n_particles:
        total = total + _cross(state.mpm_x, state.mpm_v, model.mpm_mass)
        if transfer == "apic":
            B = state.mpm_C * (model.grid.dx**2 / 4.0)  # C D with D = dx^2/4 I
            m = model.mpm_mass
            if model.dim == 2:
                total = total + np.array([float(m @ (B[:, 1, 0] - B[:, 0, 1]))])
            else:
                spin = np.stack(
                    [B[:, 2, 1] - B[:, 1, 2], B[:, 0, 2] - B[:, 2, 0], B[:, 1, 0] - B[:, 0, 1]],
                    axis=1,
                )
                total = total + m @ spin
    return total
