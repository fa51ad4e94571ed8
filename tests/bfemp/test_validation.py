"""Initial-configuration checks of contact scenes: overlap (FEM-FEM, particles in meshes, edges
crossing without any node inside), particles and FEM nodes within dhat of a FEM boundary, 2D
and 3D."""

import numpy as np
import pytest

import bfemp
from bfemp.errors import SceneError
from bfemp.validation import (
    check_clearance,
    check_fem_clearance,
    check_no_overlap,
    validate_initial,
)

NH = bfemp.NeoHookean(E=1e6, nu=0.3, density=1000.0)


def _fem_scene(dim, boxes, h):
    scene = bfemp.Scene(dim=dim)
    for name, (lo, hi) in boxes.items():
        shape = bfemp.shapes.rectangle if dim == 2 else bfemp.shapes.box
        scene.add_fem(shape(lo, hi, h=h), material=NH, name=name)
    return scene


def test_separated_bodies_pass_and_overlapping_ones_are_named():
    apart = {"a": ((0.0, 0.0), (1.0, 1.0)), "b": ((1.01, 0.0), (2.0, 1.0))}
    check_no_overlap(_fem_scene(2, apart, 0.25).build())
    overlap = {"a": ((0.0, 0.0), (1.0, 1.0)), "b": ((0.9, 0.2), (2.0, 0.6))}
    with pytest.raises(
        SceneError, match=r"fem body 'a': mesh: 2 node\(s\) start inside fem body 'b'"
    ):
        check_no_overlap(_fem_scene(2, overlap, 0.25).build())


def test_touching_counts_as_overlap():
    touching = {"a": ((0.0, 0.0), (1.0, 1.0)), "b": ((1.0, 0.0), (2.0, 1.0))}
    with pytest.raises(SceneError, match="inside fem body"):
        check_no_overlap(_fem_scene(2, touching, 0.5).build())


def test_crossing_bars_without_a_node_inside_are_found_in_2d():
    # a plus sign of two bars meshed with one cell along their length: no node of one lies in
    # the other, only their boundary edges cross
    plus = {"horizontal": ((-1.0, -0.05), (1.0, 0.05)), "vertical": ((-0.05, -1.0), (0.05, 1.0))}
    model = _fem_scene(2, plus, 5.0).build()
    with pytest.raises(SceneError, match=r"fem body 'horizontal'.*cross the boundary"):
        check_no_overlap(model)


def test_3d_overlap_and_crossing():
    apart = {"a": ((0.0,) * 3, (1.0,) * 3), "b": ((1.1, 0.0, 0.0), (2.0, 1.0, 1.0))}
    check_no_overlap(_fem_scene(3, apart, 0.5).build())
    overlap = {"a": ((0.0,) * 3, (1.0,) * 3), "b": ((0.5, 0.5, 0.5), (2.0, 2.0, 2.0))}
    with pytest.raises(SceneError, match="inside fem body"):
        check_no_overlap(_fem_scene(3, overlap, 0.5).build())
    plus = {
        "x_bar": ((-1.0, -0.05, -0.05), (1.0, 0.05, 0.05)),
        "y_bar": ((-0.05, -1.0, -0.2), (0.05, 1.0, 0.2)),
    }
    with pytest.raises(SceneError, match="cross the boundary"):
        check_no_overlap(_fem_scene(3, plus, 5.0).build())


def _particle_scene(dim, particle_lower, dhat=None):
    scene = bfemp.Scene(dim=dim)
    lo, hi = (0.0,) * dim, (1.0,) * dim
    shape = bfemp.shapes.rectangle if dim == 2 else bfemp.shapes.box
    scene.add_fem(shape(lo, hi, h=0.5), material=NH, name="floor")
    upper = tuple(c + 0.4 for c in particle_lower)
    x, vol = bfemp.sample.box(particle_lower, upper, dx=0.1, ppc=2**dim)
    scene.add_mpm(x, vol, material=NH, name="blob")
    scene.set_grid(dx=0.1)
    if dhat is not None:
        scene.set_contact(dhat=dhat)
    return scene.build()


@pytest.mark.parametrize("dim", [2, 3])
def test_particles_inside_a_mesh_are_named(dim):
    model = _particle_scene(dim, (0.8,) * dim)
    with pytest.raises(SceneError, match=r"mpm body 'blob': particles: .*inside fem body 'floor'"):
        check_no_overlap(model)


def _refused_at_a_gap_of_25_mm(check, model):
    """``model`` (bodies 0.025 m apart, not overlapping) passes ``check`` with dhat = 0.02 m and
    is refused with 0.03 m, naming the gap; returns the message."""
    check_no_overlap(model)
    check(model, dhat=0.02)
    with pytest.raises(SceneError) as info:
        check(model, dhat=0.03)
    message = str(info.value)
    assert "closest 0.025 m" in message and "0.005 m further apart" in message
    return message


@pytest.mark.parametrize("dim", [2, 3])
def test_particles_within_dhat_are_refused_with_the_distance(dim):
    # the lowest particles sit 0.025 m above the top face y = 1 (or z = 1)
    lower = (0.0,) * (dim - 1) + (1.0,)
    message = _refused_at_a_gap_of_25_mm(check_clearance, _particle_scene(dim, lower))
    assert "mpm body 'blob': particles:" in message and "fem body 'floor'" in message


def test_validate_initial_checks_only_contact_scenes():
    inside = _particle_scene(2, (0.5, 0.5))
    validate_initial(inside)  # no contact: bodies may pass through each other
    with pytest.raises(SceneError, match="inside"):
        validate_initial(_particle_scene(2, (0.5, 0.5), dhat=1e-3))
    close = _particle_scene(2, (0.0, 1.0), dhat=0.05)
    with pytest.raises(SceneError, match="within dhat"):
        validate_initial(close)
    validate_initial(_particle_scene(2, (0.0, 1.0), dhat=0.01))


def test_positions_other_than_the_rest_shape_can_be_checked():
    model = _particle_scene(2, (0.0, 1.2))
    check_no_overlap(model)
    moved = model.mpm_X - np.array([0.0, 0.5])
    with pytest.raises(SceneError, match="inside"):
        check_no_overlap(model, mpm_x=moved)
    with pytest.raises(ValueError, match="mpm_x must have shape"):
        check_no_overlap(model, mpm_x=moved[:3])


@pytest.mark.parametrize("dim", [2, 3])
def test_fem_nodes_within_dhat_of_another_fem_body_are_refused(dim):
    # body "top" starts 0.025 m above the top face of "floor"
    lo, hi = (0.0,) * dim, (1.0,) * dim
    top_lo = (0.25,) * (dim - 1) + (1.025,)
    top_hi = (0.75,) * (dim - 1) + (1.525,)
    model = _fem_scene(dim, {"floor": (lo, hi), "top": (top_lo, top_hi)}, 0.25).build()
    message = _refused_at_a_gap_of_25_mm(check_fem_clearance, model)
    # the gap is symmetric: either body may be named first, with its nodes facing the other
    floor, top = model.fem_bodies
    if message.startswith("fem body 'top': mesh: "):
        assert "of fem body 'floor'" in message
        z = model.fem_X[top.nodes, -1]
        near = np.flatnonzero(z < 1.025 + 1e-9)
    else:
        assert message.startswith("fem body 'floor': mesh: ") and "of fem body 'top'" in message
        x = model.fem_X[floor.nodes]
        near = np.flatnonzero(
            (x[:, -1] > 1.0 - 1e-9) & np.all(np.abs(x[:, :-1] - 0.5) < 0.25 + 1e-9, axis=1)
        )
    assert f"{near.size} node(s) start within dhat = 0.03 m" in message
    assert f"nodes {near[:10].tolist()}" in message


def test_validate_initial_refuses_fem_bodies_within_dhat_unless_both_are_prescribed():
    boxes = {"floor": ((0.0, 0.0), (1.0, 1.0)), "top": ((0.25, 1.025), (0.75, 1.525))}
    scene = _fem_scene(2, boxes, 0.25)
    scene.set_contact(dhat=0.03)
    with pytest.raises(SceneError, match=r"node\(s\) start within dhat = 0.03 m of fem body"):
        validate_initial(scene.build())
    with pytest.raises(SceneError, match="within dhat"):
        bfemp.Simulation(scene, dt=1e-3)
    walls = bfemp.Scene(dim=2)
    for name, (lo, hi) in boxes.items():
        mesh = bfemp.shapes.rectangle(lo, hi, h=0.25)
        walls.add_fem(mesh, material=NH, prescribed=bfemp.motion.Fixed(), name=name)
    walls.set_contact(dhat=0.03)
    validate_initial(walls.build())  # their barrier acts on no unknown
