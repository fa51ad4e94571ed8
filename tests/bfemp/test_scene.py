"""Scene validation, the terms a scene pays for, DOFs of prescribed nodes, motions."""

import math

import numpy as np
import pytest

import bfemp
from bfemp.scene import Scene

NH = bfemp.NeoHookean(E=1e6, nu=0.3, density=1000.0)
TRI_POINTS = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
TRI_CELLS = np.array([[0, 1, 2], [1, 3, 2]])


@pytest.mark.parametrize(
    "field, kwargs, fragment",
    [
        ("E", dict(E=0.0, nu=0.3, density=1.0), "E"),
        ("E", dict(E=-1.0, nu=0.3, density=1.0), "E"),
        ("nu", dict(E=1.0, nu=0.5, density=1.0), "nu"),
        ("nu", dict(E=1.0, nu=-1.0, density=1.0), "nu"),
        ("density", dict(E=1.0, nu=0.3, density=0.0), "density"),
        ("E", dict(E=float("nan"), nu=0.3, density=1.0), "E"),
    ],
)
@pytest.mark.parametrize("cls", [bfemp.NeoHookean, bfemp.LinearElastic])
def test_bad_material_names_the_field(cls, field, kwargs, fragment):
    with pytest.raises(ValueError, match=fragment):
        cls(**kwargs)


def test_bad_meshes_name_the_body_and_the_field():
    scene = Scene(dim=2)
    inverted = TRI_CELLS.copy()
    inverted[1] = inverted[1, ::-1]
    with pytest.raises(ValueError, match=r"fem body 'plate'.*invert.*1"):
        scene.add_fem(TRI_POINTS, inverted, material=NH, name="plate")
    flat = TRI_POINTS.copy()
    flat[2] = [0.5, 0.0]  # cell 0 collapses onto the x axis
    with pytest.raises(ValueError, match=r"fem body 'plate'.*degenerate.*0"):
        scene.add_fem(flat, TRI_CELLS, material=NH, name="plate")
    nan = TRI_POINTS.copy()
    nan[3, 1] = np.nan
    with pytest.raises(ValueError, match=r"fem body 'plate'.*(NaN|finite)"):
        scene.add_fem(nan, TRI_CELLS, material=NH, name="plate")
    with pytest.raises(ValueError, match=r"fem body 'plate'.*cells"):
        scene.add_fem(TRI_POINTS, TRI_CELLS[:, :2], material=NH, name="plate")
    with pytest.raises(ValueError, match=r"fem body 'plate'.*3D.*2D"):
        scene.add_fem(
            np.zeros((4, 3)) + np.eye(4, 3), np.array([[0, 1, 2, 3]]), material=NH, name="plate"
        )
    with pytest.raises(ValueError, match=r"fem body 'plate'.*velocity"):
        scene.add_fem(TRI_POINTS, TRI_CELLS, material=NH, velocity=(1, 2, 3), name="plate")
    with pytest.raises(ValueError, match=r"fem body 'plate'.*prescribed_nodes"):
        scene.add_fem(
            TRI_POINTS,
            TRI_CELLS,
            material=NH,
            name="plate",
            prescribed=bfemp.motion.Fixed(),
            prescribed_nodes=np.ones(3, bool),
        )
    with pytest.raises(ValueError, match=r"fem body 'plate'.*material"):
        scene.add_fem(TRI_POINTS, TRI_CELLS, material="steel", name="plate")


def test_bad_simulation_arguments_name_the_field():
    scene = Scene(dim=2)
    scene.add_fem(TRI_POINTS, TRI_CELLS, material=NH)
    for dt in (0.0, -1e-3, float("nan")):
        with pytest.raises(ValueError, match="dt"):
            bfemp.Simulation(scene, dt=dt)
    with pytest.raises(ValueError, match="integrator"):
        bfemp.Simulation(scene, dt=1e-3, integrator="rk4")
    with pytest.raises(ValueError, match="strategy"):
        bfemp.Simulation(scene, dt=1e-3, strategy="nope")
    with pytest.raises(ValueError, match="tol"):
        bfemp.Simulation(scene, dt=1e-3, tol=-1.0)


def test_a_scene_pays_only_for_what_it_has():
    plain = Scene(dim=2)
    plain.add_fem(TRI_POINTS, TRI_CELLS, material=NH)
    assert bfemp.Simulation(plain, dt=1e-3).terms == ["inertia", "elasticity[neo_hookean]"]

    heavy = Scene(dim=2, gravity=(0.0, -9.81))
    heavy.add_fem(TRI_POINTS, TRI_CELLS, material=NH)
    heavy.add_fem(
        TRI_POINTS + [3.0, 0.0], TRI_CELLS, material=bfemp.LinearElastic(E=1e6, nu=0.3, density=1.0)
    )
    assert bfemp.Simulation(heavy, dt=1e-3).terms == [
        "inertia",
        "elasticity[neo_hookean]",
        "elasticity[linear]",
        "gravity",
    ]


def test_prescribed_nodes_are_not_unknowns_and_follow_their_motion():
    scene = Scene(dim=2, gravity=(0.0, -9.81))
    mesh = bfemp.shapes.rectangle((0, 0), (1.0, 1.0), h=0.25)
    bottom = mesh.points[:, 1] < 1e-9
    scene.add_fem(
        mesh,
        material=NH,
        prescribed=bfemp.motion.Linear(velocity=(0.5, 0.0)),
        prescribed_nodes=bottom,
    )
    sim = bfemp.Simulation(scene, dt=1e-2)
    assert sim.stepper.layout.n_dof == 2 * int((~bottom).sum())
    for _ in range(3):
        sim.step()
    assert np.allclose(sim.state.fem_x[bottom], mesh.points[bottom] + [0.015, 0.0])
    assert np.allclose(sim.state.fem_v[bottom], [0.5, 0.0])


def test_fully_prescribed_body_has_no_unknowns_and_moves_rigidly():
    scene = Scene(dim=2)
    scene.add_fem(
        TRI_POINTS,
        TRI_CELLS,
        material=NH,
        prescribed=bfemp.motion.Rotation(center=(0.0, 0.0), angular_velocity=1.0),
    )
    sim = bfemp.Simulation(scene, dt=0.1)
    assert sim.stepper.layout.n_dof == 0
    sim.step()
    rot = np.array([[math.cos(0.1), -math.sin(0.1)], [math.sin(0.1), math.cos(0.1)]])
    assert np.allclose(sim.state.fem_x, TRI_POINTS @ rot.T)


def test_motions_velocity_is_the_time_derivative_of_position(rng):
    x0 = rng.standard_normal((5, 3))
    seq = bfemp.motion.Sequence(
        segments=(
            (0.5, bfemp.motion.Linear(velocity=(0.0, 0.0, -0.5))),
            (
                math.inf,
                bfemp.motion.Rotation(center=(0, 0, 0), axis=(0, 0, 2), angular_velocity=0.6),
            ),
        )
    )
    for motion in (
        bfemp.motion.Fixed(),
        bfemp.motion.Linear(velocity=(1.0, 2.0, 3.0)),
        bfemp.motion.Rotation(center=(1, 0, 0), axis=(1, 1, 0), angular_velocity=2.0),
        seq,
    ):
        for tau in (0.2, 0.9, 1.7):
            eps = 1e-6
            fd = (motion.positions(x0, tau + eps) - motion.positions(x0, tau - eps)) / (2 * eps)
            assert np.allclose(fd, motion.velocities(x0, tau), atol=1e-6)
    # the sequence is continuous across its switch and rotates about z after it
    before, after = seq.positions(x0, 0.5 - 1e-9), seq.positions(x0, 0.5 + 1e-9)
    assert np.allclose(before, after, atol=1e-8)
    assert np.allclose(seq.positions(x0, 0.5), x0 + [0, 0, -0.25])
    with pytest.raises(ValueError, match="velocity"):
        bfemp.motion.Linear(velocity=(1.0, float("nan")))
    with pytest.raises(ValueError, match="axis"):
        bfemp.motion.Rotation(center=(0, 0, 0), axis=(0, 0, 0), angular_velocity=1.0)


def test_body_handles_read_their_slice_of_the_state():
    scene = Scene(dim=2)
    a = scene.add_fem(TRI_POINTS, TRI_CELLS, material=NH, name="a", velocity=(1.0, 0.0))
    b = scene.add_fem(TRI_POINTS + [3.0, 0.0], TRI_CELLS, material=NH, name="b")
    x, vol = bfemp.sample.box((0.0, 2.0), (0.5, 2.5), dx=0.25, ppc=4)
    blob = scene.add_mpm(x, vol, material=NH, velocity=(0.0, -1.0), name="blob")
    scene.set_grid(dx=0.25)
    scene.add_load(b, (0.0, -1.0))  # a handle works where an index is expected
    sim = bfemp.Simulation(scene, dt=1e-3)
    assert (a.name, b.name, blob.name) == ("a", "b", "blob")
    assert np.allclose(a.x(sim.state), TRI_POINTS) and np.allclose(a.v(sim.state), [1.0, 0.0])
    assert np.allclose(b.x(sim.state), TRI_POINTS + [3.0, 0.0])
    assert np.allclose(blob.x(sim.state), x) and np.allclose(blob.v(sim.state), [0.0, -1.0])
    assert sim.model.fem_bodies[b].name == "b" and sim.model.mpm_bodies[blob].name == "blob"
