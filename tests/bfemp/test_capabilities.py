"""Strategy capabilities (bfemp.steppers.capabilities): declared, enforced on scenes, printed;
step notes reaching the user; the shared penetration check."""

import json
import warnings

import numpy as np
import pytest

import bfemp
from bfemp.cli import main
from bfemp.contact.penetration import PenetrationCheck
from bfemp.steppers import STRATEGIES
from bfemp.steppers.capabilities import PAIR_KINDS, Capabilities, scene_pairs

SOFT = bfemp.NeoHookean(E=1e5, nu=0.3, density=1000.0)
STIFF = bfemp.NeoHookean(E=1e7, nu=0.3, density=1000.0)


def block_on_plate(*, contact=True, plate_fixed="all", fem_block=False, dx=0.05):
    """A 0.2 m block (MPM, or FEM with ``fem_block``) 5 mm above a plate whose top is y = 0;
    the plate is fully fixed (``"all"``), fixed on its bottom row (``"bottom"``) or free."""
    scene = bfemp.Scene(dim=2, gravity=(0.0, -9.81))
    plate = bfemp.shapes.rectangle((-0.3, -0.1), (0.3, 0.0), h=0.05)
    kwargs = {}
    if plate_fixed == "all":
        kwargs = dict(prescribed=bfemp.motion.Fixed())
    elif plate_fixed == "bottom":
        kwargs = dict(
            prescribed=bfemp.motion.Fixed(), prescribed_nodes=plate.points[:, 1] < -0.1 + 1e-9
        )
    scene.add_fem(plate, material=STIFF, name="plate", **kwargs)
    if fem_block:
        block = bfemp.shapes.rectangle((-0.1, 0.005), (0.1, 0.205), h=0.05)
        scene.add_fem(block, material=SOFT, name="block")
    else:
        x, vol = bfemp.sample.box((-0.1, 0.005), (0.1, 0.205), dx=dx, ppc=4)
        scene.add_mpm(x, vol, material=SOFT, name="block")
        scene.set_grid(dx=dx)
    if contact:
        scene.set_contact(dhat=1e-3, kappa=1e5)
    return scene


def test_every_registered_strategy_declares_its_capabilities():
    for name, cls in STRATEGIES.items():
        caps = cls.capabilities
        assert isinstance(caps, Capabilities), name
        assert set(caps.pairs) <= set(PAIR_KINDS), name
        assert caps.penetration_note, name
        if caps.penetration_bound_cells is not None:
            assert caps.penetration_bound_cells >= 0.0, name
    table = bfemp.strategy_table()
    for name in STRATEGIES:
        assert name in table


def test_pairs_are_classified_by_body_kind_and_scripting():
    kinds = lambda scene: [k for k, _, _ in scene_pairs(scene.build())]  # noqa: E731
    assert kinds(block_on_plate(plate_fixed="all")) == ["mpm-prescribed"]
    assert kinds(block_on_plate(plate_fixed="bottom")) == ["mpm-fem"]
    assert kinds(block_on_plate(plate_fixed="all", fem_block=True)) == ["fem-fem"]
    scene = bfemp.Scene(dim=2)  # two fully scripted bodies never meet: no pair
    for k in range(2):
        mesh = bfemp.shapes.rectangle((k, 0.0), (k + 0.5, 0.5), h=0.25)
        scene.add_fem(mesh, material=STIFF, prescribed=bfemp.motion.Fixed(), name=f"f{k}")
    assert kinds(scene) == []


@pytest.mark.parametrize("fem_block", [False, True])
def test_a_pair_the_strategy_does_not_couple_is_refused_with_the_names(fem_block):
    scene = block_on_plate(fem_block=fem_block)
    with pytest.raises(ValueError) as err:
        bfemp.Simulation(scene, strategy="single_field", dt="auto")
    text = str(err.value)
    assert "'single_field'" in text and "'plate'" in text and "'block'" in text
    assert "'barrier'" in text  # a strategy that would serve
    # explicitly allowed: runs, with the refusal's message as a warning the user sees
    with pytest.warns(bfemp.StepNoteWarning, match="UNCOUPLED"):
        sim = bfemp.Simulation(scene, strategy="single_field", dt="auto", allow_uncoupled=True)
    assert any(d.startswith("UNCOUPLED") for d in sim.diagnostics)


def test_mpm_and_fem_without_contact_settings_warn_once_naming_the_bodies():
    with pytest.warns(bfemp.StepNoteWarning, match="NO_CONTACT") as record:
        sim = bfemp.Simulation(block_on_plate(contact=False), dt=1e-3)
    messages = [str(w.message) for w in record if "NO_CONTACT" in str(w.message)]
    assert len(messages) == 1 and "'plate'" in messages[0] and "'block'" in messages[0]
    assert len([d for d in sim.diagnostics if d.startswith("NO_CONTACT")]) == 1
    with warnings.catch_warnings():  # the control: with contact settings, no such warning
        warnings.simplefilter("error", bfemp.StepNoteWarning)
        bfemp.Simulation(block_on_plate(contact=True), dt=1e-3)


def test_step_notes_are_warned_once_and_counted_in_the_manifest_and_info(tmp_path, capsys):
    # a falling block at the stable step of its start: it speeds up past it, and the explicit
    # engine notes CFL_ABOVE_SAFETY in (almost) every step
    scene = bfemp.Scene(dim=2, gravity=(0.0, -9.81))
    x, vol = bfemp.sample.box((0.0, 0.0), (0.2, 0.2), dx=0.05, ppc=4)
    scene.add_mpm(x, vol, material=SOFT, velocity=(0.0, -3.0), name="block")
    scene.set_grid(dx=0.05)
    sim = bfemp.Simulation(scene, strategy="single_field", dt="auto")
    out = tmp_path / "run"
    with pytest.warns(bfemp.StepNoteWarning, match="CFL_ABOVE_SAFETY") as record:
        sim.run(t_end=12 * sim.dt, out=out, progress=False)
    warned = [w for w in record if "CFL_ABOVE_SAFETY" in str(w.message)]
    count = sim.note_counts["CFL_ABOVE_SAFETY"]
    assert len(warned) == 1 and count >= 5  # once warned, every occurrence counted
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["notes"] == {"CFL_ABOVE_SAFETY": count}
    assert manifest["sessions"][-1]["notes"] == {"CFL_ABOVE_SAFETY": count}
    assert main(["info", str(out)]) == 0
    assert f"CFL_ABOVE_SAFETY x {count}" in capsys.readouterr().out


def test_penetration_depth_is_the_distance_to_the_boundary_of_the_body_a_point_is_in():
    scene = bfemp.Scene(dim=2)
    plate = bfemp.shapes.rectangle((-0.5, -0.2), (0.5, 0.0), h=0.05)
    scene.add_fem(plate, material=STIFF, prescribed=bfemp.motion.Fixed(), name="plate")
    x = np.array([[0.01, 0.1], [0.11, -0.03], [-0.21, -0.07], [0.44, -0.19]])
    scene.add_mpm(x, np.full(4, 1e-4), material=SOFT, name="dots")
    scene.set_grid(dx=0.05)
    model = scene.build()
    check = PenetrationCheck.for_model(model)
    found = check.points(model.initial_state())
    # particles 1, 2, 3 are inside (ids after the FEM nodes), at 0.03, 0.07 and 0.01 m
    assert sorted(found.point - model.n_fem_nodes) == [1, 2, 3]
    order = np.argsort(found.point)
    np.testing.assert_allclose(found.depth[order], [0.03, 0.07, 0.01], atol=1e-12)
    assert check.depth(model.initial_state()) == pytest.approx(0.07, abs=1e-12)
    # a FEM body alone, or no FEM body: nothing to check
    alone = bfemp.Scene(dim=2)
    alone.add_fem(plate, material=STIFF, name="plate")
    assert PenetrationCheck.for_model(alone.build()) is None


def test_every_strategy_gives_the_same_protocol_on_one_small_scene():
    """Each strategy that couples the scene runs it and reports the same metrics columns,
    including the shared penetration_depth; single_field is refused (uncoupled pair)."""
    columns = {}
    for name, cls in STRATEGIES.items():
        scene = block_on_plate(plate_fixed="all")
        if cls.capabilities.couples("mpm-prescribed") is None:
            with pytest.raises(ValueError, match=name):
                bfemp.Simulation(scene, strategy=name, dt="auto")
            continue
        dt = 2e-3 if not cls.explicit else "auto"
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", bfemp.StepNoteWarning)
            sim = bfemp.Simulation(scene, strategy=name, dt=dt)
            for _ in range(3):
                sim.step()
        cols = set(sim.metrics.columns)
        assert "penetration_depth" in cols and "min_distance" in cols, name
        assert np.all(np.isfinite(sim.metrics.column("penetration_depth"))), name
        view = sim.stepper.contact()
        assert view.fem_forces.shape == sim.state.fem_x.shape, name
        assert view.particle_forces.shape == sim.state.mpm_x.shape, name
        # common columns: all but timings, iteration counts and the strategy's own parameters
        own = set(view.parameters)
        columns[name] = {c for c in cols if not c.startswith(("time_", "iterations_"))} - own
    first = next(iter(columns.values()))
    for name, cols in columns.items():
        assert cols == first, (name, cols ^ first)


def test_the_strategies_command_prints_the_table(capsys):
    assert main(["strategies"]) == 0
    text = capsys.readouterr().out
    for name in STRATEGIES:
        assert name in text
    assert main(["strategies", "--json"]) == 0
    table = json.loads(capsys.readouterr().out)
    assert table["single_field"]["pairs"] == {"mpm-mpm": "grid"}
    assert table["barrier"]["penetration_bound_cells"] == 0.0


def test_a_scene_file_may_allow_uncoupled_pairs(tmp_path):
    text = """
[scene]
dim = 2
[simulation]
strategy = "single_field"
dt = "auto"
allow_uncoupled = true
[grid]
dx = 0.05
[materials.m]
type = "neo_hookean"
E = 1e5
nu = 0.3
density = 1000.0
[[fem]]
name = "plate"
material = "m"
mesh = { shape = "rectangle", lower = [-0.3, -0.1], upper = [0.3, 0.0], h = 0.05 }
prescribed = { type = "fixed" }
[[mpm]]
name = "block"
material = "m"
particles = { sample = "box", lower = [-0.1, 0.005], upper = [0.1, 0.205], ppc = 4 }
"""
    path = tmp_path / "s.toml"
    path.write_text(text)
    with pytest.warns(bfemp.StepNoteWarning, match="UNCOUPLED"):
        sim = bfemp.Simulation.from_file(path)
    assert sim.settings["allow_uncoupled"] is True
    path.write_text(text.replace("allow_uncoupled = true\n", ""))
    with pytest.raises(ValueError, match="does not couple"):
        bfemp.Simulation.from_file(path)


def test_lr_refuses_a_scene_without_an_mpm_body_naming_who_serves():
    with pytest.raises(ValueError, match="only scenes with an MPM body") as err:
        bfemp.Simulation(block_on_plate(fem_block=True), strategy="lr", dt="auto")
    assert "'barrier'" in str(err.value) and "'lr'" in str(err.value)


def test_augury_says_when_its_contact_grid_is_too_coarse_for_its_stated_bound():
    """A coarse FEM plate (edge 0.15 m) under a fine MPM grid (5 cm): augury's contact grid is
    6 MPM cells, beyond what its penetration bound is claimed for; the control (plate edge 5 cm,
    contact grid 2 cells) gets no such note."""
    for h, expect in ((0.15, True), (0.05, False)):
        scene = bfemp.Scene(dim=2, gravity=(0.0, -9.81))
        plate = bfemp.shapes.rectangle((-0.3, -0.15), (0.3, 0.0), h=h)
        scene.add_fem(plate, material=STIFF, prescribed=bfemp.motion.Fixed(), name="plate")
        x, vol = bfemp.sample.box((-0.1, 0.005), (0.1, 0.205), dx=0.05, ppc=4)
        scene.add_mpm(x, vol, material=SOFT, name="block")
        scene.set_grid(dx=0.05)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", bfemp.StepNoteWarning)
            sim = bfemp.Simulation(scene, strategy="augury", dt="auto")
            sim.step()
        coarse = [w for w in caught if "AUGURY_COARSE_GRID" in str(w.message)]
        assert (len(coarse) == 1) == expect, h
        assert ("AUGURY_COARSE_GRID" in sim.note_counts) == expect
