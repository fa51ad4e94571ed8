"""The ``"lr"`` strategy: multimaterial MPM with logistic-regression contact and XPIC(m).

Invariants of docs/design/explicit_strategies.md section 2.8 at the stepper level (the LR fit, the
deformed radius and the contact law alone are tested in ``test_lr_kernels.py``).
"""

import numpy as np
import pytest

import bfemp
from bfemp.mpm.transfer import g2p_field, p2g_field, p2g_materials
from bfemp.steppers import STRATEGIES
from bfemp.steppers.lr import LROptions, LRStepper
from geometry.grid import particle_stencils

SOFT = bfemp.NeoHookean(E=1e4, nu=0.3, density=1000.0)
DX = 0.05


def _split_block(n_materials, *, seed=0, gravity=(0.0, -9.81), noise=0.1, spin=0.0):
    """A 0.4 m square block (4 PPC) with a random velocity field (plus a rigid motion at 1 m/s
    and ``spin`` rad/s when ``spin`` is not 0), cut into 1, 2 or 3 bodies.

    Returns the scene and the permutation from the bodies' particle order to the original one.
    """
    scene = bfemp.Scene(dim=2, gravity=gravity)
    x, vol = bfemp.sample.box((0.0, 0.0), (0.4, 0.4), dx=DX, ppc=4)
    v = np.random.default_rng(seed).normal(size=x.shape) * noise
    if spin:
        v += np.array([1.0, 0.5]) + spin * np.stack([-(x[:, 1] - 0.2), x[:, 0] - 0.2], axis=1)
    low, left = x[:, 1] < 0.2, x[:, 0] < 0.2
    parts = {
        1: [np.ones(len(x), dtype=bool)],
        2: [low, ~low],
        3: [low, ~low & left, ~low & ~left],
    }[n_materials]
    for k, part in enumerate(parts):
        scene.add_mpm(x[part], vol[part], material=SOFT, velocity=v[part], name=f"part{k}")
    scene.set_grid(dx=DX)
    order = np.concatenate([np.flatnonzero(p) for p in parts])
    back = np.empty_like(order)
    back[order] = np.arange(order.size)
    return scene, back


def _run(n_materials, steps, transfer="flip", **options):
    options.setdefault("corrections", 2)  # the paper's (eq. 34's limit), not lr's default
    scene, back = _split_block(n_materials)
    model = scene.build()
    stepper = LRStepper(model, dt=1e-3, transfer=transfer, options=LROptions(**options))
    state = stepper.initialize(model.initial_state())
    for _ in range(steps):
        state, report = stepper.step(state)
    return state.mpm_x[back], state.mpm_v[back], state.mpm_F[back], report


def _largest_difference(a, b):
    return max(float(np.abs(p - q).max()) for p, q in zip(a[:3], b[:3], strict=True))


# ---------------------------------------------------------------- L1, L2: perfect interfaces
@pytest.mark.parametrize("n_materials", [2, 3])
def test_perfect_interface_multimaterial_flip_equals_single_material(n_materials):
    """L1: two corrections and f^{C,1} make the split block move as one to round-off; one
    correction ("LR once") and f^{C,0} (the a^{a,0} option) do not (the negative controls)."""
    single = _run(1, 50)
    split = _run(n_materials, 50, interface="perfect")
    assert split[3].extra["contact_nodes"] > 10  # the interfaces are really crossed
    assert _largest_difference(single, split) < 1e-12
    once = _run(n_materials, 50, interface="perfect", corrections=1)
    assert _largest_difference(single, once) > 1e-8
    c0 = _run(n_materials, 50, interface="perfect", contact_force="c0")
    assert _largest_difference(single, c0) > 1e-8


@pytest.mark.parametrize("n_materials", [2, 3])
def test_perfect_interface_xpic1_equals_single_material_and_pic(n_materials):
    """L2: multimaterial XPIC(1) is PIC and reverts to the single-material run."""
    single = _run(1, 30, xpic_order=1)
    split = _run(n_materials, 30, interface="perfect", xpic_order=1)
    assert _largest_difference(single, split) < 1e-12
    pic = _run(n_materials, 30, transfer="pic", interface="perfect")
    assert _largest_difference(split, pic) == 0.0
    flip = _run(1, 30)
    assert _largest_difference(single, flip) > 1e-8  # PIC is not FLIP


def _transfer_operators(model, x):
    """S, S+ (single material) and S+^a (per material) as functions on fields."""
    st = particle_stencils(model.grid, x)
    mat = model.mpm_particle_body.astype(np.int64)
    one = np.zeros_like(mat)
    m = model.mpm_mass
    G = st.active_x.shape[0]
    zeros = np.zeros((x.shape[0], 2, 2))
    mass_mm = p2g_materials(
        st.nodes,
        st.weights,
        st.grads,
        mat,
        m,
        np.zeros_like(x),
        zeros,
        zeros,
        model.mpm_volume,
        len(model.mpm_bodies),
        G,
    )[0]
    inv_mm = np.where(mass_mm > 0, 1.0 / np.where(mass_mm > 0, mass_mm, 1.0), 0.0)
    inv_sm = 1.0 / mass_mm.sum(axis=0, keepdims=True)

    def S(u, materials):
        return g2p_field(st.nodes, st.weights, materials, u)

    def S_plus(values):
        return p2g_field(st.nodes, st.weights, one, m, values, inv_sm)

    def S_plus_a(values):
        return p2g_field(st.nodes, st.weights, mat, m, values, inv_mm)

    return S, S_plus, S_plus_a, mat, one


@pytest.mark.parametrize(("variant", "equation"), [("paper", 47), ("corrected_velocity", 48)])
def test_perfect_interface_xpic2_differs_from_single_material_by_eq_47_or_48(variant, equation):
    """L3: one XPIC(2) step from a noisy V: V_SMM - V_MM is eq. 47 (paper) or eq. 48 (Uintah's
    corrected-velocity form) to round-off; on a smooth motion with small noise (V close to S v)
    eq. 47 is the smaller, as the paper argues."""
    results = {}
    for n in (1, 2):
        scene, back = _split_block(n, gravity=(0.0, 0.0), noise=0.02, spin=2.0)
        model = scene.build()
        opts = LROptions(interface="perfect", xpic_order=2, xpic_variant=variant, corrections=2)
        stepper = LRStepper(model, dt=1e-4, transfer="flip", options=opts)
        state = stepper.initialize(model.initial_state())
        new, _ = stepper.step(state)
        results[n] = (model, state, new.mpm_v[back], back)
    model, state, v_mm, back = results[2]
    S, S_plus, S_plus_a, mat, one = _transfer_operators(model, state.mpm_x)
    V = state.mpm_v
    sv = S(S_plus(V), one)  # S v, v the (common) corrected grid velocity
    # the stepper's velocity update adds dt S a to both, the same field on both sides
    eq47 = S(S_plus(V - sv), one) - S(S_plus_a(V - sv), mat)
    eq48 = -(S(S_plus(sv), one) - S(S_plus_a(sv), mat))
    expected = eq47 if equation == 47 else eq48
    diff = results[1][2] - v_mm
    assert np.abs(diff - expected[back]).max() < 1e-12 * max(1.0, np.abs(V).max())
    assert np.abs(diff).max() > 1e-6  # the difference is real
    assert np.linalg.norm(eq47) < np.linalg.norm(eq48)


def test_xpic_loop_equals_the_matrix_power_sums():
    """The loop of bfemp.mpm.xpic against eq. 37's sums with explicit matrix powers (m = 4)."""
    from bfemp.mpm.xpic import xpic_grid_velocity

    rng = np.random.default_rng(3)
    A = rng.normal(size=(6, 6)) * 0.3
    v, v0, dv = rng.normal(size=(3, 1, 6, 1))
    apply_A = lambda u: (A @ u[0])[None]  # noqa: E731
    got = xpic_grid_velocity(4, "paper", v, v0, dv, apply_A)
    B = np.eye(6) - A
    want = sum(np.linalg.matrix_power(B, k) @ v[0] for k in range(4))
    want = want - sum(np.linalg.matrix_power(B, k) @ dv[0] for k in range(3))
    assert np.abs(got[0] - want).max() < 1e-12
    unc = xpic_grid_velocity(4, "uncorrected", v, v0, dv, apply_A)
    want_unc = sum(np.linalg.matrix_power(B, k) @ v0[0] for k in range(4))
    assert np.abs(unc[0] - want_unc).max() < 1e-12


# ---------------------------------------------------------------- options and refusals
def test_lr_is_registered_and_refuses_apic_no_mpm_and_bad_options():
    assert STRATEGIES["lr"] is LRStepper
    scene, _ = _split_block(2)
    with pytest.raises(ValueError, match="APIC"):
        LRStepper(scene.build(), dt=1e-3, transfer="apic")
    with pytest.raises(ValueError, match="transfer"):
        bfemp.Simulation(scene, strategy="lr", transfer="apic", dt=1e-3)
    sim = bfemp.Simulation(scene, strategy="lr", dt="auto")
    assert sim.transfer == "flip"
    fem_only = bfemp.Scene(dim=2)
    fem_only.add_fem(bfemp.shapes.rectangle((0.0, 0.0), (0.4, 0.2), h=0.1), material=SOFT)
    fem_only.set_grid(dx=DX)
    with pytest.raises(ValueError, match="no MPM body"):
        LRStepper(fem_only.build(), dt=1e-4)
    for bad in (
        {"law": "sticky"},
        {"detector": "magic"},
        {"corrections": 3},
        {"xpic_order": 0},
        {"xpic_variant": "uintah"},
        {"lump": "none"},
        {"mass_fraction": 0.7},
        {"mu": -0.1},
        {"lr_max_iterations": 0},
        {"contact_force": "c2"},
    ):
        field = next(iter(bad))
        with pytest.raises(ValueError, match=field):
            LROptions(**bad)
    # f^{C,0} is a FLIP rule: XPIC(m), PIC included, is refused by name
    model = scene.build()
    for transfer, options in (("flip", {"xpic_order": 2}), ("pic", {})):
        with pytest.raises(ValueError, match="contact_force='c0' is a FLIP rule"):
            LRStepper(
                model, dt=1e-3, transfer=transfer, options=LROptions(contact_force="c0", **options)
            )


# ---------------------------------------------------------------- FEM bodies as a material
def _fem_mpm_scene(gap, velocity=(0.0, -1.0), h=0.025):
    """An MPM block above a free FEM slab (2D), ``gap`` m apart, the block moving down."""
    scene = bfemp.Scene(dim=2)
    scene.add_fem(bfemp.shapes.rectangle((0.0, 0.0), (0.4, 0.1), h=h), material=SOFT, name="slab")
    x, vol = bfemp.sample.box((0.1, 0.1 + gap), (0.3, 0.3 + gap), dx=DX, ppc=4)
    scene.add_mpm(x, vol, material=SOFT, velocity=velocity, name="block")
    scene.set_grid(dx=DX)
    return scene


def _total_momentum(model, state):
    return model.mpm_mass @ state.mpm_v + model.fem_mass @ state.fem_v


def test_fem_material_exchanges_momentum_conservatively():
    """A perfect interface between an MPM block and a FEM slab: the total momentum of particles
    and nodes is kept to round-off while the slab is pushed (the momentum really moves)."""
    model = _fem_mpm_scene(0.0).build()
    stepper = LRStepper(model, dt=1e-4, options=LROptions(interface="perfect"))
    state = stepper.initialize(model.initial_state())
    p0 = _total_momentum(model, state)
    for _ in range(200):
        state, report = stepper.step(state)
    assert report.extra["contact_nodes"] > 0
    assert np.abs(_total_momentum(model, state) - p0).max() < 1e-12 * np.abs(p0).max()
    slab = model.fem_mass @ state.fem_v
    assert slab[1] < -0.02 * abs(p0[1])  # the slab took a real share (measured 2.8 %)
    forces = stepper.contact()
    assert np.abs(forces.fem_forces).sum() > 0.0


def test_fine_grid_against_the_fem_edge_is_warned(caplog):
    model = _fem_mpm_scene(0.05, h=0.05).build()
    with caplog.at_level("WARNING", logger="bfemp.steppers.lr"):
        LRStepper(model, dt=1e-4)
    assert "finer than twice the FEM boundary edge" in caplog.text
    caplog.clear()
    model = _fem_mpm_scene(0.05, h=0.02).build()
    with caplog.at_level("WARNING", logger="bfemp.steppers.lr"):
        LRStepper(model, dt=1e-4)
    assert "finer than twice" not in caplog.text


# ---------------------------------------------------------------- L4: momentum; L8: detection
def _colliding_blocks(third=False):
    """Two soft blocks meeting at 1 m/s each, offset vertically; optionally a third falling
    into the joint (so that nodes see three materials)."""
    scene = bfemp.Scene(dim=2)
    for name, lo, hi, v in (
        ("left", (0.0, 0.0), (0.3, 0.3), (1.0, 0.0)),
        ("right", (0.4, 0.1), (0.7, 0.4), (-1.0, 0.0)),
        *([("top", (0.3, 0.35), (0.4, 0.5), (0.0, -0.5))] if third else []),
    ):
        x, vol = bfemp.sample.box(lo, hi, dx=DX, ppc=4)
        scene.add_mpm(x, vol, material=SOFT, velocity=v, name=name)
    scene.set_grid(dx=DX)
    return scene


def _momentum_run(scene, steps=150, **options):
    model = scene.build()
    stepper = LRStepper(model, dt="auto", options=LROptions(**options))
    state = stepper.initialize(model.initial_state())
    p0 = model.mpm_mass @ state.mpm_v
    scale = float(np.abs(model.mpm_mass[:, None] * state.mpm_v).sum())
    drift, lumped_steps, drift_when_lumped = [], 0, []
    for _ in range(steps):
        state, report = stepper.step(state)
        drift.append(float(np.abs(model.mpm_mass @ state.mpm_v - p0).max()) / scale)
        if report.extra["nodes_3plus"] == 0:
            assert report.extra["lump_momentum_drift"] < 1e-12 * scale
        else:
            lumped_steps += 1
            drift_when_lumped.append(report.extra["lump_momentum_drift"])
    return stepper, drift, lumped_steps, drift_when_lumped


@pytest.mark.parametrize(
    "options",
    [{}, {"mu": 0.3}, {"xpic_order": 5}, {"detector": "cp"}, {"mu": 0.3, "contact_force": "c0"}],
)
def test_two_material_contact_conserves_momentum(options):
    """L4: the blocks collide (contact is found and corrected) with Sigma m V kept to 1e-12."""
    stepper, drift, lumped, _ = _momentum_run(_colliding_blocks(), **options)
    assert stepper.steps_with_contact > 10
    assert lumped == 0
    assert max(drift) < 1e-12


def test_lumping_at_three_material_nodes_drifts_and_the_conservative_variant_does_not():
    """L4's control: with a third body in the joint, eq. 50's lumping changes the momentum
    (only on steps with 3+ nodes, as reported); lump="conservative" keeps it."""
    _, drift, lumped, when = _momentum_run(_colliding_blocks(third=True))
    assert lumped > 5
    assert max(drift) > 1e-6 and max(when) > 0.0
    _, drift_c, lumped_c, _ = _momentum_run(_colliding_blocks(third=True), lump="conservative")
    assert lumped_c > 5
    assert max(drift_c) < 1e-12


def _approach(detector, gap_cells=1.5, steps=None):
    """A block moving at 1 m/s toward a resting one, gap_cells cells apart; the time of the
    first corrected step and the exact contact time."""
    scene = bfemp.Scene(dim=2)
    lower = bfemp.sample.box((0.0, 0.0), (0.4, 0.2), dx=DX, ppc=4)
    gap = gap_cells * DX
    upper = bfemp.sample.box((0.0, 0.2 + gap), (0.4, 0.4 + gap), dx=DX, ppc=4)
    scene.add_mpm(*lower, material=SOFT, name="lower")
    scene.add_mpm(*upper, material=SOFT, velocity=(0.0, -1.0), name="upper")
    scene.set_grid(dx=DX)
    model = scene.build()
    stepper = LRStepper(model, dt=1e-3, options=LROptions(detector=detector))
    state = stepper.initialize(model.initial_state())
    t_c = gap / 1.0
    for _ in range(int(1.5 * t_c / stepper.dt)):
        state, report = stepper.step(state)
        if report.contact_pairs:
            return state.t, t_c
    return None, t_c


def test_contact_needs_touching_and_approaching():
    """L8 in a step: LR finds the contact within a step or two of the exact time (the blocks
    are 1.5 cells apart, so the stencils overlap long before); the velocity-only detector,
    which ignores the separation, corrects at once (its contact at a distance)."""
    t_lr, t_c = _approach("lr")
    assert t_lr is not None and abs(t_lr - t_c) <= 2.5e-3
    t_v, _ = _approach("velocity")
    assert t_v is not None and t_v < t_c - 0.5 * DX


def test_coulomb_friction_slows_the_slide_and_frictionless_keeps_it():
    """A block sliding at 0.5 m/s on a resting one, pressed down by gravity: with mu = 0 the
    relative tangential speed is kept (to the elastic noise), with mu = 0.5 it falls."""
    speeds = {}
    for mu in (0.0, 0.5):
        scene = bfemp.Scene(dim=2, gravity=(0.0, -9.81))
        lower = bfemp.sample.box((0.0, 0.0), (0.8, 0.1), dx=DX, ppc=4)
        upper = bfemp.sample.box((0.2, 0.1), (0.4, 0.2), dx=DX, ppc=4)
        scene.add_mpm(*lower, material=SOFT, name="lower")
        scene.add_mpm(*upper, material=SOFT, velocity=(0.5, 0.0), name="upper")
        scene.add_boundary(
            bfemp.levelset.HalfPlane(point=(0.0, 0.0), normal=(0.0, 1.0)), kind="sticky"
        )
        scene.set_grid(dx=DX)
        model = scene.build()
        stepper = LRStepper(model, dt=1e-3, options=LROptions(mu=mu))
        state = stepper.initialize(model.initial_state())
        for _ in range(150):
            state, _ = stepper.step(state)
        up = model.mpm_particle_body == 1
        m = model.mpm_mass
        speeds[mu] = float(m[up] @ state.mpm_v[up, 0] / m[up].sum())
    assert speeds[0.0] > 0.4
    assert speeds[0.5] < speeds[0.0] - 0.1


def test_capped_lr_fits_are_counted_every_step_and_warned_once(caplog):
    model = _colliding_blocks().build()
    opts = LROptions(lr_max_iterations=1, lr_tol=1e-14)
    stepper = LRStepper(model, dt="auto", options=opts)
    state = stepper.initialize(model.initial_state())
    counted = 0
    with caplog.at_level("WARNING", logger="bfemp.steppers.lr"):
        for _ in range(120):
            state, report = stepper.step(state)
            counted += report.extra["lr_unconverged"] > 0
    assert counted > 5 and stepper.unconverged_fits > 5
    assert sum("hit the cap" in r.message for r in caplog.records) == 1


# ---------------------------------------------------------------- f^{C,1} at a lasting contact
def test_first_correction_note_needs_a_window_of_contact_steps_above_the_ratio(caplog):
    """``LR_FIRST_CORRECTION``: given once per window of contact steps whose first-correction
    impulse exceeds the ratio times the second's, warned once per run, never under f^{C,0},
    one correction or XPIC (the physics: ``benchmarks.lr_variants``, tested with its scenes)."""
    from bfemp.steppers.lr import FIRST_CORRECTION_RATIO, FIRST_CORRECTION_WINDOW

    model = _colliding_blocks().build()

    def feed(stepper, ratio, steps, touching=True):
        notes = []
        for k in range(steps):
            notes += stepper._watch_first_correction(touching, ratio, 1.0, k)
        return notes

    stepper = LRStepper(model, dt=1e-3, options=LROptions(corrections=2))  # the paper's c1
    with caplog.at_level("WARNING", logger="bfemp.steppers.lr"):
        assert feed(stepper, 2.0 * FIRST_CORRECTION_RATIO, FIRST_CORRECTION_WINDOW - 1) == []
        assert feed(stepper, 0.0, 50, touching=False) == []  # steps without contact do not count
        (note,) = feed(stepper, 2.0 * FIRST_CORRECTION_RATIO, 1)
        assert note.startswith("LR_FIRST_CORRECTION") and "2" in note
        assert len(feed(stepper, 2.0 * FIRST_CORRECTION_RATIO, 2 * FIRST_CORRECTION_WINDOW)) == 2
        assert feed(stepper, 0.5 * FIRST_CORRECTION_RATIO, FIRST_CORRECTION_WINDOW) == []
    assert stepper.first_correction_windows == 3
    assert caplog.text.count("the first correction removed") == 1
    assert stepper.first_correction_impulse == pytest.approx(
        2.0 * FIRST_CORRECTION_RATIO * 3 * FIRST_CORRECTION_WINDOW
        + 0.5 * FIRST_CORRECTION_RATIO * FIRST_CORRECTION_WINDOW
    )
    for options, transfer in (
        ({"contact_force": "c0", "corrections": 2}, "flip"),
        ({}, "flip"),  # one correction, the default
        ({"xpic_order": 5, "corrections": 2}, "flip"),
        ({"corrections": 2}, "pic"),
    ):
        quiet = LRStepper(model, dt=1e-3, transfer=transfer, options=LROptions(**options))
        assert feed(quiet, 10.0, 3 * FIRST_CORRECTION_WINDOW) == [], options
