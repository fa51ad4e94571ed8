"""``BarrierStepper.phases``: the documented inspection hook begins a step without taking it."""

import numpy as np

from bfemp.contact.term import BarrierTerm
from bfemp.integrators import BACKWARD_EULER
from bfemp.steppers.barrier import BarrierOptions, BarrierStepper
from tests.bfemp.conftest import pressed_block_scene

STATE_FIELDS = ("fem_x", "fem_v", "mpm_x", "mpm_v", "mpm_F", "mpm_C", "t")


def _stepper(model):
    return BarrierStepper(
        model, integrator=BACKWARD_EULER, dt=1e-2, options=BarrierOptions(tol=1e-6)
    )


def test_phases_describe_the_step_and_a_step_after_them_is_bit_identical():
    """A scripted plate presses a particle block (barrier contact from the fourth step, lagged
    friction, sticky floor): stepping after ``phases`` gives the state and iteration counts
    of stepping without, bit for bit, and ``phases`` sees the step's start."""
    model = pressed_block_scene(friction_iterations=20).build()
    plain, inspected = _stepper(model), _stepper(model)
    a = plain.initialize(model.initial_state())
    b = inspected.initialize(model.initial_state())
    pairs = []
    for _ in range(5):
        phases = inspected.phases(b)
        layout = phases.layout
        assert phases.x0.shape == (layout.n_dof,) == phases.context.x_hat.shape
        assert isinstance(phases.barrier, BarrierTerm) and phases.friction is not None
        assert phases.linear_solver is inspected.linear_solver
        # x0: the unknowns at t^n; the particles' grid nodes start where the grid puts them
        fem = layout.free_nodes < layout.n_fem
        assert not fem.any()  # the plate is scripted: every unknown is a grid node
        y = phases.potential.to_unknowns(phases.x0)
        phases.potential.solution_changed(y)
        assert np.isfinite(phases.potential.value(y))
        a, report_a = plain.step(a)
        b, report_b = inspected.step(b)
        pairs.append(report_b.contact_pairs)
        assert report_a.iterations == report_b.iterations
        for name in STATE_FIELDS:
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert pairs[0] == 0 and pairs[-1] > 0  # the plate reached the block within the steps
