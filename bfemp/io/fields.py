"""The fields a frame of a run shows: per-body VTK blocks with velocity, J, stress, forces."""

from __future__ import annotations

import numpy as np

from bfemp.io.vtk import Block
from bfemp.model import Model
from bfemp.state import State

__all__ = ["frame_blocks"]


def frame_blocks(
    model: Model, state: State, fem_force: np.ndarray, mpm_force: np.ndarray
) -> list[Block]:
    """One VTK block per body: FEM bodies with velocity and contact force ``(N, d)`` per node,
    J and von Mises stress (Pa) per cell; MPM bodies with velocity, J, von Mises stress, volume
    and contact force per particle. Forces in N (N/m in 2D)."""
    blocks = []
    j_cells, von_mises = _cell_stress_fields(model, state)
    for body in model.fem_bodies:
        cells = model.fem_cells[body.cells] - body.nodes.start
        blocks.append(
            Block(
                name=body.name,
                points=state.fem_x[body.nodes],
                cells=cells,
                point_data={
                    "velocity": state.fem_v[body.nodes],
                    "contact_force": fem_force[body.nodes],
                },
                cell_data={"J": j_cells[body.cells], "von_mises": von_mises[body.cells]},
            )
        )
    for body in model.mpm_bodies:
        sl = body.particles
        blocks.append(
            Block(
                name=body.name,
                points=state.mpm_x[sl],
                cells=None,
                point_data={
                    "velocity": state.mpm_v[sl],
                    "J": np.linalg.det(state.mpm_F[sl]),
                    "von_mises": _von_mises(body.material, state.mpm_F[sl]),
                    "volume": model.mpm_volume[sl],
                    "contact_force": mpm_force[sl],
                },
            )
        )
    return blocks


def _von_mises(material: object, F: np.ndarray) -> np.ndarray:
    """Von Mises Cauchy stress ``(n,)`` in Pa of deformation gradients ``(n, d, d)``.

    In 2D (plane strain) the in-plane sqrt(sxx^2 - sxx syy + syy^2 + 3 sxy^2) is reported.
    """
    sigma = material.law.cauchy_stress(F, material.mu, material.lam)
    if F.shape[1] == 2:
        sxx, syy, sxy = sigma[:, 0, 0], sigma[:, 1, 1], sigma[:, 0, 1]
        return np.sqrt(np.maximum(sxx**2 - sxx * syy + syy**2 + 3 * sxy**2, 0.0))
    dev = sigma - np.trace(sigma, axis1=1, axis2=2)[:, None, None] * np.eye(3) / 3.0
    return np.sqrt(1.5 * np.einsum("mij,mij->m", dev, dev))


def _cell_stress_fields(model: Model, state: State) -> tuple[np.ndarray, np.ndarray]:
    """Per-cell J ``(M,)`` and von Mises Cauchy stress ``(M,)`` in Pa."""
    x = state.fem_x[model.fem_cells]  # (M, d+1, d)
    F = np.einsum("mai,maj->mij", x, model.fem_cell_grad)
    vm = np.zeros(F.shape[0])
    for body in model.fem_bodies:  # a few bodies; vectorised over cells
        vm[body.cells] = _von_mises(body.material, F[body.cells])
    return np.linalg.det(F), vm
