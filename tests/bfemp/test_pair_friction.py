"""Friction per pair of bodies (``scene.set_friction``): lookup, physics, scene files, refusals."""

import numpy as np
import pytest

import bfemp
from bfemp.contact.pair_friction import PairFriction, body_code
from bfemp.testing import check_term
from tests.bfemp.conftest import started_stepper

STIFF = bfemp.NeoHookean(E=1e6, nu=0.3, density=1000.0)
G = 9.81


def test_pair_lookup_is_symmetric_and_falls_back_to_the_default():
    fem0, fem1, mpm0 = body_code("fem", 0), body_code("fem", 1), body_code("mpm", 0)
    table = PairFriction(0.1, ((fem0, mpm0, 0.5), (fem1, fem0, 0.0)))
    a = np.array([fem0, mpm0, fem0, fem1, fem1])
    b = np.array([mpm0, fem0, fem1, fem0, mpm0])
    np.testing.assert_array_equal(table.of(a, b), [0.5, 0.5, 0.0, 0.0, 0.1])
    assert table.largest == 0.5
    with pytest.raises(ValueError, match="finite and >= 0"):
        PairFriction(0.1, ((fem0, mpm0, -1.0),))


def _two_blocks(pairs, mu=0.0):
    """Two blocks sliding at 1 m/s in +x on a fixed floor, ``pairs`` {block name: mu}."""
    scene = bfemp.Scene(dim=2, gravity=(0.0, -G))
    floor = bfemp.shapes.rectangle((-0.2, -0.1), (1.6, 0.0), h=0.1)
    scene.add_fem(floor, material=STIFF, prescribed=bfemp.motion.Fixed(), name="floor")
    for name, x0 in (("left", 0.0), ("right", 0.8)):
        x, vol = bfemp.sample.box((x0, 0.0011), (x0 + 0.2, 0.0511), dx=0.025, ppc=4)
        scene.add_mpm(x, vol, material=STIFF, velocity=(1.0, 0.0), name=name)
    scene.set_grid(dx=0.025)
    scene.set_contact(dhat=1e-3, kappa=1e4, mu=mu)
    for name, value in pairs.items():
        scene.set_friction("floor", name, value)
    return scene


def _speeds_after(scene, strategy="barrier", t_end=0.1):
    """Mean x-velocity (m/s) of each block at ``t_end`` (s), and the time reached."""
    dt = 5e-3 if strategy == "barrier" else "auto"  # the explicit lr and two_stage's bound
    sim = bfemp.Simulation(scene, strategy=strategy, dt=dt)
    while sim.state.t < t_end - 1e-12:
        sim.step()
    body = sim.model.mpm_particle_body
    vx = sim.state.mpm_v[:, 0]
    return np.array([vx[body == k].mean() for k in range(2)]), sim.state.t


@pytest.mark.parametrize("strategy", ["barrier", "two_stage"])
@pytest.mark.parametrize("rubbing", ["left", "right"])
def test_only_the_pair_given_a_coefficient_rubs(rubbing, strategy):
    """mu = 0.5 for the floor and one block, 0 for the other: that block slows at mu g, the
    other keeps its speed; swapping the pair swaps the outcome (the control). Measured at
    t = 0.1 s: 0.5095 m/s (barrier) and 0.5123 m/s (two_stage) against 0.5095, 1.0 for the
    other block."""
    speeds, t = _speeds_after(_two_blocks({rubbing: 0.5}), strategy)
    k = 0 if rubbing == "left" else 1
    expected = 1.0 - 0.5 * G * t  # Coulomb deceleration mu g while sliding
    assert speeds[k] == pytest.approx(expected, rel=1e-2), speeds
    assert speeds[1 - k] == pytest.approx(1.0, abs=1e-3), speeds


def test_a_pair_can_be_frictionless_under_a_frictional_default():
    speeds, t = _speeds_after(_two_blocks({"right": 0.0}, mu=0.5))
    assert speeds[0] == pytest.approx(1.0 - 0.5 * G * t, rel=1e-2), speeds
    assert speeds[1] == pytest.approx(1.0, abs=1e-3), speeds


def test_pair_friction_passes_the_fd_harness(rng):
    scene = _two_blocks({"right": 0.7}, mu=0.2)
    sim = bfemp.Simulation(scene, dt=5e-3)
    for _ in range(10):  # the blocks land (they start 6 mm up)
        sim.step()
    _, begun, x = started_stepper(scene, dt=5e-3, state=sim.state)
    friction = next(t for t in begun.potential.potentials if t.name == "friction")
    friction.lag(x)
    assert friction.n_contacts > 0
    dim = 2
    x = x.reshape(-1, dim).copy()
    x[:, 0] += 1e-3  # sliding
    x = x.reshape(-1) + 1e-7 * rng.standard_normal(x.size)
    report = check_term(friction, x, eps=1e-8, tol=1e-5, hessian_floor=100.0)
    assert report.ok, report


def test_set_friction_refuses_bad_pairs_by_name():
    scene = _two_blocks({})
    with pytest.raises(ValueError, match="no body named 'roof'"):
        scene.set_friction("floor", "roof", 0.3)
    with pytest.raises(ValueError, match="given twice"):
        scene.set_friction("floor", "floor", 0.3)
    for bad in (-0.1, float("nan"), float("inf"), True, "0.3"):
        with pytest.raises(ValueError, match="finite number >= 0"):
            scene.set_friction("floor", "left", bad)
    lone = bfemp.Scene(dim=2)
    lone.add_fem(bfemp.shapes.rectangle((0, 0), (1, 1), h=0.5), material=STIFF, name="a")
    lone.add_fem(bfemp.shapes.rectangle((2, 0), (3, 1), h=0.5), material=STIFF, name="b")
    lone.set_friction("a", "b", 0.3)
    with pytest.raises(ValueError, match="without contact"):
        lone.build()


def test_augury_with_one_coefficient_refuses_pairs():
    scene = _two_blocks({"left": 0.5})
    with pytest.raises(ValueError, match="augury: the scene sets friction per pair"):
        bfemp.Simulation(scene, strategy="augury", dt=1e-4)


def test_barrier_warns_that_an_mpm_pair_never_rubs(caplog):
    scene = _two_blocks({})
    scene.set_friction("left", "right", 0.3)
    with caplog.at_level("WARNING"):
        bfemp.Simulation(scene, dt=5e-3)
    assert "'left' and 'right'" in caplog.text and "not used" in caplog.text


@pytest.mark.parametrize("rubbing", ["left", "right"])
def test_lr_takes_the_coefficient_of_each_material_pair(rubbing):
    """lr (the floor as a material): the named block slows at about mu g, the other keeps its
    speed. Measured at t = 0.1 s: 0.534 m/s against mu g's 0.509 (grid contact), and 0.995."""
    speeds, t = _speeds_after(_two_blocks({rubbing: 0.5}), "lr")
    k = 0 if rubbing == "left" else 1
    assert speeds[k] == pytest.approx(1.0 - 0.5 * G * t, rel=0.1), speeds
    assert speeds[1 - k] == pytest.approx(1.0, abs=1e-2), speeds


def test_lr_lumped_nodes_take_the_mass_weighted_mean_of_their_pairs():
    scene = _two_blocks({"left": 0.5, "right": 0.1}, mu=0.0)
    stepper = bfemp.Simulation(scene, strategy="lr", dt="auto").stepper
    # materials: left 0, right 1, floor 2; a node of left against right (b = 1) and one of
    # the floor against the lumped others (b = -1) with left 3 kg and right 1 kg there
    mass = np.array([[1.0, 3.0], [1.0, 1.0], [1.0, 2.0]])
    mu = stepper._pair_mu(np.array([0, 2]), np.array([1, -1]), mass)
    np.testing.assert_allclose(mu, [0.0, (3.0 * 0.5 + 1.0 * 0.1) / 4.0])


def test_scene_files_keep_the_pairs(tmp_path):
    from bfemp import scenefile

    scene = _two_blocks({"left": 0.5, "right": 0.0}, mu=0.2)
    path = tmp_path / "blocks.toml"
    scenefile.save(scene, path)
    assert "[[contact.pairs]]" in path.read_text()
    loaded = scenefile.load(path)
    assert loaded.scene.build().contact.pair_mu == scene.build().contact.pair_mu
    text = path.read_text().replace('bodies = [\n    "floor",\n    "left",\n]', "bodies = 3")
    text = text.replace('bodies = ["floor", "left"]', "bodies = 3")
    bad = tmp_path / "bad.toml"
    bad.write_text(text)
    with pytest.raises(bfemp.SceneError, match="two body names"):
        scenefile.load(bad)
