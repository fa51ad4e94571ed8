"""What the library warns about reaches a plain Python script (issue 42, defect 1) and false
energy growth of a scene at rest (issue 42, defect 4).

Defect 1: ``bfemp`` installs a ``NullHandler`` (library convention), which switched Python's
last-resort log output off: lr's grid warning, P2G and output warnings were printed by the
command line but never seen by a script, and ``sim.diagnostics`` stayed empty. They now go
through ``bfemp.errors.warn_user``: a ``bfemp.BfempWarning`` (Python's ``warnings``), the log,
and, while a simulation works, its ``note_counts`` and ``diagnostics`` (once per name).
Defect 4: a free block at rest far from the origin (no gravity, E(0) = 0) reported
ENERGY_GROWTH of a 300-digit percentage for 1.8e-19 J of round-off.
"""

import re
import subprocess
import sys
import textwrap
import warnings

import numpy as np
import pytest

import bfemp
from bfemp.plotting import plot_series

SOFT = bfemp.NeoHookean(E=1e5, nu=0.3, density=500.0)

# an lr scene whose MPM grid (dx = 0.05 m) is finer than twice the FEM boundary edge (0.05 m)
LR_GRID_FINE_SCRIPT = textwrap.dedent(
    """
    import bfemp
    scene = bfemp.Scene(dim=2, gravity=(0.0, -9.81))
    mat = bfemp.NeoHookean(E=1e5, nu=0.3, density=500.0)
    plate = bfemp.shapes.rectangle((-0.3, -0.1), (0.3, 0.0), h=0.05)
    scene.add_fem(plate, material=mat, name="plate", prescribed=bfemp.motion.Fixed())
    x, vol = bfemp.sample.box((-0.1, 0.005), (0.1, 0.205), dx=0.05, ppc=4)
    scene.add_mpm(x, vol, material=mat, name="block")
    scene.set_grid(dx=0.05)
    sim = bfemp.Simulation(scene, strategy="lr", dt="auto")
    print("diagnostics:", [d.split(":")[0] for d in sim.diagnostics])
    print("counts:", sim.note_counts)
    """
)


def test_a_plain_script_sees_the_library_warnings_without_configuring_logging():
    """The script configures nothing: the warning must reach its stderr (it did not: the
    NullHandler swallowed the log record) and ``sim.diagnostics`` (it stayed empty)."""
    done = subprocess.run(
        [sys.executable, "-c", LR_GRID_FINE_SCRIPT],
        capture_output=True,
        text=True,
        timeout=600,
        check=True,
    )
    assert done.stderr.count("BfempWarning: LR_GRID_FINE: the MPM grid (dx = 0.05 m)") == 1
    assert "diagnostics: ['LR_GRID_FINE']" in done.stdout
    assert "counts: {'LR_GRID_FINE': 1}" in done.stdout


def test_warnings_outside_a_simulation_are_issued_each_time_and_can_be_silenced(tmp_path, caplog):
    h = np.array([1.0, 2.0, 3.0])
    with pytest.warns(bfemp.BfempWarning, match="PLOT_HIDDEN_VALUES: .*ys\\['bad'\\]"):
        plot_series(h, {"bad": h - 2.0}, tmp_path / "a.png", logy=True)
    assert "PLOT_HIDDEN_VALUES" in caplog.text  # the log keeps it for the command line
    with warnings.catch_warnings():
        warnings.simplefilter("error", bfemp.BfempWarning)
        plot_series(h, {"good": h}, tmp_path / "b.png", logy=True)  # the control: no warning
        warnings.simplefilter("ignore", bfemp.BfempWarning)  # one filter silences them all
        plot_series(h, {"bad": h - 2.0}, tmp_path / "c.png", logy=True)
    assert issubclass(bfemp.StepNoteWarning, bfemp.BfempWarning)


def _block_at_rest(lower):
    """An MPM block of 0.4 m x 0.4 m (80 kg/m) at rest at ``lower`` (m), no gravity: E = 0."""
    scene = bfemp.Scene(dim=2, gravity=(0.0, 0.0))
    lower = np.asarray(lower, dtype=float)
    x, vol = bfemp.sample.box(tuple(lower), tuple(lower + 0.4), dx=0.1, ppc=4)
    scene.add_mpm(x, vol, material=SOFT, name="block")
    scene.set_grid(dx=0.1)
    return bfemp.Simulation(scene, integrator="newmark", dt=1e-2, tol=1e-8)


def test_a_block_at_rest_far_from_the_origin_reports_no_energy_growth():
    """E(0) = 0 and round-off of the particles' kinetic energy of order 1e-19 J/m (measured
    1.6e-19 J/m after 5 steps): judged against the energy scale (floored at the elastic energy
    at a strain of 1e-6, 6.2e-9 J/m here), no growth; the old check divided by
    max(|E(0)|, 1e-300) and warned of a 300-digit percentage."""
    sim = _block_at_rest((1000.0, 1000.0))
    with warnings.catch_warnings():
        warnings.simplefilter("error", bfemp.StepNoteWarning)
        for _ in range(5):
            sim.step()
    e = sim.metrics.column("energy_total")
    assert e[0] == 0.0 and 0.0 < np.max(np.abs(e)) < 1e-15  # round-off, nothing physical
    assert "ENERGY_GROWTH" not in sim.note_counts and not sim.diagnostics


def test_energy_growth_of_a_scene_starting_at_zero_energy_is_still_reported():
    """The floor must not hide real growth: the same block at rest, with energy put in behind
    the integrator's back (a velocity kick after step 1), is reported with a sane percentage
    (the kick's energy against a scale that now includes it: 100 %), warned once and counted
    at every later step."""
    sim = _block_at_rest((1000.0, 1000.0))
    sim.step()
    sim.state.mpm_v[:] = (0.0, 1e-3)  # 1/2 m v^2 = 1/2 * 80 kg/m * 1e-6 m^2/s^2 = 4e-5 J/m
    with pytest.warns(bfemp.StepNoteWarning, match="ENERGY_GROWTH") as record:
        for _ in range(4):
            sim.step()
    assert len([w for w in record if "ENERGY_GROWTH" in str(w.message)]) == 1
    assert sim.note_counts["ENERGY_GROWTH"] == 4
    (message,) = [d for d in sim.diagnostics if d.startswith("ENERGY_GROWTH")]
    percent = float(re.search(r"grew by ([0-9.e+-]+) %", message).group(1))
    assert 90.0 <= percent <= 100.0 + 1e-9
