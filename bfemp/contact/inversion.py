"""Inverted FEM cells or particles (det F <= 0) at the end of a step."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bfemp.model import Model
from bfemp.state import State

__all__ = ["Inversion", "fem_cell_J", "step_inversion"]


@dataclass(frozen=True)
class Inversion:
    """Inverted cells or particles at the end of a step (det F <= 0).

    Attributes:
        n_cells: FEM cells with J = det F <= 0.
        n_particles: MPM particles with det F_p <= 0.
        min_J: the smallest J over both (dimensionless).
        where: ``"cell i of body 'A'"`` or ``"particle i of body 'B'"`` of that J.
    """

    n_cells: int
    n_particles: int
    min_J: float
    where: str

    status = "INVERTED"

    @property
    def message(self) -> str:
        """Human-readable outcome for a step report."""
        return (
            f"{self.n_cells} FEM cell(s) and {self.n_particles} particle(s) inverted (det F <= 0)"
            f" at the end of the step, smallest J = {self.min_J:.3g} at {self.where}"
        )


def fem_cell_J(model: Model, fem_x: np.ndarray) -> np.ndarray:
    """J = det F ``(M,)`` of every FEM cell at node positions ``fem_x (N, d)``: the cell's signed
    volume over its rest volume (linear simplices, BFEMP eq. 24: F = Ds Dm^-1)."""
    v = fem_x[model.fem_cells]
    e = v[:, 1:] - v[:, :1]  # (M, d, d): rows x_a - x_0
    if model.dim == 2:
        det = e[:, 0, 0] * e[:, 1, 1] - e[:, 0, 1] * e[:, 1, 0]
        return det / (2.0 * model.fem_cell_volume)
    det = np.einsum("ij,ij->i", e[:, 0], np.cross(e[:, 1], e[:, 2]))
    return det / (6.0 * model.fem_cell_volume)


def step_inversion(model: Model, end: State) -> Inversion | None:
    """Inverted FEM cells (J <= 0, :func:`fem_cell_J`) or particles (det F_p <= 0) at the end of
    a step, or None. For the strategies that keep J > 0 (the barrier's det F line-search filter,
    section 5), checked after every step before any crossing: an inverted cell is a failure of
    its own, whose vertices may also stick out into another body."""
    J_cells = fem_cell_J(model, end.fem_x) if model.fem_cells.shape[0] else np.zeros(0)
    J_part = np.linalg.det(end.mpm_F) if model.n_particles else np.zeros(0)
    bad_c = np.flatnonzero(~(J_cells > 0.0))
    bad_p = np.flatnonzero(~(J_part > 0.0))
    if bad_c.size == 0 and bad_p.size == 0:
        return None
    jc = float(np.nanmin(J_cells[bad_c])) if bad_c.size else np.inf
    jp = float(np.nanmin(J_part[bad_p])) if bad_p.size else np.inf
    if bad_c.size and (jc <= jp or not bad_p.size):
        c = int(bad_c[np.argmin(np.nan_to_num(J_cells[bad_c], nan=-np.inf))])
        owner = model.fem_bodies[int(model.fem_cell_body[c])]
        where, J = f"cell {c - owner.cells.start} of body {owner.name!r}", J_cells[c]
    else:
        p = int(bad_p[np.argmin(np.nan_to_num(J_part[bad_p], nan=-np.inf))])
        owner = model.mpm_bodies[int(model.mpm_particle_body[p])]
        where, J = f"particle {p - owner.particles.start} of body {owner.name!r}", J_part[p]
    return Inversion(int(bad_c.size), int(bad_p.size), float(J), where)
