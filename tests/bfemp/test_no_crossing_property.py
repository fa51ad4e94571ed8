"""Property (issue 12): whatever the shapes, sizes, speeds and dt (1e-4 to 2 s), after every
implicit step no FEM node or particle lies inside another FEM body, and head-on bodies never
swap order, or the step failed with a named status. FEM-FEM and MPM-FEM, 2D and 3D.

Bounded for CI: tiny meshes, a few examples per case, two steps, the default Newton cap.
"""

import os
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

import bfemp
from bfemp.contact.intersection import points_inside, trajectory_crossing
from tests.bfemp.test_intersection import brute_force_inside

MATERIAL = bfemp.NeoHookean(E=1e6, nu=0.3, density=1000.0)
STEPS = 2
NEWTON_CAP = 200  # the default: tunnelling steps need ~100 iterations to reach x-hat
#: random examples on a developer's machine; under CI (CI=true) the same seeded ones every run,
#: so that a submission's CI is reproducible (counterexamples found locally are kept in
#: .hypothesis/ and replayed there first)
SETTINGS = settings(
    max_examples=12,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
    derandomize=bool(os.environ.get("CI")),
)

#: dt log-uniform in [1e-4, 2] s
dts = st.floats(np.log10(1e-4), np.log10(2.0)).map(lambda e: float(10.0**e))


def _shape(dim, centre, size, round_):
    """A coarse disk / square (2D) or cube (3D) of half-width ``size`` around ``centre``."""
    if dim == 2 and round_:
        return bfemp.shapes.disk(tuple(centre), size, h=0.6 * size)
    lo, hi = tuple(centre - size), tuple(centre + size)
    if dim == 2:
        return bfemp.shapes.rectangle(lo, hi, h=size)
    return bfemp.shapes.box(lo, hi, h=2.0 * size)


@st.composite
def cases(draw, dim):
    """Plain parameters (so that failures print readably) of a body 'A' left of a FEM body 'B'."""
    head_on = draw(st.booleans())
    n_lat = dim - 1
    lateral = st.floats(-0.8, 0.8) if not head_on else st.just(0.0)
    v_lat = st.floats(-10.0, 10.0) if not head_on else st.just(0.0)
    return dict(
        size_a=draw(st.floats(0.15, 0.5)),
        size_b=draw(st.floats(0.15, 0.5)),
        gap=draw(st.floats(0.02, 0.5)),
        head_on=head_on,
        lateral=tuple(draw(st.lists(lateral, min_size=n_lat, max_size=n_lat))),
        v_a=(draw(st.floats(0.0, 30.0)), *draw(st.lists(v_lat, min_size=n_lat, max_size=n_lat))),
        v_b=(-draw(st.floats(0.0, 30.0)), *draw(st.lists(v_lat, min_size=n_lat, max_size=n_lat))),
        round_a=draw(st.booleans()),
        round_b=draw(st.booleans()),
    )


def _scene(dim, mpm, c):
    """The scene of case ``c``: 'A' (FEM or MPM) and 'B' (FEM), ``gap`` apart along x."""
    centre_a = np.zeros(dim)
    centre_a[0] = -(c["size_a"] + 0.5 * c["gap"])
    centre_b = np.zeros(dim)
    centre_b[0] = c["size_b"] + 0.5 * c["gap"]
    centre_b[1:] = np.asarray(c["lateral"]) * (c["size_a"] + c["size_b"])
    scene = bfemp.Scene(dim=dim)
    shape_a = _shape(dim, centre_a, c["size_a"], c["round_a"])
    if mpm:
        dx = c["size_a"] if dim == 3 else c["size_a"] / 2.0
        particles, volumes = bfemp.sample.mesh(shape_a, dx=dx, ppc=2**dim)
        scene.add_mpm(particles, volumes, material=MATERIAL, velocity=c["v_a"], name="A")
        scene.set_grid(dx=dx, origin=tuple(np.full(dim, 0.125 * dx)))
    else:
        scene.add_fem(shape_a, material=MATERIAL, velocity=c["v_a"], name="A")
    shape_b = _shape(dim, centre_b, c["size_b"], c["round_b"])
    scene.add_fem(shape_b, material=MATERIAL, velocity=c["v_b"], name="B")
    scene.set_contact(dhat=1e-3)
    return scene


def _head_on(dim, round_, speed):
    """The issue's regime: equal bodies 0.1 m apart closing head-on at 2 x speed."""
    zeros = (0.0,) * (dim - 1)
    return dict(
        size_a=0.3,
        size_b=0.3,
        gap=0.1,
        head_on=True,
        lateral=zeros,
        v_a=(speed, *zeros),
        v_b=(-speed, *zeros),
        round_a=round_,
        round_b=round_,
    )


def _centre_x(model, state, name):
    for body in model.fem_bodies:
        if body.name == name:
            return float(body.x(state)[:, 0].mean())
    for body in model.mpm_bodies:
        if body.name == name:
            return float(state.mpm_x[body.particles, 0].mean())
    raise KeyError(name)


def _stepped(sim) -> bool:
    """One step: True when it converged, False when it failed with a named status (a step may
    refuse, never report a crossing as converged)."""
    try:
        report = sim.step()
    except bfemp.StepError as err:
        status = err.report.status
        assert re.fullmatch(r"[A-Z][A-Z_]+", status) and status != "CONVERGED", status
        return False
    assert report.status == "CONVERGED"
    return True


def _check_run(scene, head_on, dt):
    """Step twice; after each step nothing is inside another body, or the step failed by name."""
    sim = bfemp.Simulation(scene, dt=dt, max_newton_iterations=NEWTON_CAP)
    model = sim.model
    for _ in range(STEPS):
        if not _stepped(sim):
            return
        state = sim.state
        # the library's hash-based check and an all-pairs brute force agree: nothing inside
        assert not brute_force_inside(model, state).any()
        pts = state.fem_x if model.n_particles == 0 else np.concatenate([state.fem_x, state.mpm_x])
        body = np.repeat([b.index for b in model.fem_bodies], [b.n_nodes for b in model.fem_bodies])
        if model.n_particles:
            body = np.concatenate([body, -1 - model.mpm_particle_body])
        hits = points_inside(pts, body, state.fem_x, model.fem_cells, model.fem_cell_body)
        assert (hits < 0).all()
        if head_on:  # a 1D collision: A stays on the left of B
            assert _centre_x(model, state, "A") < _centre_x(model, state, "B")


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("mpm", [False, True], ids=["fem_fem", "mpm_fem"])
def test_no_point_ever_ends_inside_another_body(dim, mpm):
    # the regime of issue 12 (before its fix, these converged with A on the right of B)
    @example(case=_head_on(dim, True, 20.0), dt=0.3)
    @example(case=_head_on(dim, False, 20.0), dt=1.0)
    @SETTINGS
    @given(case=cases(dim), dt=dts)
    def run(case, dt):
        _check_run(_scene(dim, mpm, case), case["head_on"], dt)

    run()


# ------------------------------------------------------------------ thin bodies (issue 44)

#: seeded (derandomised) on every machine: the same examples every run, bounded time
THIN_SETTINGS = settings(
    max_examples=12,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
    derandomize=True,
)
#: dt log-uniform in [1e-3, 2] s
thin_dts = st.floats(np.log10(1e-3), np.log10(2.0)).map(lambda e: float(10.0**e))


@st.composite
def thin_cases(draw):
    """A disk (FEM or MPM) thrown at a free bar thinner than 2 d-hat or not."""
    return dict(
        thickness=draw(st.floats(0.01, 0.1)),
        dhat=draw(st.floats(0.01, 0.12)),
        radius=draw(st.floats(0.05, 0.1)),
        speed=draw(st.floats(2.0, 30.0)),
        angle=draw(st.floats(-0.5, 0.5)),  # rad off the downward vertical
        offset=draw(st.floats(-0.3, 0.3)),  # m, the disk's x
        mpm=draw(st.booleans()),
    )


def _thin_scene(c):
    """The scene of a thin-bar case: the bar 0.74 m long centred at the origin, the disk
    0.15 m above its top."""
    scene = bfemp.Scene(dim=2)
    t, r = c["thickness"], c["radius"]
    centre = (c["offset"], 0.5 * t + r + 0.15)
    v = c["speed"] * np.array([np.sin(c["angle"]), -np.cos(c["angle"])])
    if c["mpm"]:
        dx = 0.5 * r
        particles, volumes = bfemp.sample.mesh(
            bfemp.shapes.disk(centre, r, h=0.25 * r), dx=dx, ppc=4
        )
        scene.add_mpm(particles, volumes, material=MATERIAL, velocity=tuple(v), name="disk")
        scene.set_grid(dx=dx, origin=(0.13 * dx, 0.13 * dx))
    else:
        disk = bfemp.shapes.disk(centre, r, h=0.5 * r)
        scene.add_fem(disk, material=MATERIAL, velocity=tuple(v), name="disk")
    bar = bfemp.shapes.rectangle((-0.37, -0.5 * t), (0.37, 0.5 * t), h=t)
    scene.add_fem(bar, material=MATERIAL, name="bar")
    scene.set_contact(dhat=c["dhat"], kappa=1e7)
    return scene


def _oracle_J(model, state):
    """J of every FEM cell and det F of every particle, by numpy's det (independent)."""
    v = state.fem_x[model.fem_cells]
    ds = np.transpose(v[:, 1:] - v[:, :1], (0, 2, 1))
    rest = model.fem_X[model.fem_cells]
    dm = np.transpose(rest[:, 1:] - rest[:, :1], (0, 2, 1))
    J = np.linalg.det(ds) / np.linalg.det(dm)
    if model.n_particles:
        J = np.concatenate([J, np.linalg.det(state.mpm_F)])
    return J


#: samples of the straight-line motion for the oracle's point-in-cell test
ORACLE_SAMPLES = 64


def test_thin_bodies_are_never_passed_through_silently():
    """Issue 44, property: a disk (FEM or MPM) thrown at a free bar (thinner than 2 d-hat or
    not; dt 1e-3 to 2 s, 2D) either fails by name or ends a step with nothing inside another
    body, no inverted cell or particle, and a straight-line motion that is clear by the library's
    CCD and by an independent oracle: the barycentric point-in-cell test of every FEM node and
    particle at the end and at 64 interior samples of the motion."""

    @THIN_SETTINGS
    @given(case=thin_cases(), dt=thin_dts)
    def run(case, dt):
        sim = bfemp.Simulation(_thin_scene(case), integrator="backward_euler", dt=dt)
        model = sim.model
        for _ in range(STEPS):
            start = sim.state.copy()
            if not _stepped(sim):
                return
            end = sim.state
            assert (_oracle_J(model, end) > 0.0).all()
            assert trajectory_crossing(model, start, end) is None
            for s in np.linspace(0.0, 1.0, ORACLE_SAMPLES + 1)[1:]:
                mid = end.copy()
                mid.fem_x = (1.0 - s) * start.fem_x + s * end.fem_x
                mid.mpm_x = (1.0 - s) * start.mpm_x + s * end.mpm_x
                assert not brute_force_inside(model, mid).any(), s

    run()
