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
    assert sim.stepper.phases(sim.state).layout.n_dof == 2 * int((~bottom).sum())
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
    assert sim.stepper.phases(sim.state).layout.n_dof == 0
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


# --------------------------------------------------------------------------- issue 12 (inputs)
def _meshio_with_unused_point():
    """A 1 x 0.2 rectangle as a meshio mesh whose point 0 is used by no cell (a Gmsh arc centre),
    and the file indices of its left edge x = 0."""
    import meshio

    mesh = bfemp.shapes.rectangle((0.0, 0.0), (1.0, 0.2), h=0.1)
    pts = np.vstack([[0.5, 0.5], mesh.points])
    pts = np.hstack([pts, np.zeros((pts.shape[0], 1))])
    raw = meshio.Mesh(pts, [("triangle", mesh.cells + 1)])
    return raw, 1 + np.flatnonzero(mesh.points[:, 0] < 1e-9)


def test_prescribed_indices_of_a_mesh_with_an_unused_point_use_the_file_numbering():
    raw, left = _meshio_with_unused_point()
    scene = Scene(dim=2)
    fixed = bfemp.motion.Fixed()
    body = scene.add_fem(raw, material=NH, prescribed=fixed, prescribed_nodes=left, name="plate")
    model = scene.build()
    expected = model.fem_X[:, 0] < 1e-9  # the left edge, found by position
    assert expected.sum() == left.size == 3
    np.testing.assert_array_equal(model.fem_prescribed, expected)
    # a mask and per-node velocities with one entry per point of the file are translated too
    mask = np.zeros(raw.points.shape[0], bool)
    mask[left] = True
    v = np.zeros((raw.points.shape[0], 2))
    v[:, 0] = raw.points[:, 0]  # v_x = x
    other = Scene(dim=2)
    other.add_fem(raw, material=NH, prescribed=fixed, prescribed_nodes=mask, velocity=v)
    again = other.build()
    np.testing.assert_array_equal(again.fem_prescribed, expected)
    np.testing.assert_allclose(again.fem_v0[~expected, 0], again.fem_X[~expected, 0])
    # loads take the same numbering
    scene.add_load(body, (0.0, -1.0), nodes=left + 1)
    loaded = scene.build().fem_load[:, 1] < 0
    np.testing.assert_array_equal(np.flatnonzero(loaded), np.flatnonzero(expected) + 1)


def test_indices_of_a_pruned_point_are_refused_naming_the_index():
    raw, left = _meshio_with_unused_point()
    fixed = bfemp.motion.Fixed()
    with pytest.raises(ValueError, match=r"fem body 'plate': prescribed_nodes .*\[0\].*meshio"):
        Scene(dim=2).add_fem(
            raw, material=NH, prescribed=fixed, prescribed_nodes=[0, *left], name="plate"
        )
    mask = np.zeros(raw.points.shape[0], bool)
    mask[0] = True
    with pytest.raises(ValueError, match=r"prescribed_nodes mask entries \[0\].*no cell uses"):
        Scene(dim=2).add_fem(raw, material=NH, prescribed=fixed, prescribed_nodes=mask)
    n_file = raw.points.shape[0]
    with pytest.raises(ValueError, match=rf"must lie in \[0, {n_file}\)"):
        Scene(dim=2).add_fem(raw, material=NH, prescribed=fixed, prescribed_nodes=[n_file])


def _long_plate():
    """Two triangles of 0.2 m^2 each making a 40 m x 0.01 m plate (aspect ratio ~ 2000)."""
    points = np.array([[0.0, 0.0], [40.0, 0.0], [40.0, 0.01], [0.0, 0.01]])
    return points, np.array([[0, 1, 2], [0, 2, 3]])


def test_a_fully_prescribed_plate_of_slivers_is_accepted():
    points, cells = _long_plate()
    scene = Scene(dim=2)
    scene.add_fem(points, cells, material=NH, prescribed=bfemp.motion.Fixed(), name="plate")
    model = scene.build()
    np.testing.assert_allclose(model.fem_cell_volume, [0.2, 0.2])
    # it works as a floor: a block dropped on it comes within dhat, never through, and bounces
    block = bfemp.shapes.rectangle((10.0, 0.02), (10.2, 0.22), h=0.1)
    scene.add_fem(block, material=NH, velocity=(0.0, -1.0), name="block")
    scene.set_contact(dhat=5e-3, kappa=1e6)
    sim = bfemp.Simulation(scene, dt=5e-3)
    lowest = []
    sim.run(
        t_end=0.05, progress=False, callback=lambda s: lowest.append(s.state.fem_x[4:, 1].min())
    )
    assert 0.01 < min(lowest) < 0.01 + 5e-3
    assert sim.state.fem_v[4:, 1].mean() > 0.0
    np.testing.assert_array_equal(sim.state.fem_x[:4], points)
    # inverted and zero-area cells are still refused for a prescribed body
    flat = points.copy()
    flat[2] = [20.0, 0.0]  # cell 0 collapses
    with pytest.raises(ValueError, match=r"fem body 'plate'.*zero.*area"):
        Scene(dim=2).add_fem(
            flat, cells, material=NH, prescribed=bfemp.motion.Fixed(), name="plate"
        )
    mixed = cells.copy()
    mixed[1] = mixed[1, ::-1]
    with pytest.raises(ValueError, match=r"fem body 'plate'.*inverted.*\[1\]"):
        Scene(dim=2).add_fem(
            points, mixed, material=NH, prescribed=bfemp.motion.Fixed(), name="plate"
        )


def test_a_deformable_body_of_slivers_is_refused_naming_the_aspect_ratio():
    points, cells = _long_plate()
    for nodes in (None, np.array([0, 3])):  # free, and only its left end clamped
        motion = None if nodes is None else bfemp.motion.Fixed()
        with pytest.raises(ValueError) as info:
            Scene(dim=2).add_fem(
                points, cells, material=NH, prescribed=motion, prescribed_nodes=nodes, name="plate"
            )
        message = str(info.value)
        assert message.startswith("fem body 'plate': ") and "aspect ratio up to" in message
        assert "not the area" in message and "indices [0, 1]" in message


def test_a_clockwise_mesh_is_flipped_and_logged(caplog):
    import logging

    mesh = bfemp.shapes.rectangle((0.0, 0.0), (1.0, 0.5), h=0.25)
    clockwise = mesh.cells[:, [0, 2, 1]]
    scene = Scene(dim=2)
    with caplog.at_level(logging.INFO, logger="bfemp.scene"):
        body = scene.add_fem(mesh.points, clockwise, material=NH, name="cw")
    assert "fem body 'cw': all 16 cells are clockwise; flipped" in caplog.text
    model = scene.build()
    assert np.all(model.fem_cell_volume > 0)
    np.testing.assert_allclose(model.fem_cell_volume.sum(), 0.5)
    # the boundary is outward: the body is on the left of every boundary edge
    edges = body.boundary
    d = model.fem_X[edges[:, 1]] - model.fem_X[edges[:, 0]]
    mid = model.fem_X[edges].mean(axis=1)
    outward = np.column_stack([d[:, 1], -d[:, 0]])
    assert np.all(np.einsum("ij,ij->i", mid - [0.5, 0.25], outward) > 0)


def test_an_empty_prescribed_selection_is_refused():
    for nodes in (np.zeros(4, bool), np.array([], dtype=np.int64), []):
        with pytest.raises(ValueError, match=r"fem body 'plate': prescribed_nodes selects no"):
            Scene(dim=2).add_fem(
                TRI_POINTS,
                TRI_CELLS,
                material=NH,
                prescribed=bfemp.motion.Fixed(),
                prescribed_nodes=nodes,
                name="plate",
            )


def test_unclear_inputs_get_messages_naming_the_field_and_the_allowed_values():
    expected = r"fem body 'p': cells .*tetrahedra.*scene is 2D.*\(m, 3\)"
    with pytest.raises(ValueError, match=expected) as info:
        Scene(dim=2).add_fem(TRI_POINTS, np.array([[0, 1, 2, 3]]), material=NH, name="p")
    assert "TetMesh" not in str(info.value)
    with pytest.raises(ValueError, match=r"kappa .* or the string 'auto'.*'automatic'"):
        Scene(dim=2).set_contact(dhat=1e-3, kappa="automatic")
    scene = Scene(dim=2)
    scene.add_fem(TRI_POINTS, TRI_CELLS, material=NH)
    x, vol = bfemp.sample.box((0.0, 2.0), (0.5, 2.5), dx=0.25, ppc=4)
    blob = scene.add_mpm(x, vol, material=NH, name="blob")
    scene.set_grid(dx=0.25)
    with pytest.raises(ValueError, match=r"loads act on FEM bodies only.*'blob' is an MPM body"):
        scene.add_load(blob, (0.0, -1.0))
    with pytest.raises(ValueError, match=r"^Simulation.tol must be > 0") as info:
        bfemp.Simulation(scene, dt=1e-3, tol=0)
    assert "NewtonOptions" not in str(info.value)
    with pytest.raises(ValueError, match=r"^Simulation.max_newton_iterations must be an integer"):
        bfemp.Simulation(scene, dt=1e-3, max_newton_iterations=0)


def test_the_rotation_axis_is_ignored_in_2d_only():
    rot = bfemp.motion.Rotation(center=(0.0, 0.0), angular_velocity=1.0, axis=(0.0, 0.0, 0.0))
    x0 = np.array([[1.0, 0.0]])
    np.testing.assert_allclose(rot.positions(x0, math.pi / 2), [[0.0, 1.0]], atol=1e-15)
    with pytest.raises(ValueError, match="Rotation.axis must be a non-zero 3-vector"):
        bfemp.motion.Rotation(center=(0, 0, 0), axis=(0, 0, 0), angular_velocity=1.0)


def test_run_refuses_an_end_time_before_the_current_time():
    scene = Scene(dim=2)
    scene.add_fem(TRI_POINTS, TRI_CELLS, material=NH)
    sim = bfemp.Simulation(scene, dt=0.01)
    with pytest.raises(ValueError, match=r"t_end = -1 s is earlier than the current time t = 0"):
        sim.run(t_end=-1, progress=False)
    sim.run(t_end=0.03, progress=False)
    with pytest.raises(ValueError, match=r"t_end = 0.01 s is earlier .* t = 0.03 s"):
        sim.run(t_end=0.01, progress=False)
    assert sim.state.step == 3
    sim.run(t_end=sim.state.t, progress=False)  # nothing to do, not an error
    assert sim.state.step == 3


# --------------------------------------------------------------------------- issue 42 (API)
def test_motions_take_their_fields_positionally_as_the_readme_writes_them():
    # issue 42: Linear(v) raised a bare TypeError (keyword-only dataclasses)
    x0 = np.array([[0.0, 0.0], [1.0, 2.0]])
    linear = bfemp.motion.Linear((0.0, -0.1))
    assert linear == bfemp.motion.Linear(velocity=(0.0, -0.1))
    assert np.allclose(linear.positions(x0, 2.0), x0 + [0.0, -0.2])
    rotation = bfemp.motion.Rotation((0.0, 0.0), math.pi / 2)
    assert rotation == bfemp.motion.Rotation(center=(0.0, 0.0), angular_velocity=math.pi / 2)
    assert np.allclose(rotation.positions(x0, 1.0), [[0.0, 0.0], [-2.0, 1.0]])
    sequence = bfemp.motion.Sequence(((1.0, linear), (math.inf, bfemp.motion.Fixed())))
    assert np.allclose(sequence.positions(x0, 5.0), x0 + [0.0, -0.1])


def test_add_load_takes_a_body_name_like_set_friction():
    def scene_with(load_body):
        scene = Scene(dim=2)
        scene.add_fem(TRI_POINTS, TRI_CELLS, material=NH, name="a")
        b = scene.add_fem(TRI_POINTS + [3.0, 0.0], TRI_CELLS, material=NH, name="plate")
        x, vol = bfemp.sample.box((0.0, 2.0), (0.5, 2.5), dx=0.25, ppc=4)
        scene.add_mpm(x, vol, material=NH, name="blob")
        scene.set_grid(dx=0.25)
        scene.add_load(b if load_body is None else load_body, (0.0, -1.0), nodes=[1, 3])
        return scene.build()

    by_name, by_handle = scene_with("plate"), scene_with(None)
    assert np.array_equal(by_name.fem_load, by_handle.fem_load)
    assert by_name.fem_load[4 + 1, 1] == -1.0 and by_name.fem_load[:4].sum() == 0.0
    with pytest.raises(ValueError, match=r"add_load: no FEM body named 'plat' .*'a', 'plate'"):
        scene_with("plat")
    with pytest.raises(ValueError, match=r"loads act on FEM bodies only.*'blob' is an MPM body"):
        scene_with("blob")
