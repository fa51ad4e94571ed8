"""``"lr"`` on issue 40's drop: an MPM body dropped on a FEM plate, and LR's contact node.

- A scripted (fixed) FEM plate is infinitely heavy in the contact law (NairnMPM's rigid
  materials): before, its field held only its boundary nodes' masses and the centre-of-mass
  law let the body through (lowest particle -5.7 cells for the 2D disk, -2.2 for the box,
  -0.51 for the 3D cube at these settings).
- LR section 3.1's contact node: two or more materials with any mass there (the default);
  Uintah's threshold ``mass_fraction`` is an option.
"""

import numpy as np
import pytest

import bfemp
from bfemp.contact.lr import contact_momentum
from bfemp.steppers.lr import LROptions, LRStepper

SOFT = bfemp.NeoHookean(E=1e5, nu=0.3, density=1000.0)
STIFF = bfemp.NeoHookean(E=1e8, nu=0.3, density=1000.0)


def _drop(dim, shape, dx, *, plate="fixed", plate_material=STIFF, h=0.025, mu=0.3):
    """Issue 40's drop: a body at (1, -1) m/s just above a plate whose top is y = 0."""
    gravity = (0.0, -9.81) if dim == 2 else (0.0, -9.81, 0.0)
    scene = bfemp.Scene(dim=dim, gravity=gravity)
    if dim == 2:
        mesh = bfemp.shapes.rectangle((-0.5, -0.1), (1.0, 0.0), h=h)
    else:
        mesh = bfemp.shapes.box((-0.3, -0.1, -0.3), (0.5, 0.0, 0.3), h=h)
    nodes = None if plate == "fixed" else np.flatnonzero(mesh.points[:, 1] < -0.1 + 1e-9)
    scene.add_fem(
        mesh,
        material=plate_material,
        prescribed=bfemp.motion.Fixed(),
        prescribed_nodes=nodes,
        name="plate",
    )
    if shape == "disk":
        x, vol = bfemp.sample.mesh(bfemp.shapes.disk((0.0, 0.15), 0.1, h=0.02), dx=dx, ppc=4)
    elif shape == "box":
        x, vol = bfemp.sample.box((-0.1, 0.05), (0.1, 0.25), dx=dx, ppc=4)
    else:
        x, vol = bfemp.sample.box((-0.05, 0.05, -0.05), (0.05, 0.15, 0.05), dx=dx, ppc=8)
    velocity = (1.0, -1.0) if dim == 2 else (1.0, -1.0, 0.0)
    scene.add_mpm(x, vol, material=SOFT, velocity=velocity, name="body")
    scene.set_grid(dx=dx)
    scene.set_contact(dhat=1e-3, kappa=1e5, mu=mu)
    return scene


def _lowest(scene, t_end, **options):
    """The lowest particle centre (m) over the run, and the plate's reaction impulse (N s)."""
    sim = bfemp.Simulation(scene, strategy="lr", dt="auto", options=LROptions(**options))
    lowest, impulse = np.inf, 0.0
    while sim.state.t < t_end - 1e-12:
        report = sim.step()
        lowest = min(lowest, float(sim.state.mpm_x[:, 1].min()))
        impulse += report.extra.get("scripted_impulse", 0.0)
    return lowest, impulse


@pytest.mark.parametrize(
    ("dim", "shape", "dx"),
    [(2, "disk", 0.02), (2, "box", 0.05), (3, "cube", 0.05)],
    ids=["disk-2d-dx0.02", "box-2d-dx0.05", "cube-3d-dx0.05"],
)
def test_body_stays_on_a_fixed_fem_plate(dim, shape, dx):
    """The body lands at t ~ 0.045 s; to 0.12 s no particle centre goes 0.1 cell below the
    plate top (measured: +0.23, +0.24, +0.25 cells, particle centres one radius above; before
    the fix -5.7, -2.2 and -0.51 cells), and the plate takes a reaction impulse."""
    lowest, impulse = _lowest(_drop(dim, shape, dx, h=0.025 if dim == 2 else 0.05), 0.12)
    assert lowest > -0.1 * dx
    assert impulse > 0.0


def test_scripted_side_is_infinitely_heavy_in_the_contact_law():
    """dp(0) = m_a (v_b - v_a) against a rigid b (m_b (v_b - v_a) against a rigid a): after the
    correction the free side moves with the rigid one along the normal, whatever m_b."""
    m_a, m_b = np.array([2.0]), np.array([0.5])
    v_a, v_b = np.array([[0.3, -1.0]]), np.array([[0.0, 0.1]])
    n = np.array([[0.0, -1.0]])  # from a (above) to b (below)
    kw = dict(mu=0.0, law="frictionless", detector="lr")
    sep = np.array([-1e-3])
    yes = np.array([True])
    dp, hit = contact_momentum(m_a, m_b, m_a * v_a, m_b * v_b, n, sep, rigid_b=yes, **kw)
    assert hit[0]
    assert (v_a + dp / m_a)[0, 1] == pytest.approx(v_b[0, 1], abs=1e-15)
    assert (v_a + dp / m_a)[0, 0] == pytest.approx(0.3)  # frictionless: tangent kept
    # a finite b stops a only at the centre of mass (the old law against the plate)
    dp_f, _ = contact_momentum(m_a, m_b, m_a * v_a, m_b * v_b, n, sep, **kw)
    v_cm = (m_a * v_a[0, 1] + m_b * v_b[0, 1]) / (m_a + m_b)
    assert (v_a + dp_f / m_a)[0, 1] == pytest.approx(v_cm[0])
    # rigid a: b takes a's velocity (b gets -dp)
    dp, hit = contact_momentum(m_b, m_a, m_b * v_b, m_a * v_a, -n, sep, rigid_a=yes, **kw)
    assert hit[0] and (v_a - dp / m_a)[0, 1] == pytest.approx(v_b[0, 1], abs=1e-15)
    # both rigid: nothing is exchanged
    dp, hit = contact_momentum(
        m_a, m_b, m_a * v_a, m_b * v_b, n, sep, rigid_a=yes, rigid_b=yes, **kw
    )
    assert not hit[0] and np.all(dp == 0.0)
    with pytest.raises(ValueError, match="rigid_b"):
        contact_momentum(m_a, m_b, m_a * v_a, m_b * v_b, n, sep, rigid_b=np.array([1]), **kw)


def test_a_scripted_piston_carries_the_block_at_its_speed():
    """A FEM piston scripted up at 0.5 m/s under a block at rest (gravity on): the scripted
    field enters with the script's velocity at t^{n+1} and is rigid, so the block rides at
    the piston's speed with its particle centres above the piston's top (measured: 0.502 m/s,
    +0.24 cells; before, the piston passed through: -1.58 m/s, -4.5 cells)."""
    dx = 0.05
    scene = bfemp.Scene(dim=2, gravity=(0.0, -9.81))
    piston = bfemp.shapes.rectangle((-0.3, -0.1), (0.3, 0.0), h=0.025)
    scene.add_fem(
        piston, material=SOFT, prescribed=bfemp.motion.Linear(velocity=(0.0, 0.5)), name="piston"
    )
    x, vol = bfemp.sample.box((-0.1, 0.006), (0.1, 0.106), dx=dx, ppc=4)
    scene.add_mpm(x, vol, material=SOFT, name="block")
    scene.set_grid(dx=dx)
    sim = bfemp.Simulation(scene, strategy="lr", dt="auto")
    lowest = np.inf
    while sim.state.t < 0.2:
        sim.step()
        lowest = min(lowest, float((sim.state.mpm_x[:, 1] - sim.state.fem_x[:, 1].max()).min()))
    model = sim.model
    vy = model.mpm_mass @ sim.state.mpm_v[:, 1] / model.mpm_mass.sum()
    assert vy == pytest.approx(0.5, rel=0.05)
    assert lowest > -0.1 * dx


# ---------------------------------------------------------------- LR section 3.1: contact node
def _two_particles(offset_cells):
    """Particle A on a node; particle B 1.5 - ``offset_cells`` cells to its right, so that B's
    B-spline weight at A's node is 0.5 offset^2 (5e-9 at 1e-4): B's share of that node's mass
    is 6.7e-9, under Uintah's 1e-8."""
    dx = 0.1
    scene = bfemp.Scene(dim=2)
    vol = np.array([dx * dx / 4])
    scene.add_mpm(np.array([[0.5, 0.5]]), vol, material=SOFT, name="a")
    scene.add_mpm(np.array([[0.5 + dx * (1.5 - offset_cells), 0.5]]), vol, material=SOFT, name="b")
    scene.set_grid(dx=dx)
    return scene


def _contact_nodes(scene, **options):
    model = scene.build()
    stepper = LRStepper(model, dt=1e-4, options=LROptions(**options))
    state = stepper.initialize(model.initial_state())
    _, report = stepper.step(state)
    return report.extra["contact_nodes"]


def test_contact_node_is_any_mass_by_default_and_uintahs_threshold_is_an_option():
    """LR sec. 3.1 / NairnMPM: a node with two materials is a contact node, however little mass
    one has there. The columns x = 0.6 (B's main weight) and x = 0.5 (B's weight 5e-9) are
    shared, 3 nodes each: 6 contact nodes by default; Uintah's 1e-8 drops the x = 0.5 column."""
    scene = _two_particles(1e-4)
    assert _contact_nodes(scene) == 6
    assert LROptions().mass_fraction == 0.0
    assert _contact_nodes(scene, mass_fraction=0.0) == 6
    assert _contact_nodes(scene, mass_fraction=1e-8) == 3
    for bad in (-1e-9, 0.5, float("nan")):
        with pytest.raises(ValueError, match="mass_fraction"):
            LROptions(mass_fraction=bad)


# ---------------------------------------------------------------- the default particle update
def test_default_update_holds_a_landing_on_a_deformable_plate_and_the_papers_c1_does_not():
    """The disk lands on a plate held by its bottom row alone (E = 1 MPa, so its top nodes
    move). One correction (the default) keeps every particle centre within 0.1 cell of the
    top to 0.12 s; the paper's two corrections with f^{C,1} give neither the particles nor
    the plate the first correction, and the disk sinks (measured -2.8 cells)."""
    soft_plate = bfemp.NeoHookean(E=1e6, nu=0.3, density=1000.0)
    dx = 0.02

    def scene():
        return _drop(2, "disk", dx, plate="bottom", plate_material=soft_plate)

    assert _lowest(scene(), 0.12)[0] > -0.1 * dx
    assert _lowest(scene(), 0.12, corrections=2, contact_force="c1")[0] < -1.0 * dx
