"""A step writes each position array once (issue 41): every explicit strategy, counted on the state.

The start state is a ``State`` subclass that counts assignments of ``fem_x`` and ``mpm_x`` with an
array it has not seen (a new position array; the unchanged arrays a ``dataclasses.replace`` carries
over are not writes) and remembers a copy of each; an array that changes after its assignment
(an in-place write such as ``new.fem_x[idx] += ...``) counts once more. ``replace`` keeps the
subclass, so the counter follows the steps.
"""

from collections import Counter
from dataclasses import fields

import numpy as np
import pytest

import bfemp
from bfemp.state import State

MAT = bfemp.NeoHookean(E=1e5, nu=0.3, density=1000.0)
POSITIONS = ("fem_x", "mpm_x")


class _Watched(State):
    """A state that records position writes in the class-level ``writes`` and ``assigned``;
    ``start`` holds the start state's arrays (carried over by ``replace``: not writes)."""

    writes: Counter = Counter()
    assigned: list = []
    start: list = []

    def __setattr__(self, name: str, value: object) -> None:
        known = [a for a, _, _ in _Watched.assigned] + _Watched.start
        if name in POSITIONS and not any(value is a for a in known):
            _Watched.writes[name] += 1
            _Watched.assigned.append((value, value.copy(), name))
        object.__setattr__(self, name, value)


def _watch(state: State) -> _Watched:
    return _Watched(**{f.name: getattr(state, f.name) for f in fields(state)})


def _counted_writes() -> Counter:
    """The writes of the step so far, in-place changes after assignment included."""
    writes = Counter(_Watched.writes)
    for array, copy, name in _Watched.assigned:
        if not np.array_equal(array, copy):
            writes[name] += 1
    return writes


def _scene(strategy: str) -> bfemp.Scene:
    """A free FEM block and an MPM block moving into each other (contact on the first steps)."""
    scene = bfemp.Scene(dim=2, gravity=(0.0, -9.81))
    block = bfemp.shapes.rectangle((0.21, 0.0), (0.41, 0.2), h=0.05)
    scene.add_fem(block, material=MAT, velocity=(-1.0, 0.0), name="fem")
    x, vol = bfemp.sample.box((0.0, 0.0), (0.2, 0.2), dx=0.05, ppc=4)
    scene.add_mpm(x, vol, material=MAT, velocity=(1.0, 0.0), name="mpm")
    scene.set_grid(dx=0.05)
    if strategy == "two_stage":
        scene.set_contact(dhat=5e-3, kappa=1e4)
    return scene


@pytest.mark.parametrize("strategy", ["single_field", "augury", "lr", "two_stage"])
def test_every_explicit_strategy_writes_each_position_once_per_step(strategy):
    transfer = "flip" if strategy == "lr" else "apic"
    sim = bfemp.Simulation(
        _scene(strategy), strategy=strategy, transfer=transfer, dt="auto", allow_uncoupled=True
    )
    state = _watch(sim.state)
    moved = Counter()
    for _ in range(3):
        _Watched.writes.clear()
        _Watched.assigned.clear()
        _Watched.start[:] = [state.fem_x, state.mpm_x]
        new, report = sim.stepper.step(state)
        assert isinstance(new, _Watched), f"{strategy}: the step built its state another way"
        assert _counted_writes() == Counter(fem_x=1, mpm_x=1), report.message
        for name in POSITIONS:
            moved[name] += not np.array_equal(getattr(new, name), getattr(state, name))
        state = new
    assert moved == Counter(fem_x=3, mpm_x=3)  # the bodies move: the writes are real
