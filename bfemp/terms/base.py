"""The energy contract (ARCHITECTURE.md) and the per-step context every term reads.

| member | contract |
|---|---|
| ``begin_step(ctx)`` | once per time step: refresh x-hat, lagged data, stencils, DOF patterns |
| ``solution_changed(x)`` | once per new iterate (line-search trials too): refresh x-caches |
| ``value(x)``, ``gradient(x)`` | unweighted |
| ``hessian(x, psd)`` | local blocks, projected to PSD per stencil when ``psd``, as COO triplets |
| ``max_step_size(x, p)`` | 1.0 unless the term guards feasibility |

Only ``IncrementalPotential`` sums terms and applies the weight ``2 alpha beta dt^2``
(BFEMP eq. 22).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from bfemp.dofs import DofLayout
from bfemp.model import Model
from bfemp.state import State
from solvers.assembly import Triplets

__all__ = ["StepContext", "Term", "block_pattern"]


@dataclass
class StepContext:
    """What the terms need to know about the step being solved.

    Attributes:
        model: the static model.
        state: the state at the start of the step (t^n).
        dt: time step in s.
        layout: the unknowns of this step.
        fixed_positions: all node positions ``(n_all, d)`` in m whose prescribed entries hold
            their positions at t^{n+1} (free entries are ignored by ``layout.positions``).
        x_hat: inertial prediction ``(n_dof,)`` in m, x^n + dt v^n + alpha (1 - 2 beta) dt^2 a^n.
        dof_mass: lumped mass of each unknown ``(n_dof,)`` in kg.
        mpm: the MPM part of the step (stencils, grid fields, constraints), None without
            particles.
        sliding: ``(s, c)``: every node's sliding over the step is ``s y + c`` (friction,
            BFEMP eq. 37), with ``c (n_all, d)`` in m; None without friction.
    """

    model: Model
    state: State
    dt: float
    layout: DofLayout
    fixed_positions: np.ndarray
    x_hat: np.ndarray
    dof_mass: np.ndarray
    mpm: object | None = None
    sliding: tuple | None = None


class Term(Protocol):
    """One energy of the incremental potential (see the module docstring)."""

    name: str

    def begin_step(self, ctx: StepContext) -> None: ...

    def solution_changed(self, x: np.ndarray) -> None: ...

    def value(self, x: np.ndarray) -> float: ...

    def gradient(self, x: np.ndarray) -> np.ndarray: ...

    def hessian(self, x: np.ndarray, psd: bool) -> Triplets: ...

    def max_step_size(self, x: np.ndarray, p: np.ndarray) -> float: ...


def block_pattern(stencil_dofs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """COO pattern of dense local blocks, prescribed DOFs dropped.

    Args:
        stencil_dofs: global DOF of each local DOF ``(S, n)``, -1 where prescribed.

    Returns:
        ``rows (nnz,)``, ``cols (nnz,)`` and ``keep (S * n * n,)``: the flattened local-block
        entries (row-major per stencil) that survive, so ``vals = blocks.reshape(-1)[keep]``.
    """
    s, n = stencil_dofs.shape
    rows = np.broadcast_to(stencil_dofs[:, :, None], (s, n, n)).reshape(-1)
    cols = np.broadcast_to(stencil_dofs[:, None, :], (s, n, n)).reshape(-1)
    keep = (rows >= 0) & (cols >= 0)
    return (
        np.ascontiguousarray(rows[keep]),
        np.ascontiguousarray(cols[keep]),
        keep,
    )
