"""Small scenes shared by the bfemp tests."""

import numpy as np
import pytest

import bfemp
from bfemp.integrators import BACKWARD_EULER, integrator_from_name
from bfemp.steppers.barrier import BarrierOptions, BarrierStepper


def started_stepper(scene, dt=1e-2, state=None, integrator=BACKWARD_EULER):
    """An implicit stepper whose potential has begun a step from the scene's initial state."""
    model = scene.build()
    stepper = BarrierStepper(
        model,
        integrator=integrator_from_name(integrator),
        dt=dt,
        options=BarrierOptions(tol=1e-8),
    )
    state = model.initial_state() if state is None else state
    x = stepper.begin_step(state)
    return model, stepper, x


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


def block_scene(dim, material, *, prescribed_bottom=True, gravity=True, h=0.5):
    """A 2 x 1 (x 1) m block, optionally with its bottom nodes fixed."""
    g = (0.0, -9.81) if dim == 2 else (0.0, 0.0, -9.81)
    scene = bfemp.Scene(dim=dim, gravity=g if gravity else None)
    if dim == 2:
        mesh = bfemp.shapes.rectangle((0.0, 0.0), (2.0, 1.0), h=h)
    else:
        mesh = bfemp.shapes.box((0.0, 0.0, 0.0), (2.0, 1.0, 1.0), h=h)
    kwargs = {}
    if prescribed_bottom:
        kwargs = dict(
            prescribed=bfemp.motion.Linear(velocity=(0.1,) + (0.0,) * (dim - 1)),
            prescribed_nodes=mesh.points[:, dim - 1] < 1e-9,
        )
    scene.add_fem(mesh, material=material, name="block", **kwargs)
    return scene
