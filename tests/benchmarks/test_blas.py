"""The optimised BLAS against the reference one: the same Newton trajectories (rings quick), and
a set-up that still works, and says so once, when no optimised BLAS can be installed.

``python tests/benchmarks/test_blas.py OUT.npz [T_END]`` (``_trajectory`` runs it, once per
BLAS) runs the colliding rings of ``benchmarks.rings`` in quick mode (APIC) to ``T_END``
(default 0.04 s: 20 steps, contact from step 13) under the BLAS of its process and saves the FEM
node and particle positions of every step and the name of the BLAS CHOLMOD ran on.
"""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import bfemp
from benchmarks import catalogue, rings
from benchmarks._blas_switch import reference_blas_env
from solvers.blas import cholmod_blas
from solvers.linear import CholmodSolver

ROOT = Path(__file__).resolve().parents[2]


def trajectory(t_end: float) -> dict:
    """Positions of every step: ``fem_x`` (steps, N, 2), ``mpm_x`` (steps, P, 2) in m, ``blas``."""
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


def _trajectory(out: Path, env: dict) -> dict:
    """``trajectory`` in a process of its own under ``env`` (its BLAS), through ``out``."""
    env = dict(env)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
    subprocess.run(
        [sys.executable, __file__, str(out)],
        env=env,
        check=True,
        timeout=600,
        capture_output=True,
    )
    return dict(np.load(out))


def test_optimised_blas_gives_the_reference_trajectories(tmp_path):
    ref_env = reference_blas_env()
    if ref_env is None or not cholmod_blas().optimised:
        pytest.skip("needs both the reference BLAS and an optimised one installed")
    fast = _trajectory(tmp_path / "fast.npz", dict(os.environ))
    ref = _trajectory(tmp_path / "ref.npz", ref_env)
    assert str(fast["blas"]) != "reference" and str(ref["blas"]) == "reference"
    assert fast["fem_x"].shape == ref["fem_x"].shape and fast["fem_x"].shape[0] == 20
    # the rings move (and touch from step 13): a comparison of something that happens
    assert np.abs(fast["fem_x"][-1] - fast["fem_x"][0]).max() > 0.5
    np.testing.assert_allclose(fast["fem_x"], ref["fem_x"], rtol=0.0, atol=1e-10)
    np.testing.assert_allclose(fast["mpm_x"], ref["mpm_x"], rtol=0.0, atol=1e-10)


def _install_openblas(env: dict) -> subprocess.CompletedProcess:
    script = str(ROOT / "tools" / "install_openblas.sh")
    return subprocess.run(["sh", script], env=env, capture_output=True, text=True, timeout=60)


def test_setup_without_openblas_goes_on_and_says_so_once(tmp_path):
    stub = tmp_path / "bin"
    stub.mkdir()
    for tool in ("apt-get", "sudo"):
        (stub / tool).write_text("#!/bin/sh\nexit 100\n")
        (stub / tool).chmod(0o755)
    env = dict(os.environ, PATH=f"{stub}:{os.environ['PATH']}", OPENBLAS_GLOB="/nonexistent/x")
    done = _install_openblas(env)
    assert done.returncode == 0
    warnings = [line for line in done.stdout.splitlines() if line.startswith("warning:")]
    assert len(warnings) == 1
    assert "reference BLAS" in warnings[0]
    # with OpenBLAS present nothing is installed and nothing said
    present = dict(env, OPENBLAS_GLOB=str(ROOT / "tools" / "install_openblas.sh"))
    quiet = _install_openblas(present)
    assert quiet.returncode == 0 and quiet.stdout == ""


if __name__ == "__main__":
    result = trajectory(float(sys.argv[2]) if len(sys.argv) > 2 else 0.04)
    np.savez(sys.argv[1], **result)
