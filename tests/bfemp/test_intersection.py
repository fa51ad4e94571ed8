"""The end-of-step intersection check: head-on disks at huge steps, hand-made crossed states,
the point-in-mesh test against brute force, and the stepper's named failure."""

import numpy as np
import pytest

import bfemp
from bfemp.contact.intersection import (
    fem_cell_J,
    points_inside,
    step_intersection,
    step_inversion,
)
from bfemp.steppers import barrier as barrier_stepper

STIFF = bfemp.NeoHookean(E=1e6, nu=0.3, density=1000.0)


def _disks(h=0.1, speed=20.0, gap=0.2):
    """Two unit disks 'A' (left) and 'B' (right) ``gap`` apart, closing head-on at 2 speed."""
    scene = bfemp.Scene(dim=2)
    c = 0.5 + 0.5 * gap
    a = scene.add_fem(
        bfemp.shapes.disk((-c, 0), 0.5, h=h), material=STIFF, velocity=(speed, 0), name="A"
    )
    b = scene.add_fem(
        bfemp.shapes.disk((c, 0), 0.5, h=h), material=STIFF, velocity=(-speed, 0), name="B"
    )
    scene.set_contact(dhat=1e-3)
    return scene, a, b


def brute_force_inside(model, state):
    """(N + P,) bool: FEM nodes then particles strictly inside a cell of another FEM body, by
    barycentric coordinates of every point in every cell (small scenes only)."""
    body = np.repeat([b.index for b in model.fem_bodies], [b.n_nodes for b in model.fem_bodies])
    pts, owner = state.fem_x, body
    if model.n_particles:
        pts = np.concatenate([pts, state.mpm_x])
        owner = np.concatenate([owner, -1 - model.mpm_particle_body])
    v = state.fem_x[model.fem_cells]  # (C, d + 1, d)
    dm = np.transpose(v[:, 1:] - v[:, :1], (0, 2, 1))
    lam = np.einsum("cij,pcj->pci", np.linalg.inv(dm), pts[:, None, :] - v[None, :, 0])
    bary = np.concatenate([1.0 - lam.sum(axis=2, keepdims=True), lam], axis=2).min(axis=2)
    other = owner[:, None] != model.fem_cell_body[None, :]
    return np.any((bary > 1e-12) & other, axis=1)


# ------------------------------------------------------------------ the reproducer (issue 12)


@pytest.mark.parametrize("dt, h", [(1.0, 0.1), (0.6, 0.1), (1.0, 0.05)])
def test_head_on_disks_never_pass_through_each_other(dt, h):
    """At dt = 1 s the frictionless Newton iterates slid A around B to the free-flight
    prediction (centres at x = +-19.4, every iterate and the end state clear) and the step
    reported CONVERGED. Now the step either keeps the order of the bodies or fails by name."""
    scene, a, b = _disks(h=h)
    sim = bfemp.Simulation(scene, dt=dt)
    start = sim.state.copy()
    try:
        sim.step()
    except bfemp.StepError as err:
        assert err.report.status == "TUNNELED"
        assert "'A'" in err.report.message or "'B'" in err.report.message
        np.testing.assert_array_equal(sim.state.fem_x, start.fem_x)  # left at the start
        return
    assert a.x(sim.state)[:, 0].mean() < b.x(sim.state)[:, 0].mean()
    assert not brute_force_inside(sim.model, sim.state).any()


def test_head_on_disks_at_a_moderate_step_still_converge():
    """dt = 0.5 s: the disks meet and stay apart; the check lets the step through."""
    scene, a, b = _disks()
    sim = bfemp.Simulation(scene, dt=0.5)
    report = sim.step()
    assert report.status == "CONVERGED"
    assert a.x(sim.state)[:, 0].mean() < b.x(sim.state)[:, 0].mean()
    assert not brute_force_inside(sim.model, sim.state).any()
    assert np.isfinite(report.timings["intersection"])


# ------------------------------------------------------------------ hand-made states


def test_check_fires_on_a_hand_made_crossed_end_state():
    """Negative control: B moved 0.3 m into A gives INTERSECTION, naming a point and a body."""
    scene, a, b = _disks()
    model = scene.build()
    start = model.initial_state()
    end = start.copy()
    end.fem_x[b.nodes] -= (0.5, 0.0)  # B overlaps A by 0.3 m
    found = step_intersection(model, start, end)
    assert found is not None and found.status == "INTERSECTION" and found.s == 1.0
    assert found.n_points > 0 and found.body in ("A", "B")
    assert "inside body" in found.message
    assert step_intersection(model, start, start) is None


def test_check_fires_when_only_the_trajectory_crosses():
    """Both ends clear, B jumped from the right of A to its left: TUNNELED at an interior s."""
    scene, a, b = _disks()
    model = scene.build()
    start = model.initial_state()
    end = start.copy()
    end.fem_x[b.nodes] -= (2.4, 0.0)  # B's mirror image on A's left
    assert not brute_force_inside(model, end).any()
    found = step_intersection(model, start, end)
    assert found is not None and found.status == "TUNNELED" and 0.0 < found.s < 1.0


def test_a_sliding_step_past_a_corner_is_a_crossing_only_when_its_chord_cuts_it():
    """A triangle sliding 0.03 m above a block past its corner (1, 1) is clear; the same slide
    ending 0.015 m below the corner's height beside the block cuts the corner on its chord: the
    straight-line motion enters the block, TUNNELED (the depth-thresholded sampling let cuts
    shallower than d-hat through)."""
    scene = bfemp.Scene(dim=2)
    scene.add_fem(bfemp.shapes.rectangle((0, 0), (1, 1), h=0.5), material=STIFF, name="block")
    scene.add_fem(
        np.array([[0.9, 1.03], [1.0, 1.03], [0.95, 1.08]]),
        np.array([[0, 1, 2]]),
        material=STIFF,
        name="tri",
    )
    scene.set_contact(dhat=0.02)
    model = scene.build()
    start = model.initial_state()
    tri = slice(model.fem_bodies[1].nodes.start, None)
    above = start.copy()
    above.fem_x[tri] += (0.11, 0.0)
    assert step_intersection(model, start, above) is None
    cut = start.copy()
    cut.fem_x[tri] += (0.11, -0.045)  # node 0 ends at (1.01, 0.985): beside the block
    assert not brute_force_inside(model, cut).any()
    found = step_intersection(model, start, cut)
    assert found is not None and found.status == "TUNNELED" and 0.0 < found.s < 1.0
    assert {found.body, found.point.split("'")[1]} == {"block", "tri"}


@pytest.mark.parametrize(
    "begin, end, found",
    [
        # slides round the corner: its chord cuts it by 4.75 mm, under min(L / 2, edge / 4)
        ((0.99, 1.0005), (1.0005, 0.99), False),
        ((0.99, 1.0005), (1.02, 1.0005), False),  # past it at a 0.5 mm gap
        # round the corner in one 0.54 m move: the chord cuts 0.14 m deep, over edge / 4
        ((0.8, 1.0005), (1.0005, 0.5), True),
        # from contact on the top straight through the block to below it: the far side
        ((0.5, 1.0005), (0.5, -0.0005), True),
    ],
)
def test_a_particle_round_a_corner_is_a_crossing_when_its_chord_cuts_it(begin, end, found):
    """A particle in contact (0.5 mm, d-hat 1 mm) above the block's top that slides round its
    corner cuts it on the chord by a corner's cut (the solver's iterates went round it): no
    crossing. A cut deeper than the allowance, or a pass to the far side, is TUNNELED."""
    scene = bfemp.Scene(dim=2)
    scene.add_fem(bfemp.shapes.rectangle((0, 0), (1, 1), h=0.5), material=STIFF, name="block")
    scene.add_mpm(np.array([begin]), np.array([1e-6]), material=STIFF, name="blob")
    scene.set_grid(dx=0.25)
    scene.set_contact(dhat=1e-3)
    model = scene.build()
    start = model.initial_state()
    stop = start.copy()
    stop.mpm_x[0] = end
    assert not brute_force_inside(model, stop).any()
    result = step_intersection(model, start, stop)
    assert (result is not None) == found
    if found:
        assert result.status == "TUNNELED" and result.point == "particle 0 of body 'blob'"


def test_equal_aligned_boxes_passing_through_are_tunneled():
    """3D: two equal cubes, one tet wide, swapped along x with every vertex on the other's
    surface during the pass (the sampling needed the cell centroids to see it): the CCD finds
    vertices reaching the other's faces."""
    scene = bfemp.Scene(dim=3)
    scene.add_fem(bfemp.shapes.box((-0.7, 0, 0), (-0.1, 0.6, 0.6), h=0.6), material=STIFF, name="A")
    scene.add_fem(bfemp.shapes.box((0.1, 0, 0), (0.7, 0.6, 0.6), h=0.6), material=STIFF, name="B")
    scene.set_contact(dhat=1e-3)
    model = scene.build()
    start = model.initial_state()
    end = start.copy()
    end.fem_x[model.fem_bodies[0].nodes] += (1.6, 0.0, 0.0)
    end.fem_x[model.fem_bodies[1].nodes] -= (1.6, 0.0, 0.0)
    assert not brute_force_inside(model, end).any()
    found = step_intersection(model, start, end)
    assert found is not None and found.status == "TUNNELED"
    assert found.s == pytest.approx(0.2 / 3.2, rel=1e-6)  # the faces meet at 0.2 m of 3.2 m


def _tet(points):
    """One right-handed tetrahedron (4, 3) and its cell."""
    points = np.asarray(points, dtype=float)
    e = points[1:] - points[0]
    if np.linalg.det(e) < 0:
        points = points[[0, 2, 1, 3]]
    return points, np.array([[0, 1, 2, 3]])


def test_a_crossing_seen_only_by_edge_edge_ccd_3d():
    """3D: a long tet 'A' (vertices at x = +-1) falls through a long thin tet 'B' (vertices at
    y = +-1) so that only their long edges cross: no vertex passes through a face, the end state
    is clear, and edge-edge CCD alone sees it. A miss (A falls beside B) is clear."""
    scene = bfemp.Scene(dim=3)
    a = [(-1, 0, 0.3), (1, 0, 0.3), (-1, 0.1, 0.4), (-1, -0.1, 0.4)]
    b = [(0, -1, 0), (0, 1, 0), (0.05, -1, -0.1), (-0.05, -1, -0.1)]
    scene.add_fem(*_tet(a), material=STIFF, name="A")
    scene.add_fem(*_tet(b), material=STIFF, name="B")
    scene.set_contact(dhat=1e-3)
    model = scene.build()
    start = model.initial_state()
    nodes_a = model.fem_bodies[0].nodes
    through = start.copy()
    through.fem_x[nodes_a] -= (0.0, 0.0, 1.0)  # from 0.3 m above B's edge to 0.7 m below it
    assert not brute_force_inside(model, through).any()
    found = step_intersection(model, start, through)
    assert found is not None and found.status == "TUNNELED"
    assert "edge" in found.point and found.s == pytest.approx(0.3, rel=1e-6)
    beside = start.copy()
    beside.fem_x[nodes_a] += (0.0, 5.0, -1.0)  # A's edge passes z = 0 at y = 1.5: past B's end
    assert step_intersection(model, start, beside) is None


# ------------------------------------------------------------------ thin bodies (issue 44, 1)


def _thin_bar(dhat, mpm=False):
    """Issue 44's reproducer: a disk at 16 m/s onto a free bar 0.088 m thick (< 2 d-hat)."""
    scene = bfemp.Scene(dim=2)
    if mpm:
        particles, volumes = bfemp.sample.mesh(
            bfemp.shapes.disk((0.05, 0.324), 0.08, h=0.02), dx=0.04, ppc=4
        )
        scene.add_mpm(particles, volumes, material=STIFF, velocity=(0.0, -16.0), name="disk")
        scene.set_grid(dx=0.04, origin=(0.005, 0.005))
    else:
        disk = bfemp.shapes.disk((0.05, 0.324), 0.08, h=0.04)
        scene.add_fem(disk, material=STIFF, velocity=(0.0, -16.0), name="disk")
    bar = bfemp.shapes.rectangle((-0.37, -0.044), (0.37, 0.044), h=0.088)
    scene.add_fem(bar, material=STIFF, name="bar")
    scene.set_contact(dhat=dhat, kappa=1e7)
    return scene


def _thin_plate():
    """3D: a cube at 16 m/s onto a free plate 0.08 m thick (d-hat 0.1 m)."""
    scene = bfemp.Scene(dim=3)
    cube = bfemp.shapes.box((-0.06, -0.06, 0.25), (0.06, 0.06, 0.37), h=0.12)
    scene.add_fem(cube, material=STIFF, velocity=(0, 0, -16.0), name="disk")
    plate = bfemp.shapes.box((-0.3, -0.3, -0.04), (0.3, 0.3, 0.04), h=0.3)
    scene.add_fem(plate, material=STIFF, name="bar")
    scene.set_contact(dhat=0.1, kappa=1e7)
    return scene


@pytest.mark.parametrize(
    "scene, dt",
    [
        (lambda: _thin_bar(0.1), 1.45),
        (lambda: _thin_bar(0.1, mpm=True), 1.45),
        (lambda: _thin_bar(0.05, mpm=True), 0.5),
        (_thin_plate, 1.45),
    ],
    ids=["fem_2d", "mpm_2d", "mpm_2d_dhat_0.05", "fem_3d_plate"],
)
def test_a_thin_body_passed_through_is_never_converged(scene, dt):
    """Issue 44, defect 1: the disk (cube) ended 23 m below the bar (plate) and the step said
    CONVERGED, the sampled check counting only points deeper than d-hat, which a body thinner
    than 2 d-hat never holds. Now: TUNNELED, naming the bar, and the state left at the start."""
    sim = bfemp.Simulation(scene(), integrator="backward_euler", dt=dt)
    start = sim.state.copy()
    with pytest.raises(bfemp.StepError) as err:
        sim.step()
    report = err.value.report
    assert report.status == "TUNNELED" and not report.success
    assert "'bar'" in report.message and "'disk'" in report.message
    np.testing.assert_array_equal(sim.state.fem_x, start.fem_x)


def test_the_trajectory_check_finds_a_pass_through_a_bar_of_any_thickness():
    """A point passing through a bar 1e-4 m thick (d-hat 0.1 m) is found, one passing 1e-6 m
    beside its end is not (the CCD's floor is 1e-10 x the coordinates here)."""
    scene = bfemp.Scene(dim=2)
    bar = np.array([[-0.005, 0.0], [0.005, 0.0], [0.005, 1e-4], [-0.005, 1e-4]])
    scene.add_fem(bar, np.array([[0, 1, 2], [0, 2, 3]]), material=STIFF, name="bar")
    scene.add_mpm(np.array([[0.002, 0.5]]), np.array([1e-6]), material=STIFF, name="blob")
    scene.set_grid(dx=0.25)
    scene.set_contact(dhat=0.1)
    model = scene.build()
    start = model.initial_state()
    for x_mid, crossed in ((0.003, True), (0.005 + 1e-6, False)):
        end = start.copy()
        end.mpm_x[0] = (2.0 * x_mid - 0.002, -0.5 + 1e-4)  # through (x_mid, 5e-5) at s = 1/2
        found = step_intersection(model, start, end)
        assert (found is not None) == crossed, x_mid
        if crossed:
            assert found.status == "TUNNELED" and found.s == pytest.approx(0.49995, abs=1e-6)


# ------------------------------------------------------------------ inversion (issue 44, 2)


def test_step_inversion_finds_a_flipped_cell_and_particle():
    """A hand-made state with one FEM cell folded over (J < 0) and one particle with
    det F < 0: INVERTED, naming the smallest J; the rest state has none."""
    scene, a, b = _disks()
    scene.add_mpm(np.array([[0.0, 2.0]]), np.array([1e-4]), material=STIFF, name="blob")
    scene.set_grid(dx=0.25)
    model = scene.build()
    state = model.initial_state()
    assert step_inversion(model, state) is None
    np.testing.assert_allclose(fem_cell_J(model, state.fem_x), 1.0, rtol=1e-12)
    cell = model.fem_cells[3]
    x = state.fem_x
    x[cell[0]] = x[cell[1]] + x[cell[2]] - x[cell[0]]  # mirrored across the opposite edge
    state.mpm_F[0] = np.diag([1.0, -0.5])
    found = step_inversion(model, state)
    J = fem_cell_J(model, x)
    assert found is not None and found.status == "INVERTED"
    assert found.n_cells == int((J <= 0).sum()) >= 1 and found.n_particles == 1
    assert found.min_J == pytest.approx(min(J.min(), -0.5))
    assert "det F <= 0" in found.message


def _box_onto_mpm(speed):
    """2D two_stage: a one-cell-thick soft FEM square (E = 1e5 Pa) falling at ``speed`` onto
    a stiff MPM block (E = 1e7 Pa), dt the CFL step."""
    soft = bfemp.NeoHookean(E=1e5, nu=0.3, density=1000.0)
    hard = bfemp.NeoHookean(E=1e7, nu=0.3, density=1000.0)
    scene = bfemp.Scene(dim=2)
    box = bfemp.shapes.rectangle((0.0, 0.42), (0.4, 0.82), h=0.4)
    scene.add_fem(box, material=soft, velocity=(0.0, -speed), name="A")
    particles, volumes = bfemp.sample.mesh(
        bfemp.shapes.rectangle((0.0, 0.0), (0.4, 0.4), h=0.2), dx=0.1, ppc=4
    )
    scene.add_mpm(particles, volumes, material=hard, name="B")
    scene.set_grid(dx=0.1, origin=(0.0013, 0.0013))
    scene.set_contact(dhat=1e-3, kappa=1e6)
    return scene


def test_two_stage_never_converges_with_an_inverted_cell():
    """Issue 44, defect 2: two_stage stepped a FEM cell to J = -0.0011 (step 18) and said
    CONVERGED. Stage 1's explicit free motion crushes the soft square (J* = -0.0009 at x*) and
    stage 2, which holds no elasticity (no det F filter), follows its energy toward x*. Now
    every converged step has J > 0 and the run fails as INVERTED, not as a crossing."""
    sim = bfemp.Simulation(_box_onto_mpm(89.0), strategy="two_stage", dt="auto")
    for _ in range(30):
        try:
            sim.step()
        except bfemp.StepError as err:
            assert err.report.status == "INVERTED"
            assert "cell 0 of body 'A'" in err.report.message
            return
        assert fem_cell_J(sim.model, sim.state.fem_x).min() > 0.0
    pytest.fail("the square was expected to invert within 30 steps")


@pytest.mark.parametrize("dim", [2, 3])
def test_points_inside_matches_brute_force(dim, rng):
    """Random points against two overlapping meshes: hash + kernel equals brute force."""
    if dim == 2:
        meshes = [bfemp.shapes.disk((0, 0), 0.5, h=0.2), bfemp.shapes.disk((0.4, 0), 0.5, h=0.2)]
    else:
        meshes = [
            bfemp.shapes.box((0, 0, 0), (1, 1, 1), h=0.5),
            bfemp.shapes.box((0.6, 0.2, 0.3), (1.4, 1.0, 1.1), h=0.4),
        ]
    vertices = np.concatenate([m.points for m in meshes])
    offset = meshes[0].points.shape[0]
    cells = np.concatenate([meshes[0].cells, meshes[1].cells + offset])
    cell_body = np.repeat([0, 1], [meshes[0].cells.shape[0], meshes[1].cells.shape[0]])
    lo, hi = vertices.min(axis=0) - 0.1, vertices.max(axis=0) + 0.1
    points = rng.uniform(lo, hi, size=(400, dim))
    point_body = rng.integers(-1, 2, size=400)  # -1: a particle
    got = points_inside(points, point_body, vertices, cells, cell_body)
    v = vertices[cells]
    dm = np.transpose(v[:, 1:] - v[:, :1], (0, 2, 1))
    lam = np.einsum("cij,pcj->pci", np.linalg.inv(dm), points[:, None, :] - v[None, :, 0])
    bary = np.concatenate([1.0 - lam.sum(axis=2, keepdims=True), lam], axis=2).min(axis=2)
    inside = (bary > 1e-12) & (point_body[:, None] != cell_body[None, :])
    np.testing.assert_array_equal(got >= 0, inside.any(axis=1))
    hit = got >= 0
    assert inside[np.flatnonzero(hit), got[hit]].all()
    assert 0 < hit.sum() < 400


def test_stepper_reports_a_crossed_solve_as_intersection(monkeypatch):
    """Wiring: a solve whose end state overlaps (forced here) fails with INTERSECTION instead of
    CONVERGED, and the simulation keeps the start state."""
    scene, a, b = _disks()
    sim = bfemp.Simulation(scene, dt=1e-3)
    write_state = barrier_stepper.write_state

    def crossed(*args, **kwargs):
        new = write_state(*args, **kwargs)
        new.fem_x[b.nodes] -= (0.5, 0.0)
        return new

    monkeypatch.setattr(barrier_stepper, "write_state", crossed)
    with pytest.raises(bfemp.StepError) as err:
        sim.step()
    assert err.value.report.status == "INTERSECTION"
    assert not err.value.report.success
    assert sim.state.t == 0.0


# ------------------------------------------------------------------ cells_containing


@pytest.mark.parametrize("seed", range(4))
def test_cells_containing_is_the_first_deep_enough_cell_of_another_body(seed):
    """Randomised against a test of every (point, cell) pair: overlapping disks of two bodies
    (2D), points scattered over both (some exactly on vertices), three tolerances; the found
    cell is the smallest-index one of another body with every barycentric above tol, and the
    depth is its smallest barycentric coordinate."""
    from bfemp.contact._end_state import cells_containing

    rng = np.random.default_rng(seed)
    a = bfemp.shapes.disk((0.0, 0.0), 0.5, h=0.12)
    b = bfemp.shapes.disk((0.4 + 0.2 * rng.random(), 0.1), 0.5, h=0.1)
    vertices = np.concatenate([a.points, b.points])
    cells = np.concatenate([a.cells, b.cells + a.points.shape[0]])
    cell_body = np.repeat([0, 1], [a.cells.shape[0], b.cells.shape[0]])
    pts = np.concatenate([rng.uniform(-0.6, 1.2, (400, 2)), vertices[::5]])
    owner = rng.integers(-1, 2, pts.shape[0])
    v = vertices[cells]
    dm = np.transpose(v[:, 1:] - v[:, :1], (0, 2, 1))
    lam = np.einsum("cij,pcj->pci", np.linalg.inv(dm), pts[:, None, :] - v[None, :, 0])
    bary = np.concatenate([1.0 - lam.sum(axis=2, keepdims=True), lam], axis=2).min(axis=2)
    other = owner[:, None] != cell_body[None, :]
    for tol in (1e-12, 1e-9, 0.05):
        hit = (bary > tol) & other
        expect = np.where(hit.any(axis=1), hit.argmax(axis=1), -1)
        found, depth = cells_containing(pts, owner, vertices, cells, cell_body, tol)
        np.testing.assert_array_equal(found, expect)
        inside = found >= 0
        assert inside.any() and not inside.all()
        np.testing.assert_allclose(depth[inside], bary[inside, found[inside]], atol=1e-12)
        assert (depth[~inside] == 0.0).all()
