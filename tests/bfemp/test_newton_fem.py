"""Projected Newton on the incremental potential converges quadratically near the solution."""

import numpy as np

import bfemp
from bfemp.scene import Scene
from solvers.newton import minimize
from solvers.options import NewtonOptions
from tests.bfemp.conftest import started_stepper


def test_newton_converges_quadratically_on_a_large_deformation_step():
    mesh = bfemp.shapes.rectangle((0, 0), (2.0, 0.25), h=0.125)
    scene = Scene(dim=2, gravity=(0.0, -9.81))
    scene.add_fem(
        mesh,
        material=bfemp.NeoHookean(E=1e5, nu=0.3, density=1000.0),
        prescribed=bfemp.motion.Fixed(),
        prescribed_nodes=mesh.points[:, 0] < 1e-9,
    )
    model, begun, x0 = started_stepper(scene, dt=1.0)  # quasi-static: large sag
    iterates = []
    result = minimize(
        begun.potential,
        x0.copy(),
        options=NewtonOptions(tol=1e-10, step_scale=1.0, max_iter=100),
        callback=lambda it: iterates.append(it.x),
    )
    assert result.success, result.message
    x_star = result.x
    sag = np.max(np.abs(x_star - x0))
    assert sag > 0.1  # a genuinely nonlinear step
    errors = np.array([np.max(np.abs(x - x_star)) for x in iterates])
    errors = errors[errors > 1e-9 * sag]
    assert errors.size >= 3
    e0, e1, e2 = errors[-3:]
    order = np.log(e2 / e1) / np.log(e1 / e0)
    assert order > 1.7, (errors, order)
