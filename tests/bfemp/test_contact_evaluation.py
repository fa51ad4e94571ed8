"""Contact data apart from contact evaluation (issue 11): collision sets from point stencils, and
stateless barrier and friction evaluation on (pairs, positions, parameters)."""

import numpy as np
import pytest

import bfemp
from bfemp.contact.collision import PointStencils, build_collision_set
from bfemp.contact.evaluation import barrier_energy, barrier_pair_gradients, barrier_pair_hessians
from bfemp.contact.friction import (
    friction_energy,
    friction_pair_gradients,
    lag_contacts,
)
from bfemp.contact.pairs import find_pairs
from tests.bfemp.conftest import started_stepper

MAT = bfemp.NeoHookean(E=1e6, nu=0.3, density=1000.0)
DHAT = 1e-3


def _particle_over_plate(dim, gap=0.3 * DHAT, mu=0.4):
    scene = bfemp.Scene(dim=dim)
    if dim == 2:
        mesh = bfemp.shapes.rectangle((0.0, 0.0), (1.0, 1.0), h=0.5)
        x = np.array([[0.3, 1.0 + gap]])
    else:
        mesh = bfemp.shapes.box((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), h=0.5)
        x = np.array([[0.3, 0.4, 1.0 + gap]])
    scene.add_fem(mesh, material=MAT, prescribed=bfemp.motion.Fixed(), name="plate")
    scene.add_mpm(x, np.full(1, 1e-4 if dim == 2 else 1e-6), material=MAT, name="p")
    scene.set_grid(dx=0.1)
    scene.set_contact(dhat=DHAT, kappa=1e4, mu=mu, eps_v=1e-3)
    return scene


@pytest.mark.parametrize("dim", [2, 3])
def test_particles_as_their_own_stencils_put_collision_points_at_the_particles(dim):
    """The particles-as-DOFs collision set (what two_stage needs): identity stencils over nodes
    numbered after the FEM nodes; the points are the particles themselves."""
    model = _particle_over_plate(dim).build()
    n_fem, n_p = model.n_fem_nodes, model.n_particles
    own = PointStencils(n_fem + np.arange(n_p)[:, None], np.ones((n_p, 1)))
    cs = build_collision_set(model, own)
    nodes = np.concatenate([model.fem_X, model.initial_state().mpm_x])
    pos = cs.positions(nodes)
    np.testing.assert_array_equal(pos[cs.n_fem_points :], model.initial_state().mpm_x)
    np.testing.assert_array_equal(
        pos[: cs.n_fem_points], model.fem_X[cs.nodes[: cs.n_fem_points, 0]]
    )
    pairs = find_pairs(cs, pos, DHAT)
    assert pairs.n_pairs >= 1 and 0 < pairs.min_distance() < DHAT
    with pytest.raises(ValueError, match="rows for 1 particles"):
        build_collision_set(model, PointStencils(np.zeros((2, 1), int), np.ones((2, 1))))
    with pytest.raises(ValueError, match=r"must both be \(P, K\)"):
        PointStencils(np.zeros((1, 2), int), np.ones((1, 3)))


@pytest.mark.parametrize("dim", [2, 3])
def test_stateless_barrier_equals_the_term_and_passes_finite_differences(dim, rng):
    _, begun, x = started_stepper(_particle_over_plate(dim), dt=1e-2)
    bar = begun.barrier
    bar.solution_changed(x)
    cs, pos = bar.collisions, bar.collision_positions(x)
    pairs = find_pairs(cs, pos, DHAT)
    energy = barrier_energy(pairs, pos, cs.omega, DHAT, bar.kappa)
    assert energy == bar.value(x) and energy > 0
    # the per-pair gradient is the derivative of the energy with respect to the points
    grads = barrier_pair_gradients(pairs, pos, cs.omega, DHAT, bar.kappa)
    hess = barrier_pair_hessians(pairs, pos, cs.omega, DHAT, bar.kappa, psd=False)
    g = np.zeros_like(pos)
    for pts, local in grads.values():
        np.add.at(g, pts.reshape(-1), local.reshape(-1, dim))
    direction = rng.standard_normal(pos.shape) * 1e-9
    e_plus = barrier_energy(
        find_pairs(cs, pos + direction, DHAT), pos + direction, cs.omega, DHAT, bar.kappa
    )
    e_minus = barrier_energy(
        find_pairs(cs, pos - direction, DHAT), pos - direction, cs.omega, DHAT, bar.kappa
    )
    fd = (e_plus - e_minus) / 2.0
    assert fd == pytest.approx(float(np.sum(g * direction)), rel=1e-5)
    for pts, h in hess.values():
        assert h.shape == (pts.shape[0], pts.shape[1] * dim, pts.shape[1] * dim)
        np.testing.assert_allclose(h, np.swapaxes(h, 1, 2), atol=1e-9 * np.abs(h).max())


def test_lagging_friction_leaves_the_barrier_alone_and_matches_the_stateless_functions(rng):
    _, begun, x = started_stepper(_particle_over_plate(2), dt=1e-2)
    bar, friction = begun.barrier, begun.friction
    bar.solution_changed(x)
    pairs_before = bar.pairs
    moved = x + 1e-5 * rng.standard_normal(x.size)
    friction.lag(moved)
    assert bar.pairs is pairs_before  # the friction term never changes the barrier's state
    cs = bar.collisions
    pos = bar.collision_positions(moved)
    contacts = lag_contacts(cs, pos, find_pairs(cs, pos, DHAT), DHAT, bar.kappa, 0.4)
    assert contacts.n_contacts == friction.n_contacts >= 1
    friction.solution_changed(moved)
    U = friction._U
    assert friction.value(moved) == friction_energy(contacts, U, friction._eps) / friction._s
    ((pts, local),) = friction_pair_gradients(contacts, U, friction._eps)
    assert local.shape == (pts.shape[0], pts.shape[1] * 2)
    # a negative control: without contacts there is no friction energy or gradient
    lifted = pos.copy()
    lifted[cs.n_fem_points :] += [0.0, 1.0]  # the particle 1 m above the plate
    empty = lag_contacts(cs, lifted, find_pairs(cs, lifted, DHAT), DHAT, bar.kappa, 0.4)
    assert empty.n_contacts == 0 and friction_energy(empty, U, 1e-5) == 0.0


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("swept", [False, True])
def test_candidates_per_body_are_every_overlap_of_different_bodies_in_order(dim, swept, rng):
    """``candidate_pairs`` runs the broad phase once per facet body on the other bodies' points:
    its rows are exactly the brute-force overlaps of all points and facets less the same-body
    ones, sorted as the single-pass broad phase returned them (same pairs, same order)."""
    from bfemp.contact.pairs import candidate_pairs
    from geometry.broadphase import point_simplex_candidates

    scene = bfemp.Scene(dim=dim)
    h = 0.5 if dim == 2 else 0.6
    for name, shift in (("a", 0.0), ("b", 1.05)):
        lo, hi = (shift,) + (0.0,) * (dim - 1), (shift + 1.0,) + (1.0,) * (dim - 1)
        mesh = (bfemp.shapes.rectangle if dim == 2 else bfemp.shapes.box)(lo, hi, h=h)
        scene.add_fem(mesh, material=MAT, name=name)
    x = rng.uniform(0.0, 2.0, size=(40, dim))
    scene.add_mpm(x, np.full(40, 1e-4), material=MAT, name="p")
    scene.set_grid(dx=0.1)
    model = scene.build()
    n_p = model.n_particles
    cs = build_collision_set(
        model, PointStencils(model.n_fem_nodes + np.arange(n_p)[:, None], np.ones((n_p, 1)))
    )
    pos = cs.positions(np.concatenate([model.fem_X, x])) + rng.normal(0.0, 0.02, (cs.n_points, dim))
    end = pos + rng.normal(0.0, 0.1, pos.shape) if swept else None
    nf = cs.n_fem_points
    every = point_simplex_candidates(
        pos,
        pos[:nf],
        cs.facets,
        inflation=0.05,
        points_end=end,
        vertices_end=None if end is None else end[:nf],
        method="brute",
    )
    every = every[np.lexsort((every[:, 1], every[:, 0]))]
    expected = every[cs.point_body[every[:, 0]] != cs.facet_body[every[:, 1]]]
    got = candidate_pairs(cs, pos, 0.05, end)
    assert len(np.unique(cs.facet_body)) == 2 and expected.shape[0] > 10
    np.testing.assert_array_equal(got, expected)


def test_line_search_trials_reuse_one_broad_phase_and_find_the_same_pairs(monkeypatch):
    """From a line search's first backtrack on, the barrier's trials take their candidates from
    one swept broad phase: every trial's pairs equal a fresh broad phase's (points, coefficients,
    distances, bit for bit), and the reuse happens (a frictional disk thrown onto a plate
    backtracks)."""
    import bfemp.contact.term as term_module

    reused = []

    def checked(cs, pos, dhat, candidates=None):  # noqa: ANN001, ANN202
        got = find_pairs(cs, pos, dhat, candidates)
        if candidates is not None:
            fresh = find_pairs(cs, pos, dhat)
            for kind in fresh.points:
                np.testing.assert_array_equal(got.points[kind], fresh.points[kind])
                np.testing.assert_array_equal(got.coef[kind], fresh.coef[kind])
                np.testing.assert_array_equal(got.distance[kind], fresh.distance[kind])
            reused.append(fresh.n_pairs)
        return got

    monkeypatch.setattr(term_module, "find_pairs", checked)
    scene = bfemp.Scene(dim=2, gravity=(0.0, -9.81))
    plate = bfemp.shapes.rectangle((-0.4, -0.05), (0.8, 0.0), h=0.01)
    scene.add_fem(plate, material=MAT, prescribed=bfemp.motion.Fixed(), name="plate")
    x, vol = bfemp.sample.mesh(bfemp.shapes.disk((0.0, 0.12), 0.1, h=0.02), dx=0.02, ppc=4)
    scene.add_mpm(x, vol, material=MAT, velocity=(1.0, -1.0), name="disk")
    scene.set_grid(dx=0.02)
    scene.set_contact(dhat=DHAT, kappa=1e5, mu=0.3)
    sim = bfemp.Simulation(scene, strategy="barrier", dt=2e-3)
    for _ in range(15):
        sim.step()
    assert len(reused) >= 5 and max(reused) > 0
