"""The end-of-step intersection check: head-on disks at huge steps, hand-made crossed states,
the point-in-mesh test against brute force, and the stepper's named failure."""

import numpy as np
import pytest

import bfemp
from bfemp.contact.intersection import points_inside, step_intersection
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


def test_a_sliding_step_past_a_corner_is_not_a_crossing():
    """A node sliding past a convex boundary vertex cuts the corner on the chord by less than
    d-hat: no finding; the same slide cut deeper than d-hat is TUNNELED."""
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
    end = start.copy()
    tri = slice(model.fem_bodies[1].nodes.start, None)
    end.fem_x[tri] += (0.11, -0.045)  # cuts the block's corner (1, 1) by at most 0.015 m
    assert not brute_force_inside(model, end).any()
    assert step_intersection(model, start, end) is None
    found = step_intersection(model, start, end, depth=0.002)
    assert found is not None and found.status == "TUNNELED"


@pytest.mark.parametrize(
    "begin, end, found",
    [((0.99, 1.0005), (1.0005, 0.99), False), ((0.8, 1.0005), (1.0005, 0.5), True)],
)
def test_a_particle_sliding_round_a_corner_may_cut_it(begin, end, found):
    """A particle in contact (0.5 mm, d-hat 1 mm) above the block's top and, at the end of the
    step, beside its right side, cuts the corner on the chord by 4.75 mm: a corner cut, allowed
    up to half its 15 mm move. From 0.2 m left of the corner to 0.5 m down the side, the chord
    cuts 0.14 m deep, beyond the allowance's cap (a quarter of the block's 0.5 m edges):
    TUNNELED."""
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
    result = step_intersection(model, start, stop, spacing=1e-3)  # sampled finely: the criterion
    assert (result is not None) == found
    if found:
        assert result.status == "TUNNELED" and result.point == "particle 0 of body 'blob'"


def test_equal_aligned_boxes_passing_through_are_seen_by_cell_centroids():
    """3D: two equal cubes, one tet wide, swapped along x with every vertex on the other's
    surface during the pass: only the cell centroids see the overlap."""
    scene = bfemp.Scene(dim=3)
    scene.add_fem(bfemp.shapes.box((-0.7, 0, 0), (-0.1, 0.6, 0.6), h=0.6), material=STIFF, name="A")
    scene.add_fem(bfemp.shapes.box((0.1, 0, 0), (0.7, 0.6, 0.6), h=0.6), material=STIFF, name="B")
    scene.set_contact(dhat=1e-3)
    model = scene.build()
    start = model.initial_state()
    end = start.copy()
    end.fem_x[model.fem_bodies[0].nodes] += (1.6, 0.0, 0.0)
    end.fem_x[model.fem_bodies[1].nodes] -= (1.6, 0.0, 0.0)
    found = step_intersection(model, start, end)
    assert found is not None and found.status == "TUNNELED"
    assert "centroid" in found.point


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
