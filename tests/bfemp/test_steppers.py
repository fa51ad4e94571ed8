"""The Stepper interface (issue 11): protocol, options, reports, contact view, metrics columns."""

import dataclasses
import math

import numpy as np
import pytest

import bfemp
from bfemp import scenefile
from bfemp.errors import SceneError
from bfemp.steppers import (
    STRATEGIES,
    BarrierOptions,
    BarrierStepper,
    ContactView,
    Stepper,
    StepReport,
    options_from_mapping,
    options_to_dict,
)
from tests.bfemp.conftest import block_on_fem_floor

MAT = bfemp.NeoHookean(E=1e6, nu=0.3, density=1000.0)


def test_every_registered_stepper_implements_the_protocol():
    for name, cls in STRATEGIES.items():
        assert cls.name == name
        assert issubclass(cls.Options, bfemp.StepperOptions) and cls.Options.strategy == name
        for member in ("initialize", "step", "stable_dt", "contact", "terms"):
            assert hasattr(cls, member), (name, member)
        for member in ("checkpoint_data", "restore_checkpoint_data"):
            assert callable(getattr(cls, member)), (name, member)
    sim = bfemp.Simulation(block_on_fem_floor(), dt=1e-3)
    assert isinstance(sim.stepper, Stepper)
    assert sim.stepper.stable_dt(sim.state) == math.inf


def test_options_are_frozen_validated_and_named():
    opts = BarrierOptions(tol=1e-7, max_newton_iterations=50)
    with pytest.raises(dataclasses.FrozenInstanceError):
        opts.tol = 1.0
    with pytest.raises(TypeError):
        BarrierOptions(1e-7)  # keyword-only
    with pytest.raises(ValueError, match=r"tol must be > 0 \(a Newton tolerance in m/s\)"):
        BarrierOptions(tol=0.0)
    with pytest.raises(ValueError, match="max_newton_iterations must be an integer >= 1"):
        BarrierOptions(max_newton_iterations=0)
    with pytest.raises(ValueError, match="linear_solver must be one of"):
        BarrierOptions(linear_solver="umfpack")
    assert options_to_dict(opts) == {
        "tol": 1e-7,
        "max_newton_iterations": 50,
        "warm_start": False,
        "linear_solver": "default",
        "velocity_update": "positions",
        "friction_back_solve": True,
    }
    with pytest.raises(ValueError, match="velocity_update must be one of"):
        BarrierOptions(velocity_update="residual")
    with pytest.raises(ValueError, match="friction_back_solve must be true or false, got 'no'"):
        BarrierOptions(friction_back_solve="no")


def test_options_from_a_mapping_refuse_unknown_fields_and_wrong_types():
    built = options_from_mapping(BarrierOptions, {"tol": 1e-5, "warm_start": True})
    assert built == BarrierOptions(tol=1e-5, warm_start=True)
    with pytest.raises(ValueError, match=r"unknown option 'tau' for strategy 'barrier'.*tol"):
        options_from_mapping(BarrierOptions, {"tau": 1e-3})
    with pytest.raises(ValueError, match=r"options\.warm_start: expected bool, got 'yes'"):
        options_from_mapping(BarrierOptions, {"warm_start": "yes"})
    with pytest.raises(ValueError, match=r"options\.max_newton_iterations: expected int"):
        options_from_mapping(BarrierOptions, {"max_newton_iterations": 2.5})


def test_simulation_takes_options_or_the_flat_keywords_not_both():
    scene = block_on_fem_floor()
    a = bfemp.Simulation(scene, dt=1e-3, options=BarrierOptions(tol=1e-7))
    b = bfemp.Simulation(scene, dt=1e-3, tol=1e-7)
    assert a.settings == b.settings and a.settings["tol"] == 1e-7
    assert a.settings["strategy"] == "barrier" and a.settings["linear_solver"] == "default"
    with pytest.raises(ValueError, match="either options=BarrierOptions"):
        bfemp.Simulation(scene, dt=1e-3, options=BarrierOptions(), tol=1e-7)
    with pytest.raises(ValueError, match=r"^Simulation.tol must be > 0"):
        bfemp.Simulation(scene, dt=1e-3, tol=0)
    with pytest.raises(ValueError, match="strategy must be one of"):
        bfemp.Simulation(scene, dt=1e-3, strategy="magic")
    with pytest.raises(ValueError, match="dt='auto' needs an explicit strategy"):
        bfemp.Simulation(scene, dt="auto")


def test_options_of_another_strategy_are_refused():
    @dataclasses.dataclass(frozen=True, kw_only=True)
    class OtherOptions(bfemp.StepperOptions):
        strategy = "other"

    with pytest.raises(ValueError, match=r"strategy 'barrier' takes BarrierOptions, got Other"):
        bfemp.Simulation(block_on_fem_floor(), dt=1e-3, options=OtherOptions())


def test_report_iterations_become_metrics_columns_and_contact_view_balances():
    sim = bfemp.Simulation(block_on_fem_floor(mu=0.2), dt=2e-3)
    for _ in range(60):
        report = sim.step()
    assert isinstance(report, StepReport)
    assert set(report.iterations) == {"newton", "friction"}
    assert report.newton_iterations == report.iterations["newton"] >= 1
    assert report.friction_iterations == report.iterations["friction"] >= 1
    with pytest.raises(TypeError):
        report.iterations["newton"] = 0  # read-only
    for column in ("iterations_newton", "iterations_friction", "min_distance", "kappa"):
        assert column in sim.metrics.columns
    np.testing.assert_array_equal(
        sim.metrics.column("iterations_newton")[1:].astype(int) >= 1, True
    )
    view = sim.stepper.contact()
    assert isinstance(view, ContactView) and view.pairs > 0 and 0 < view.min_distance < 5e-3
    assert view.energy > 0 and view.parameters["kappa"] == 1e5
    # resting block: the contact forces carry its weight, and they act equal and opposite
    weight = 9.81 * sim.model.mpm_mass.sum()
    on_block, on_floor = view.particle_forces.sum(0), view.fem_forces.sum(0)
    np.testing.assert_allclose(on_block + on_floor, 0.0, atol=1e-9 * weight)
    assert on_block[1] == pytest.approx(weight, rel=0.1)
    fem, mpm = sim.contact_forces()
    np.testing.assert_array_equal(mpm, view.particle_forces)
    assert sim.energies()["energy_contact"] == view.energy


def test_energies_and_columns_without_contact_have_no_contact_entries():
    scene = bfemp.Scene(dim=2, gravity=(0.0, -9.81))
    scene.add_fem(bfemp.shapes.rectangle((0, 0), (1, 0.2), h=0.1), material=MAT)
    sim = bfemp.Simulation(scene, dt=1e-3)
    sim.step()
    assert "energy_contact" not in sim.energies() and "min_distance" not in sim.metrics.columns
    view = sim.stepper.contact()
    assert view.pairs == 0 and math.isnan(view.energy) and not view.fem_forces.any()


def test_scene_file_options_table_is_read_checked_and_written(tmp_path):
    scene = block_on_fem_floor()
    text = scenefile.save(
        scene,
        simulation={"dt": 1e-3, "options": BarrierOptions(tol=2e-6, max_newton_iterations=40)},
        run={"t_end": 4e-3},
    )
    assert "[simulation.options]" in text
    sf = scenefile.loads(text)
    assert sf.simulation["options"] == BarrierOptions(tol=2e-6, max_newton_iterations=40)
    sim = bfemp.Simulation.from_file(sf)
    assert sim.settings["tol"] == 2e-6 and sim.settings["max_newton_iterations"] == 40
    sim.run(4e-3, progress=False)
    assert sim.state.step == 4
    unit = text.replace("tol = 2e-06", 'tol = "0.002 mm/s"')
    assert scenefile.loads(unit).simulation["options"].tol == pytest.approx(2e-6)
    with pytest.raises(SceneError, match=r"simulation\.options.*unknown option 'tau'"):
        scenefile.loads(text.replace("tol = 2e-06", "tau = 0.1"))
    with pytest.raises(SceneError, match=r"simulation\.options\.warm_start: expected bool"):
        scenefile.loads(text.replace("warm_start = false", 'warm_start = "no"'))
    with pytest.raises(SceneError, match=r"unit 'm' is a length"):
        scenefile.loads(text.replace("tol = 2e-06", 'tol = "2 m"'))


def test_checkpoint_hooks_are_declared_and_round_trip():
    scene = block_on_fem_floor()
    scene.set_contact(dhat=5e-3, kappa="auto", mu=0.0)
    sim = bfemp.Simulation(scene, dt=2e-3)
    assert sim.stepper.checkpoint_data() == {}
    for _ in range(20):
        sim.step()
    data = sim.stepper.checkpoint_data()
    assert set(data) == {"adaptive"}
    other = BarrierStepper(
        sim.model, integrator=sim.integrator, dt=sim.dt, options=BarrierOptions()
    )
    other.restore_checkpoint_data(data)
    assert other.adaptive == sim.stepper.adaptive
    with pytest.raises(ValueError, match="unknown checkpoint data"):
        other.restore_checkpoint_data({"augury_B": np.zeros(3)})


def _two_blocks_text(strategy_lines: str) -> str:
    """A scene file of two MPM blocks on a slip floor with the given [simulation] lines."""
    return f"""
[scene]
dim = 2
gravity = [0.0, -9.81]

[simulation]
{strategy_lines}

[run]
t_end = 0.02

[materials.soft]
type = "neo_hookean"
E = 1e5
nu = 0.3
density = 1000.0

[[mpm]]
name = "left"
material = "soft"
particles = {{ sample = "box", lower = [0.0, 0.1], upper = [0.2, 0.3], ppc = 4 }}

[[mpm]]
name = "right"
material = "soft"
particles = {{ sample = "box", lower = [0.3, 0.1], upper = [0.5, 0.3], ppc = 4 }}

[grid]
dx = 0.05

[[boundary]]
kind = "slip"
levelset = {{ type = "half_plane", point = [0.0, 0.0], normal = [0.0, 1.0] }}
"""


def test_one_scene_file_runs_under_both_strategies_with_their_options():
    barrier = scenefile.loads(
        _two_blocks_text('strategy = "barrier"\ndt = 2e-3\n[simulation.options]\ntol = 1e-5')
    )
    explicit = scenefile.loads(
        _two_blocks_text(
            'strategy = "single_field"\ndt = "auto"\n[simulation.options]\ncfl_safety_mpm = 0.3'
        )
    )
    sims = {}
    for sf in (barrier, explicit):
        sim = bfemp.Simulation.from_file(sf)
        sim.run(sf.run_settings()["t_end"], progress=False)
        sims[sim.strategy] = sim
    assert sims["barrier"].settings["tol"] == 1e-5
    explicit_sim = sims["single_field"]
    assert explicit_sim.settings["cfl_safety_mpm"] == 0.3
    assert explicit_sim.integrator.name == "symplectic_euler"
    assert explicit_sim.dt == pytest.approx(
        explicit_sim.stepper.stable_dt(explicit_sim.model.initial_state())
    )
    # the same metrics columns for energies, momenta and contact; iterations per strategy
    base = {c for c in sims["barrier"].metrics.columns if not c.startswith(("time_", "iter"))}
    other = {c for c in explicit_sim.metrics.columns if not c.startswith(("time_", "iter"))}
    assert base - {"residual"} == other - {"residual"}
    for sim in sims.values():  # both fell under gravity, onto nothing yet
        assert 0.02 - 1e-12 <= sim.state.t < 0.02 + sim.dt  # the step that reaches t_end
        assert sim.metrics.column("momentum_y")[-1] < 0
    with pytest.raises(SceneError, match=r"unknown option 'tol' for strategy 'single_field'"):
        scenefile.loads(
            _two_blocks_text('strategy = "single_field"\ndt = 1e-4\n[simulation.options]\ntol = 1')
        )
    with pytest.raises(SceneError, match=r"cfl_safety_mpm must lie in \(0, 1\]"):
        scenefile.loads(
            _two_blocks_text(
                'strategy = "single_field"\ndt = 1e-4\n[simulation.options]\ncfl_safety_mpm = 2.0'
            )
        )


def test_simulation_refuses_wrong_combinations_of_strategy_and_settings():
    scene = scenefile.loads(_two_blocks_text('strategy = "barrier"\ndt = 1e-3')).scene
    with pytest.raises(ValueError, match=r"tol belong to strategy 'barrier'"):
        bfemp.Simulation(scene, strategy="single_field", dt="auto", tol=1e-6)
    with pytest.raises(ValueError, match=r"takes SingleFieldOptions, got BarrierOptions"):
        bfemp.Simulation(scene, strategy="single_field", dt="auto", options=BarrierOptions())
    with pytest.raises(ValueError, match=r"is explicit: integrator must be 'symplectic_euler'"):
        bfemp.Simulation(scene, strategy="single_field", dt="auto", integrator="newmark")
    with pytest.raises(ValueError, match=r"'barrier' is implicit: integrator 'symplectic_euler'"):
        bfemp.Simulation(scene, dt=1e-3, integrator="symplectic_euler")
    with pytest.raises(ValueError, match=r"exceeds the explicit stable step .*mpm body"):
        bfemp.Simulation(scene, strategy="single_field", dt=1.0)
