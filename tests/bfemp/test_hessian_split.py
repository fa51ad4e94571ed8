"""The Hessian phase split by term: ``IncrementalPotential.hessian_seconds`` and the barrier
stepper's ``timings["hessian_projection"]`` (the elasticity terms' dP/dF projection to PSD)."""

import pytest

import bfemp
from tests.bfemp.conftest import pressed_block_scene


def test_hessian_split_covers_the_hessian_phase_and_names_the_projection():
    sim = bfemp.Simulation(pressed_block_scene(friction_iterations=2), dt=1e-2, tol=1e-4)
    potential = sim.stepper.potential
    for _ in range(4):  # the plate reaches the block in the fourth step
        before = potential.hessian_seconds()
        report = sim.step()
        after = potential.hessian_seconds()
        step = {k: v - before.get(k, 0.0) for k, v in after.items()}
        t = report.timings
        # one entry per potential, inertia and the stacking; the elasticity terms' phases below
        names = {term.name for term in potential.potentials}
        assert names | {"inertia", "stack"} == {k for k in step if "/" not in k}
        mpm = next(term.name for term in potential.potentials if term.name.startswith("mpm_"))
        whole = sum(v for k, v in step.items() if "/" not in k)
        # nested in Newton's hessian phase, and most of it (the rest: a few Python statements)
        assert 0.5 * t["hessian"] <= whole <= t["hessian"] + 1e-9, (whole, t["hessian"])
        projection = step[f"{mpm}/projection"]
        assert 0.0 < projection <= step[mpm]
        assert t["hessian_projection"] == pytest.approx(
            sum(v for k, v in step.items() if k.endswith("/projection")), rel=1e-12
        )
    assert report.contact_pairs > 0 and report.newton_iterations > 0
