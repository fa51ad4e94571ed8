"""The rings quick trajectory under the BLAS of this process (for the BLAS comparison test).

``python -m benchmarks._blas_trajectory OUT.npz [T_END]`` runs the colliding rings of
``benchmarks.rings`` in quick mode (APIC) to ``T_END`` (default 0.04 s: 20 steps, contact from
step 13) and saves the FEM node and particle positions of every step and the name of the BLAS
CHOLMOD ran on; run it in two processes, one with the reference BLAS on ``LD_LIBRARY_PATH``
(``benchmarks._blas_switch.reference_blas_env``), and compare.
"""

from __future__ import annotations

import sys

import numpy as np

import bfemp
from benchmarks import catalogue, rings
from solvers.blas import cholmod_blas
from solvers.linear import CholmodSolver


def trajectory(t_end: float) -> dict:
    """Positions of every step: ``fem_x`` (steps, N, 2), ``mpm_x`` (steps, P, 2), ``blas``."""
    cfg = rings.MODES["quick"]
    sim = bfemp.Simulation(
        catalogue.rings_scene(cfg),
        integrator=rings.INTEGRATOR,
        transfer="apic",
        dt=cfg["dt"],
        tol=rings.TOL,
        # supernodal: the factorisation that runs on BLAS (simplicial would not touch it)
        linear_solver=CholmodSolver(mode="supernodal"),
    )
    fem, mpm = [], []

    def keep(s: bfemp.Simulation) -> None:
        fem.append(s.state.fem_x.copy())
        mpm.append(s.state.mpm_x.copy())

    sim.run(t_end=t_end, progress=False, callback=keep)
    return {"fem_x": np.array(fem), "mpm_x": np.array(mpm), "blas": cholmod_blas().name}


if __name__ == "__main__":
    out = trajectory(float(sys.argv[2]) if len(sys.argv) > 2 else 0.04)
    np.savez(sys.argv[1], **out)
