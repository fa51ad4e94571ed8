"""The explicit engine and ``single_field``: free fall, conservation, sticking, CFL, boundaries."""

import numpy as np
import pytest

import bfemp
from bfemp.integrators import SYMPLECTIC_EULER, integrator_from_name
from bfemp.mpm.transfer import g2p_explicit, grid_to_particles, p2g_with_forces, particles_to_grid
from bfemp.steppers import STRATEGIES, StepError, stepper_class
from bfemp.steppers.base import Stepper, options_from_mapping
from bfemp.steppers.single_field import SingleFieldOptions, SingleFieldStepper
from bfemp.steppers.stable_dt import _fastest_particle, cell_altitudes
from bfemp.terms import fem_elastic_groups, stencil_energy
from geometry.grid import particle_stencils
from tests.bfemp.conftest import started_stepper

SOFT = bfemp.NeoHookean(E=1e4, nu=0.3, density=1000.0)
G = np.array([0.0, -9.81])


def _stepper(scene, dt="auto", transfer="apic", **options):
    model = scene.build()
    stepper = SingleFieldStepper(
        model,
        integrator="symplectic_euler",
        transfer=transfer,
        dt=dt,
        options=SingleFieldOptions(**options),
    )
    return model, stepper, stepper.initialize(model.initial_state())


def _block(scene, lower, upper, dx, velocity, name, ppc=4):
    x, vol = bfemp.sample.box(lower, upper, dx=dx, ppc=ppc)
    return scene.add_mpm(x, vol, material=SOFT, velocity=velocity, name=name)


# ---------------------------------------------------------------------------- free fall
@pytest.mark.parametrize("transfer", ["apic", "pic", "flip"])
def test_mpm_free_fall_centre_of_mass_is_the_symplectic_euler_recursion(transfer):
    scene = bfemp.Scene(dim=2, gravity=tuple(G))
    v0 = np.array([1.0, 0.5])
    _block(scene, (0.0, 0.0), (0.5, 0.5), 0.05, v0, "block")
    scene.set_grid(dx=0.05)
    model, stepper, state = _stepper(scene, transfer=transfer)
    m = model.mpm_mass
    com, v = m @ state.mpm_x / m.sum(), v0.copy()
    for _ in range(30):
        state, report = stepper.step(state)
        v = v + stepper.dt * G  # v^{n+1/2} = v^{n-1/2} + dt g; x^{n+1} = x^n + dt v^{n+1/2}
        com = com + stepper.dt * v
    assert report.status == "EXPLICIT" and report.success
    assert np.allclose(m @ state.mpm_v / m.sum(), v, rtol=0.0, atol=1e-12)
    assert np.allclose(m @ state.mpm_x / m.sum(), com, rtol=0.0, atol=1e-12)


def test_fem_free_fall_centre_of_mass_is_the_symplectic_euler_recursion():
    scene = bfemp.Scene(dim=2, gravity=tuple(G))
    mesh = bfemp.shapes.rectangle((0.0, 0.0), (1.0, 0.5), h=0.1)
    v0 = np.array([0.3, 2.0])
    scene.add_fem(mesh, material=SOFT, velocity=v0, name="slab")
    model, stepper, state = _stepper(scene)
    m = model.fem_mass
    com, v = m @ state.fem_x / m.sum(), v0.copy()
    for _ in range(50):
        state, _ = stepper.step(state)
        v = v + stepper.dt * G
        com = com + stepper.dt * v
    assert np.allclose(m @ state.fem_v / m.sum(), v, rtol=0.0, atol=1e-12)
    assert np.allclose(m @ state.fem_x / m.sum(), com, rtol=0.0, atol=1e-12)


# ---------------------------------------------------------------------------- collision
def _collision_scene():
    """Two soft blocks approaching at 2 m/s, offset vertically (non-zero angular momentum)."""
    scene = bfemp.Scene(dim=2)
    _block(scene, (0.0, 0.0), (0.3, 0.3), 0.05, (1.0, 0.0), "left")
    _block(scene, (0.4, 0.1), (0.7, 0.4), 0.05, (-1.0, 0.0), "right")
    scene.set_grid(dx=0.05)
    return scene


def _angular(model, state, transfer):
    return bfemp.diagnostics.angular_momentum(model, state, transfer)[0]


@pytest.mark.parametrize("transfer", ["apic", "pic", "flip"])
def test_single_field_collision_conserves_momentum(transfer):
    model, stepper, state = _stepper(_collision_scene(), transfer=transfer)
    p0 = bfemp.diagnostics.linear_momentum(model, state)
    L0 = _angular(model, state, transfer)
    scale = float(model.mpm_mass.sum()) * 1.0  # total mass x speed
    for _ in range(150):  # the grid couples them from ~0.01 s on; they part again by ~0.3 s
        state, _ = stepper.step(state)
    p = bfemp.diagnostics.linear_momentum(model, state)
    assert np.allclose(p, p0, rtol=0.0, atol=1e-13 * scale), (p, p0)
    if transfer == "apic":  # the symmetrised B_p keeps x_i x v_i; Neo-Hookean torques cancel
        L = _angular(model, state, transfer)
        assert abs(L - L0) < 1e-13 * scale, (L, L0)
    # the no-slip interface turned part of the head-on motion into opposite vertical motion
    left, right = model.mpm_bodies
    m = model.mpm_mass
    v_left = m[left.particles] @ state.mpm_v[left.particles] / m[left.particles].sum()
    assert v_left[1] < -0.1


def test_single_field_bodies_stick_tangentially():
    """A block sliding over a resting one: one grid field glues them (no slip), so both end up
    vibrating about the common velocity v0 / 2; frictionless contact would keep 0 and v0."""
    scene = bfemp.Scene(dim=2)
    v0 = 0.2
    _block(scene, (0.0, 0.0), (1.0, 0.2), 0.05, (0.0, 0.0), "bottom")
    _block(scene, (0.0, 0.2), (1.0, 0.4), 0.05, (v0, 0.0), "top")
    scene.set_grid(dx=0.05)
    model, stepper, state = _stepper(scene)
    bottom, top = model.mpm_bodies
    m = model.mpm_mass
    v_bottom, v_top = [], []
    for k in range(200):
        state, _ = stepper.step(state)
        if k >= 50:
            v_bottom.append(m[bottom.particles] @ state.mpm_v[bottom.particles, 0])
            v_top.append(m[top.particles] @ state.mpm_v[top.particles, 0])
    v_bottom = np.mean(v_bottom) / m[bottom.particles].sum()
    v_top = np.mean(v_top) / m[top.particles].sum()
    assert v_bottom == pytest.approx(0.5 * v0, rel=0.2) and v_top == pytest.approx(
        0.5 * v0, rel=0.2
    )


def test_apic_angular_momentum_changes_under_pic():
    """The round-off conservation above is APIC's: PIC damps the rotation of the pair."""
    model, stepper, state = _stepper(_collision_scene(), transfer="pic")
    L0 = _angular(model, state, "pic")
    for _ in range(150):
        state, _ = stepper.step(state)
    assert abs(_angular(model, state, "pic") - L0) > 1e-6 * abs(L0)


def test_fused_p2g_equals_transfer_and_minus_elasticity_gradient(rng):
    scene = bfemp.Scene(dim=2)
    _block(scene, (0.0, 0.0), (0.5, 0.5), 0.1, None, "block")
    scene.set_grid(dx=0.1)
    model = scene.build()
    state = model.initial_state()
    n = model.n_particles
    state.mpm_F = np.eye(2) + 0.1 * rng.standard_normal((n, 2, 2))
    state.mpm_v = rng.standard_normal((n, 2))
    state.mpm_C = rng.standard_normal((n, 2, 2))
    state.mpm_x = state.mpm_x + 0.01 * rng.standard_normal((n, 2))
    _, begun, x_n = started_stepper(scene, state=state)
    st = begun.context.mpm.stencils
    term = begun.potential.potentials[0]
    term.solution_changed(x_n)
    reference = -term.gradient(x_n).reshape(-1, 2)  # grid forces at the start positions
    fields = particles_to_grid(
        "apic",
        st.nodes,
        st.weights,
        st.active_x,
        state.mpm_x,
        model.mpm_mass,
        state.mpm_v,
        state.mpm_C,
    )
    piola = SOFT.law.first_piola(state.mpm_F, SOFT.mu, SOFT.lam)
    args = (st.nodes, st.weights, st.grads, st.active_x, state.mpm_x, model.mpm_mass)
    for chunks in (1, 7):
        mass, mom, force = p2g_with_forces(
            *args, state.mpm_v, state.mpm_C, piola, state.mpm_F, model.mpm_volume, chunks
        )
        assert np.allclose(mass, fields.mass, rtol=1e-13)
        assert np.allclose(mom, fields.velocity * fields.mass[:, None], rtol=1e-12, atol=1e-14)
        free = begun.layout.free_nodes[begun.layout.free_nodes >= model.n_fem_nodes]
        assert np.allclose(force[free - model.n_fem_nodes], reference, rtol=1e-12, atol=1e-10)


# ---------------------------------------------------------------------------- FEM bar
def _bar_scene():
    scene = bfemp.Scene(dim=2)
    mesh = bfemp.shapes.rectangle((0.0, 0.0), (1.0, 0.1), h=0.05)
    mat = bfemp.NeoHookean(E=1e4, nu=0.0, density=1000.0)  # c = sqrt(E / rho), bar speed
    v = np.zeros_like(mesh.points)
    v[:, 0] = 0.02 * np.cos(np.pi * mesh.points[:, 0])  # first free-free axial mode
    scene.add_fem(mesh, material=mat, velocity=v, name="bar")
    return scene


def test_vibrating_fem_bar_keeps_its_energy_within_one_percent_over_ten_periods():
    model = _bar_scene().build()
    bound = SingleFieldStepper.auto_dt(model)
    stepper = SingleFieldStepper(model, integrator=SYMPLECTIC_EULER, dt=0.5 * bound)
    state = stepper.initialize(model.initial_state())
    groups = fem_elastic_groups(model)
    period = 2.0 * 1.0 / np.sqrt(1e4 / 1000.0)  # 2 L / c
    n_steps = int(np.ceil(10 * period / stepper.dt))
    m = model.fem_mass
    energies, kinetic = [], []
    v_prev = state.fem_v  # the initial velocity is the full-step one at t = 0
    for _ in range(n_steps):
        x = state.fem_x
        state, _ = stepper.step(state)
        # energy at x^n with the central-difference velocity (v^{n-1/2} + v^{n+1/2}) / 2
        v_full = 0.5 * (v_prev + state.fem_v)
        ke = 0.5 * float(m @ np.einsum("nd,nd->n", v_full, v_full))
        kinetic.append(ke)
        energies.append(ke + sum(stencil_energy(law, st, x) for law, st in groups))
        v_prev = state.fem_v
    energies = np.array(energies[1:])  # from the first full-step velocity on
    e0 = 0.5 * float(m @ (0.02 * np.cos(np.pi * model.fem_X[:, 0])) ** 2)
    assert np.abs(energies / e0 - 1.0).max() < 0.01
    # and it does vibrate: the kinetic energy passes through (nearly) zero and back
    assert min(kinetic) < 0.05 * e0 and max(kinetic[-200:]) > 0.9 * e0


def test_dt_above_the_stable_step_is_refused_naming_the_bound_body_and_cell():
    model = _bar_scene().build()
    bound = SingleFieldStepper.auto_dt(model)
    h_min = cell_altitudes(model.fem_X, model.fem_cells).min()
    assert bound == pytest.approx(0.5 * h_min / np.sqrt(1e4 / 1000.0), rel=1e-12)
    with pytest.raises(ValueError, match=r"exceeds the explicit stable step") as err:
        SingleFieldStepper(model, integrator="symplectic_euler", dt=1.1 * bound)
    message = str(err.value)
    assert f"{bound:.6g} s" in message and "fem body 'bar'" in message and "cell " in message
    SingleFieldStepper(model, integrator="symplectic_euler", dt=bound)  # the bound itself is fine


def test_mpm_bound_names_the_fastest_particle_and_a_step_past_cfl_one_fails():
    scene = bfemp.Scene(dim=2)
    x, vol = bfemp.sample.box((0.0, 0.0), (0.5, 0.5), dx=0.05, ppc=4)
    v = np.zeros_like(x)
    v[7] = (3.0, 0.0)
    scene.add_mpm(x, vol, material=SOFT, velocity=v, name="blob")
    scene.set_grid(dx=0.05)
    model = scene.build()
    c = SOFT.p_wave_speed
    assert SingleFieldStepper.auto_dt(model) == pytest.approx(0.4 * 0.05 / (c + 3.0))
    with pytest.raises(ValueError, match=r"particle 7 of mpm body 'blob'"):
        SingleFieldStepper(model, dt=0.4 * 0.05 / c)
    stepper = SingleFieldStepper(model, dt="auto")
    state = stepper.initialize(model.initial_state())
    state.mpm_v[3] = (0.0, 10.0 * c)  # now a particle would cross more than a cell
    with pytest.raises(StepError) as err:
        stepper.step(state)
    assert err.value.report.status == "CFL_VIOLATED"
    assert "particle 3 of mpm body 'blob'" in err.value.report.message


@pytest.mark.parametrize("d", [2, 3])
def test_fastest_particle_is_numpys_argmax_bit_for_bit(d):
    """The parallel search of the MPM bound picks numpy's particle (the first of equal maxima,
    the first NaN) and speed exactly, so ``dt="auto"`` is unchanged to the last bit."""
    rng = np.random.default_rng(d)
    speed_b = rng.uniform(1.0, 50.0, 3)
    for n in (1, 5, 3000, 40_000):
        v = rng.standard_normal((n, d)) * rng.uniform(0.0, 10.0)
        body = rng.integers(0, 3, n)
        for case in ("random", "ties", "nan"):
            if case == "ties":
                v[:] = 1.0
                body[:] = 0
            elif case == "nan":
                v[n // 2 :: 7] = np.nan
            speed = speed_b[body] + np.sqrt(np.einsum("pd,pd->p", v, v))
            k, top = _fastest_particle(speed_b, body, v)
            assert k == np.argmax(speed), (n, case)
            assert top == speed[k] or (np.isnan(top) and np.isnan(speed[k]))


# ---------------------------------------------------------------------------- FEM scripted
def test_scripted_fem_nodes_follow_their_motion():
    scene = bfemp.Scene(dim=2, gravity=tuple(G))
    mesh = bfemp.shapes.rectangle((0.0, 0.0), (1.0, 0.2), h=0.1)
    left = mesh.points[:, 0] < 1e-9
    motion = bfemp.motion.Linear(velocity=(0.0, 0.5))
    scene.add_fem(mesh, material=SOFT, prescribed=motion, prescribed_nodes=left, name="beam")
    model, stepper, state = _stepper(scene)
    for _ in range(20):
        state, _ = stepper.step(state)
    assert np.allclose(state.fem_x[left], model.prescribed_positions(state.t)[left], atol=1e-14)
    assert np.allclose(state.fem_v[left], (0.0, 0.5))
    assert np.all(state.fem_x[~left, 1] < model.fem_X[~left, 1] + 0.5 * state.t)  # it sags


# ---------------------------------------------------------------------------- level sets
def _on_floor(kind, velocity):
    scene = bfemp.Scene(dim=2)
    _block(scene, (0.0, 0.01), (0.4, 0.41), 0.05, velocity, "block")
    scene.set_grid(dx=0.05)
    scene.add_boundary(bfemp.levelset.HalfPlane(point=(0.0, 0.0), normal=(0.0, 1.0)), kind)
    return scene


@pytest.mark.parametrize(
    "kind, velocity, keeps_x, keeps_y",
    [
        ("slip", (1.0, 0.0), True, True),  # tangential motion is free
        ("sticky", (1.0, 0.0), False, True),  # the floor holds the bottom nodes
        ("separate", (0.0, 0.5), True, True),  # leaving the floor: released
        ("slip", (0.0, 0.5), True, False),  # slip holds even when leaving
    ],
)
def test_level_set_boundaries_on_grid_velocities(kind, velocity, keeps_x, keeps_y):
    model, stepper, state = _stepper(_on_floor(kind, velocity))
    p0 = bfemp.diagnostics.linear_momentum(model, state)
    state, report = stepper.step(state)
    p = bfemp.diagnostics.linear_momentum(model, state)
    scale = float(model.mpm_mass.sum())
    assert (abs(p[0] - p0[0]) < 1e-13 * scale) == keeps_x, (p, p0)
    assert (abs(p[1] - p0[1]) < 1e-13 * scale) == keeps_y, (p, p0)
    # the reported reaction is the momentum the boundary took, per unit time
    reaction = np.array(report.boundary_forces[0])
    assert np.allclose(reaction * stepper.dt, p - p0, rtol=1e-10, atol=1e-14 * scale)


# ---------------------------------------------------------------------------- options
def test_registry_and_protocol():
    assert stepper_class("single_field") is SingleFieldStepper is STRATEGIES["single_field"]
    _, stepper, _ = _stepper(_collision_scene())
    assert isinstance(stepper, Stepper) and stepper.explicit
    assert stepper.checkpoint_data() == {} and stepper.stable_dt(stepper.model.initial_state()) > 0
    view = stepper.contact()
    assert view.pairs == 0 and not view.particle_forces.any() and np.isnan(view.energy)
    assert stepper.terms == ["mpm_elasticity[neo_hookean]"]


def test_bad_options_and_integrators_are_refused_by_name():
    with pytest.raises(ValueError, match="cfl_safety_mpm"):
        SingleFieldOptions(cfl_safety_mpm=1.5)
    with pytest.raises(ValueError, match="cfl_safety_fem"):
        SingleFieldOptions(cfl_safety_fem="half")
    with pytest.raises(ValueError, match="unknown option 'cfl'.*cfl_safety_fem, cfl_safety_mpm"):
        options_from_mapping(SingleFieldOptions, {"cfl": 0.3})
    assert options_from_mapping(SingleFieldOptions, {"cfl_safety_mpm": 0.2}).cfl_safety_mpm == 0.2
    model = _collision_scene().build()
    with pytest.raises(
        ValueError, match="explicit: integrator must be 'symplectic_euler'.*newmark"
    ):
        SingleFieldStepper(model, integrator="newmark", dt="auto")
    with pytest.raises(ValueError, match="transfer"):
        SingleFieldStepper(model, transfer="xpic", dt="auto")
    with pytest.raises(ValueError, match="dt"):
        SingleFieldStepper(model, dt=-1.0)
    assert integrator_from_name("symplectic_euler").explicit
    assert not integrator_from_name("newmark").explicit


@pytest.mark.parametrize("transfer", ["apic", "pic", "flip"])
def test_explicit_g2p_equals_grid_to_particles(transfer, rng):
    scene = bfemp.Scene(dim=2)
    _block(scene, (0.0, 0.0), (0.5, 0.5), 0.1, None, "block")
    scene.set_grid(dx=0.1)
    model = scene.build()
    n = model.n_particles
    x = model.mpm_X + 0.01 * rng.standard_normal((n, 2))
    st = particle_stencils(model.grid, x)
    v_old, v_new = rng.standard_normal((2, st.n_nodes, 2))
    mpm_v, mpm_F = rng.standard_normal((n, 2)), np.eye(2) + 0.1 * rng.standard_normal((n, 2, 2))
    dt = 1e-3
    ref = grid_to_particles(
        transfer,
        st.nodes,
        st.weights,
        st.grads,
        st.active_x,
        st.active_x + dt * v_new,
        v_old,
        v_new,
        None,
        x,
        mpm_v,
        mpm_F,
    )
    out = g2p_explicit(
        transfer, st.nodes, st.weights, st.grads, st.active_x, v_old, v_new, dt, x, mpm_v, mpm_F, 3
    )
    for a, b in zip(out, ref[:4], strict=True):
        assert np.allclose(a, b, rtol=1e-13, atol=1e-13)


class _GeneralPath(SingleFieldStepper):
    dense_2d = False


@pytest.mark.parametrize("transfer", ["apic", "pic", "flip"])
def test_dense_2d_kernels_follow_the_general_stencil_path(transfer):
    scene = _on_floor("slip", (0.3, -0.2))
    model = scene.build()
    fast = SingleFieldStepper(model, transfer=transfer, dt="auto")
    general = _GeneralPath(model, transfer=transfer, dt="auto")
    a = b = model.initial_state()
    for _ in range(15):
        (a, report_a), (b, report_b) = fast.step(a), general.step(b)
    for name in ("mpm_x", "mpm_v", "mpm_F", "mpm_C"):
        assert np.allclose(getattr(a, name), getattr(b, name), rtol=0.0, atol=1e-12), name
    assert np.allclose(report_a.boundary_forces, report_b.boundary_forces, rtol=1e-10)
    assert np.abs(a.mpm_v - model.mpm_v0).max() > 1e-3  # the floor and the elasticity acted


def test_states_the_caller_keeps_are_never_overwritten():
    """The stepper reuses particle arrays only when nothing else holds them (BufferPool)."""
    model, stepper, state = _stepper(_collision_scene())
    kept = [state]
    for _ in range(6):
        state, _ = stepper.step(state)
        kept.append(state)
    snapshot = [s.mpm_F.copy() for s in kept]
    state, _ = stepper.step(state)
    view = state.mpm_x[:5]  # a view keeps its base array out of the pool too
    view_copy = view.copy()
    for _ in range(6):
        state, _ = stepper.step(state)  # drops the state the view came from
    assert all(np.array_equal(s.mpm_F, f) for s, f in zip(kept, snapshot, strict=True))
    assert np.array_equal(view, view_copy)
    assert len({id(s.mpm_F) for s in kept}) == len(kept)


def test_3d_free_fall_of_an_mpm_and_a_fem_body_is_the_symplectic_euler_recursion():
    g = np.array([0.0, 0.0, -9.81])
    scene = bfemp.Scene(dim=3, gravity=tuple(g))
    x, vol = bfemp.sample.box((0.0, 0.0, 0.0), (0.3, 0.3, 0.3), dx=0.1, ppc=8)
    v0 = np.array([0.2, -0.1, 1.0])
    spin = 0.5 * np.cross([0.0, 0.0, 1.0], x - 0.15)  # a rotation: elastic forces stay zero
    scene.add_mpm(x, vol, material=SOFT, velocity=v0 + spin, name="cube")
    scene.add_fem(bfemp.shapes.box((1.0, 0.0, 0.0), (1.3, 0.3, 0.3), h=0.15), material=SOFT)
    scene.set_grid(dx=0.1)
    model, stepper, state = _stepper(scene)
    m, M = model.mpm_mass, model.fem_mass
    com_p, com_f = m @ state.mpm_x / m.sum(), M @ state.fem_x / M.sum()
    v_p, v_f = m @ state.mpm_v / m.sum(), np.zeros(3)
    for _ in range(20):
        state, _ = stepper.step(state)
        v_p, v_f = v_p + stepper.dt * g, v_f + stepper.dt * g
        com_p, com_f = com_p + stepper.dt * v_p, com_f + stepper.dt * v_f
    assert np.allclose(m @ state.mpm_x / m.sum(), com_p, rtol=0.0, atol=1e-12)
    assert np.allclose(M @ state.fem_x / M.sum(), com_f, rtol=0.0, atol=1e-12)


def test_auto_dt_is_not_reported_above_itself_as_a_body_translates():
    """dt="auto" is the stable step of the initial state; a freely translating FEM block keeps
    that bound up to round-off, which must not be reported as CFL_ABOVE_SAFETY (it was, on 49
    of 50 steps, before the bound was compared with a 1e-12 relative slack)."""
    scene = bfemp.Scene(dim=2)
    mesh = bfemp.shapes.rectangle((0.0, 0.0), (0.4, 0.2), h=0.05)
    scene.add_fem(mesh, material=SOFT, velocity=(0.37, -0.21), name="slab")
    sim = bfemp.Simulation(scene, strategy="single_field", dt="auto")
    flagged = sum(any("CFL_ABOVE" in n for n in sim.step().notes) for _ in range(50))
    assert flagged == 0
