"""Small scenes shared by the bfemp tests."""

import numpy as np
import pytest

import bfemp
from bfemp.integrators import BACKWARD_EULER, integrator_from_name
from bfemp.steppers.barrier import BarrierOptions, BarrierStepper


def started_stepper(scene, dt=1e-2, state=None, integrator=BACKWARD_EULER):
    """``(model, phases, x0)``: a barrier step begun from ``state`` (the scene's initial state
    when None) and not taken (``BarrierStepper.phases``), and its start positions."""
    model = scene.build()
    stepper = BarrierStepper(
        model,
        integrator=integrator_from_name(integrator),
        dt=dt,
        options=BarrierOptions(tol=1e-8),
    )
    state = model.initial_state() if state is None else state
    phases = stepper.phases(state)
    return model, phases, phases.x0


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


def particle_block_on_sticky_floor():
    """A 2D scene holding a 0.5 x 0.5 m particle block (E = 1 MPa, 4 particles a 5 cm cell) on
    a sticky floor at y = 0. Returns the scene, the block's material and its particle positions
    (n, 2) in m."""
    scene = bfemp.Scene(dim=2)
    mat = bfemp.NeoHookean(E=1e6, nu=0.2, density=1000.0)
    x, vol = bfemp.sample.box((0.0, 0.0), (0.5, 0.5), dx=0.05, ppc=4)
    scene.add_mpm(x, vol, material=mat)
    scene.set_grid(dx=0.05)
    scene.add_boundary(bfemp.levelset.HalfPlane(point=(0, 0), normal=(0, 1)), "sticky")
    return scene, mat, x


def pressed_block_scene(friction_iterations):
    """A 0.5 m particle block on a sticky floor, pressed and dragged by a scripted FEM plate
    moving at (0.2, -1.0) m/s with mu = 0.5; the lagged-friction loop capped at
    ``friction_iterations`` minimisations."""
    scene, mat, _ = particle_block_on_sticky_floor()
    plate = bfemp.shapes.rectangle((-0.2, 0.52), (0.7, 0.57), h=0.025)
    scene.add_fem(plate, material=mat, prescribed=bfemp.motion.Linear(velocity=(0.2, -1.0)))
    scene.set_contact(
        dhat=1e-3, kappa=1e4, mu=0.5, eps_v=1e-3, friction_iterations=friction_iterations
    )
    return scene


def fd_wrt_F(fn, F, h=1e-6):
    """Central differences of ``fn(F)`` (n, ...) with respect to each entry of F (n, d, d):
    an array (n, ..., d, d) (the first Piola stress of an energy density, or dP/dF of P)."""
    d = F.shape[1]
    out = None
    for k in range(d):
        for m in range(d):
            E = np.zeros((d, d))
            E[k, m] = h
            diff = (fn(F + E) - fn(F - E)) / (2 * h)
            if out is None:
                out = np.empty((*diff.shape, d, d))
            out[..., k, m] = diff
    return out


def block_on_fem_floor(mu=0.2):
    """A 2D MPM block (E = 1 MPa) resting just above a fixed FEM floor, with barrier contact
    (d-hat 5 mm) and friction coefficient ``mu``."""
    mat = bfemp.NeoHookean(E=1e6, nu=0.3, density=1000.0)
    scene = bfemp.Scene(dim=2, gravity=(0.0, -9.81))
    floor = bfemp.shapes.rectangle((-1.0, -0.2), (1.0, 0.0), h=0.1)
    scene.add_fem(floor, material=mat, prescribed=bfemp.motion.Fixed(), name="floor")
    x, vol = bfemp.sample.box((-0.2, 0.0), (0.2, 0.2), dx=0.05, ppc=4)
    scene.add_mpm(x, vol, material=mat, name="block")
    scene.set_grid(dx=0.05)
    scene.set_contact(dhat=5e-3, kappa=1e5, mu=mu)
    return scene
