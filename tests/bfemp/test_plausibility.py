"""Implausible discretisations and runs that lose most of their energy are named, not silent
(issue 42, item 5; thresholds and their reasons: ``bfemp.plausibility``)."""

import re
import warnings

import numpy as np
import pytest

import bfemp
from bfemp.plausibility import (
    ENERGY_LOSS_RUN_FRACTION,
    MAX_DT_OVER_WAVE_PERIOD,
    EnergyLossCheck,
)

SOFT = bfemp.NeoHookean(E=1e6, nu=0.3, density=1000.0)


def _plausibility_notes(build):
    """The PlausibilityWarning messages issued while ``build()`` runs, and its result."""
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        result = build()
    return [
        str(w.message) for w in record if issubclass(w.category, bfemp.PlausibilityWarning)
    ], result


def _mpm_block(dx):
    scene = bfemp.Scene(dim=2)
    x, vol = bfemp.sample.box((0.0, 0.0), (0.34, 0.34), dx=0.04, ppc=4)  # 0.02 m apart
    scene.add_mpm(x, vol, material=SOFT, name="block")
    scene.set_grid(dx=dx)
    return scene


def test_a_grid_far_coarser_than_the_particles_is_named_with_its_ratios():
    notes, sim = _plausibility_notes(lambda: bfemp.Simulation(_mpm_block(20.0), dt=1e-3))
    grid = [n for n in notes if n.startswith("IMPLAUSIBLE_GRID")]
    # one warning (a simulation warns the first note of a name) with both findings: particles
    # per cell and cells across the body
    assert len(grid) == 1, notes
    ppc = float(re.search(r"has ([0-9.e+]+) particles per grid cell", grid[0]).group(1))
    assert ppc == pytest.approx((20.0 / 0.02) ** 2, rel=1e-3)  # by volume: (dx / spacing)^2
    across = float(re.search(r"is ([0-9.e+-]+) grid cells across", grid[0]).group(1))
    assert across == pytest.approx(0.34 / 20.0, rel=1e-2)  # 17 particles of 0.02 m
    assert grid[0].count("'block'") == 2
    assert set(grid) <= set(sim.diagnostics)
    # the control: 2 particles per cell edge on a body 9 cells across
    notes, sim = _plausibility_notes(lambda: bfemp.Simulation(_mpm_block(0.04), dt=1e-3))
    assert notes == [] and not any("IMPLAUSIBLE" in d for d in sim.diagnostics)


def _colliding_blocks(integrator, dt, gap=0.05):
    """Two 0.2 m blocks meeting at 2 m/s; wave period 2 L / c_p = 0.0109 s."""
    scene = bfemp.Scene(dim=2)
    block = bfemp.shapes.rectangle((0.0, 0.0), (0.2, 0.2), h=0.05)
    scene.add_fem(block, material=SOFT, velocity=(1.0, 0.0), name="a")
    other = bfemp.shapes.rectangle((0.2 + gap, 0.0), (0.4 + gap, 0.2), h=0.05)
    scene.add_fem(other, material=SOFT, velocity=(-1.0, 0.0), name="b")
    scene.set_contact(dhat=1e-3, kappa=1e5)
    return bfemp.Simulation(scene, integrator=integrator, dt=dt, tol=1e-6)


def test_a_step_above_the_wave_period_is_named_unless_the_integrator_damps_by_design():
    period = 2 * 0.2 / SOFT.p_wave_speed
    notes, _ = _plausibility_notes(lambda: _colliding_blocks("newmark_implicit_contact", 0.1))
    assert len(notes) == 1 and notes[0].startswith("IMPLAUSIBLE_DT"), notes
    ratio = float(re.search(r"is ([0-9.]+) times the wave period", notes[0]).group(1))
    assert ratio == pytest.approx(0.1 / period, rel=1e-2)
    assert "'a'" in notes[0]
    ok_dt = 0.9 * MAX_DT_OVER_WAVE_PERIOD * period
    notes, _ = _plausibility_notes(lambda: _colliding_blocks("newmark_implicit_contact", ok_dt))
    assert notes == []
    # backward Euler at the same large step: the quasi-static use, not named
    notes, _ = _plausibility_notes(lambda: _colliding_blocks("backward_euler", 0.1))
    assert notes == []
    # without contact nothing collides: the mid-point rule keeps the unresolved modes' energy
    scene = bfemp.Scene(dim=2)
    scene.add_fem(bfemp.shapes.rectangle((0.0, 0.0), (0.2, 0.2), h=0.05), material=SOFT)
    notes, _ = _plausibility_notes(lambda: bfemp.Simulation(scene, integrator="newmark", dt=0.1))
    assert notes == []


def test_an_impact_that_loses_most_of_the_energy_gets_one_note():
    sim = _colliding_blocks("newmark_implicit_contact", 0.1)
    with pytest.warns(bfemp.PlausibilityWarning, match="ENERGY_LOSS"):
        sim.run(1.0, progress=False)
    e = sim.metrics.column("energy_total")
    assert e[-1] < 0.5 * e[0]  # measured 74 % lost
    assert len([d for d in sim.diagnostics if d.startswith("ENERGY_LOSS")]) == 1


def test_a_resolved_impact_and_a_damping_integrator_get_no_energy_note():
    resolved = _colliding_blocks("newmark_implicit_contact", 2.5e-3)
    resolved.run(0.15, progress=False)  # through the impact: measured 15 % lost
    e = resolved.metrics.column("energy_total")
    assert 0.05 * e[0] < e[0] - e.min() < ENERGY_LOSS_RUN_FRACTION * e[0]
    assert not any(d.startswith("ENERGY_LOSS") for d in resolved.diagnostics)
    damped = _colliding_blocks("backward_euler", 0.1)  # dissipates by design: not checked
    damped.run(1.0, progress=False)
    e = damped.metrics.column("energy_total")
    assert e[-1] < 0.5 * e[0]
    assert not any(d.startswith("ENERGY_LOSS") for d in damped.diagnostics)


def test_an_inelastic_contact_by_design_gets_no_energy_note():
    # augury's impact without iterations sticks (AUG): the two blocks keep half the energy or
    # less, which is its contact's design, not a discretisation gone wrong
    from bfemp.steppers.augury import AuguryOptions

    scene = bfemp.Scene(dim=2)
    mat = bfemp.NeoHookean(E=1e5, nu=0.3, density=1000.0)
    scene.add_fem(
        bfemp.shapes.rectangle((0, 0), (0.2, 0.2), h=0.05), material=mat, velocity=(1.0, 0.0)
    )
    scene.add_fem(
        bfemp.shapes.rectangle((0.25, 0.05), (0.45, 0.25), h=0.05),
        material=mat,
        velocity=(-1.0, 0.0),
    )
    opts = AuguryOptions(iterations=0)
    sim = bfemp.Simulation(scene, strategy="augury", options=opts, dt="auto")
    sim.run(0.1, progress=False)
    e = sim.metrics.column("energy_total")
    assert e[-1] < (1.0 - ENERGY_LOSS_RUN_FRACTION) * e[0]  # measured 51 % lost by 0.062 s
    assert not any(d.startswith("ENERGY_LOSS") for d in sim.diagnostics)


def test_energy_loss_is_measured_against_the_motion_not_the_height():
    # a block falling 1 m from rest (total energy 0 at the start, gravity's zero at its start)
    # keeps its energy while it falls, then loses 30 % of its kinetic energy in one step
    check = EnergyLossCheck("")
    check.start(np.array([0.0]), np.array([0.0]))
    kinetic = np.linspace(0.0, 10.0, 11)
    for k in kinetic[1:]:
        assert check.check(0.0, float(k), 0.1) is None
    note = check.check(-3.0, 7.0, 1.1)
    assert note is not None and note.startswith("ENERGY_LOSS") and "30 %" in note
    assert check.check(-9.0, 1.0, 1.2) is None  # once per run
    assert EnergyLossCheck("friction, mu up to 0.3").check(-9.0, 1.0, 1.0) is None


def test_energy_loss_below_the_noise_of_the_total_is_not_counted():
    # a body at rest 100 m above gravity's zero (1e3 J of potential energy): a 1e-9 J wobble of
    # the total is round-off and Newton tolerance, however little energy is in motion
    check = EnergyLossCheck("")
    check.start(np.array([1e3]), np.array([1e-9]))
    assert check.check(1e3 - 1e-9, 1e-9, 0.1, magnitude=1e3) is None
    note = check.check(1e3 - 1e-2, 1e-9, 0.2, magnitude=1e3)  # well above the noise: named
    assert note is not None and note.startswith("ENERGY_LOSS")
