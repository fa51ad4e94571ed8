"""The lagged-friction loop of Algorithm 1 stops early, unconverged and said so, when it stalls."""

import logging

import pytest

import bfemp
from bfemp.contact.friction import FrictionTerm
from bfemp.steppers._barrier_solve import ScriptedSolve, stalled
from tests.bfemp.conftest import pressed_block_scene

WINDOW, FACTOR = ScriptedSolve.STALL_WINDOW, ScriptedSolve.STALL_FACTOR


@pytest.mark.parametrize("rate", [0.1, 0.5, 0.75])
def test_a_contracting_loop_never_stalls(rate):
    moves = [0.1 * rate**k for k in range(40)]
    assert not any(stalled(moves[:n], WINDOW, FACTOR) for n in range(1, 41))


def test_moves_with_no_trend_stall_once_the_window_follows_a_first_move():
    moves = [1.2e-3, 0.9e-3, 1.5e-3, 1.1e-3, 0.8e-3]
    assert [stalled(moves[:n], WINDOW, FACTOR) for n in range(1, 6)] == [
        False,
        False,
        False,
        True,
        True,
    ]


def test_a_bump_before_a_halving_is_not_a_stall():
    # the third move is large, but the fourth is below half the first: still converging
    assert not stalled([1e-2, 2e-2, 3e-2, 4e-3], WINDOW, FACTOR)
    assert stalled([1e-2, 2e-2, 3e-2, 6e-3], WINDOW, FACTOR)


def _pressed_block(cap: int) -> bfemp.Simulation:
    """A particle block pressed and dragged by a scripted FEM plate at mu = 0.5."""
    return bfemp.Simulation(pressed_block_scene(cap), dt=1e-2, tol=1e-4)


def _friction_steps(sim: bfemp.Simulation, n: int) -> list:
    reports = [sim.step() for _ in range(n)]
    assert sim.stepper.barrier.pairs.n_pairs > 0  # pressed: friction acts
    return reports


def test_the_loop_stops_when_its_lagged_data_keep_it_from_converging(monkeypatch, caplog):
    """Lagging at positions scaled by 1 -/+ 1e-4 in turn (distances off by up to 0.06 mm, a
    different normal force every re-lag) keeps every re-solve moving: the loop stops after
    WINDOW + 2 minimisations, well before the cap, with the step reported unconverged."""
    cap = 20
    calls = {"n": 0}
    lag = FrictionTerm.lag

    def alternating_lag(self, x):
        calls["n"] += 1
        lag(self, x * (1.0 + (-1.0) ** calls["n"] * 1e-4))

    sim = _pressed_block(cap)
    _friction_steps(sim, 4)  # into contact
    monkeypatch.setattr(FrictionTerm, "lag", alternating_lag)
    with caplog.at_level(logging.INFO, logger="bfemp.steppers._barrier_solve"):
        with pytest.warns(bfemp.StepNoteWarning, match="FRICTION_LOOP"):  # a script sees it
            report = sim.step()
    assert report.friction_iterations == WINDOW + 2 < cap
    assert not report.friction_converged and sim.note_counts["FRICTION_LOOP"] == 1
    assert "friction loop stalled after" in caplog.text  # the detail, in the log

    # control: without the stall rule the same step runs the loop to its cap
    monkeypatch.setattr(ScriptedSolve, "STALL_WINDOW", 10 * cap)
    sim = _pressed_block(cap)
    monkeypatch.setattr(FrictionTerm, "lag", lag)
    _friction_steps(sim, 4)
    monkeypatch.setattr(FrictionTerm, "lag", alternating_lag)
    report = sim.step()
    assert report.friction_iterations == cap and not report.friction_converged


def test_negative_control_the_same_steps_lagged_as_they_are_converge():
    sim = _pressed_block(20)
    reports = _friction_steps(sim, 6)
    pressed = [r for r in reports if r.contact_pairs > 0]
    assert pressed and all(r.friction_converged for r in reports)
    assert max(r.friction_iterations for r in pressed) < WINDOW + 2
