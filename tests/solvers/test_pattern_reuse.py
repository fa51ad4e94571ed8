"""Index arrays of a fixed pattern reused by identity: stacking, frame rotation, assembly."""

import numpy as np
import pytest

from bfemp.frames import NodeFrames
from solvers.assembly import TripletAssembler, Triplets, TripletStacker
from solvers.linear import CholmodSolver


def _random_triplets(rng, n, m):
    rows = rng.integers(0, n, m)
    cols = rng.integers(0, n, m)
    return Triplets(np.concatenate([rows, cols]), np.concatenate([cols, rows]), rng.random(2 * m))


def test_stacker_reuses_index_arrays_while_the_parts_bring_the_same_arrays():
    rng = np.random.default_rng(0)
    a, b = _random_triplets(rng, 30, 50), _random_triplets(rng, 30, 40)
    empty = Triplets.empty()
    stacker = TripletStacker()
    first = stacker.stack([a, empty, b])
    # new values, same index arrays (and a fresh empty part): the stacked indices are reused
    a2 = Triplets(a.rows, a.cols, 2.0 * a.vals)
    second = stacker.stack([a2, Triplets.empty(), b])
    assert second.rows is first.rows and second.cols is first.cols
    np.testing.assert_array_equal(second.vals, np.concatenate([2.0 * a.vals, b.vals]))
    # a part with other index arrays: stacked afresh
    c = _random_triplets(rng, 30, 40)
    third = stacker.stack([a, c])
    assert third.rows is not first.rows
    np.testing.assert_array_equal(third.rows, np.concatenate([a.rows, c.rows]))


def test_assembler_result_is_the_same_for_reused_and_for_copied_index_arrays():
    rng = np.random.default_rng(1)
    t = _random_triplets(rng, 40, 300)
    asm = TripletAssembler(40)
    m1 = asm.assemble(t)
    t2 = Triplets(t.rows, t.cols, 3.0 * t.vals)  # same objects: no comparison
    np.testing.assert_allclose(asm.assemble(t2).toarray(), 3.0 * m1.toarray())
    t3 = Triplets(t.rows.copy(), t.cols.copy(), t.vals)  # equal copies: compared, reused
    np.testing.assert_allclose(asm.assemble(t3).toarray(), m1.toarray())
    assert asm.n_rebuilds == 1


def _frames(rng, dim, n_nodes, rotated):
    q = np.linalg.qr(rng.standard_normal((rotated.size, dim, dim)))[0]
    return NodeFrames(dim, dim * n_nodes, rotated, q)


def test_rotate_with_a_kept_pattern_equals_a_fresh_rotation():
    rng = np.random.default_rng(2)
    dim, n_nodes = 3, 12
    frames = _frames(rng, dim, n_nodes, np.array([1, 4, 7]))
    t = _random_triplets(rng, dim * n_nodes, 200)
    first = frames.rotate(t)
    t2 = Triplets(t.rows, t.cols, rng.random(t.vals.size))
    second = frames.rotate(t2)
    assert second.rows is first.rows  # the pattern work was kept
    assert second.pattern_key == first.pattern_key is not None  # and the assembler is told so
    fresh = NodeFrames(dim, dim * n_nodes, frames.nodes, frames.frames).rotate(t2)
    asm = TripletAssembler(dim * n_nodes)
    np.testing.assert_allclose(asm.assemble(second).toarray(), asm.assemble(fresh).toarray())
    # and it is Q^T H Q
    q = np.eye(dim * n_nodes)
    for k, node in enumerate(frames.nodes):
        q[node * dim : (node + 1) * dim, node * dim : (node + 1) * dim] = frames.frames[k]
    h = TripletAssembler(dim * n_nodes).assemble(t2).toarray()
    np.testing.assert_allclose(asm.assemble(second).toarray(), q.T @ h @ q, atol=1e-12)
    # another pattern: rotated afresh, not with the kept one
    t3 = _random_triplets(rng, dim * n_nodes, 150)
    third = frames.rotate(t3)
    assert third.pattern_key != first.pattern_key
    h3 = TripletAssembler(dim * n_nodes).assemble(t3).toarray()
    np.testing.assert_allclose(asm.assemble(third).toarray(), q.T @ h3 @ q, atol=1e-12)


def test_barrier_stepper_keeps_the_hessian_pattern_across_steps():
    from benchmarks import catalogue
    from bfemp.integrators import BACKWARD_EULER
    from bfemp.steppers.barrier import BarrierOptions, BarrierStepper

    model = catalogue.fem_block_scene(2, (12, 3)).build()
    stepper = BarrierStepper(
        model, integrator=BACKWARD_EULER, dt=0.05, options=BarrierOptions(tol=1e-6)
    )
    state = stepper.initialize(model.initial_state())
    total = 0
    for _ in range(3):
        state, report = stepper.step(state)
        total += report.newton_iterations
    assert total >= 3  # Newton ran every step
    # FEM only: the Hessian's pattern never changes, so it was built once for all steps
    assert stepper._solver._assembler.n_rebuilds == 1
    if isinstance(stepper.linear_solver, CholmodSolver):  # SuperLU analyses at every solve
        assert stepper.linear_solver.n_symbolic == 1


@pytest.mark.parametrize("kind", ["fem", "mpm_on_slip_floor"])
def test_triplet_index_arrays_are_the_same_objects_from_step_to_step(kind):
    """Where the DOF numbering holds, the terms hand the same index arrays each step, so the
    stacked (and, with slip frames, rotated) pattern is not rebuilt (it cost 0.33 + 0.26 s a
    step on the 3D perf_fem mesh and 0.19 s on the 3D perf_mpm block, measured)."""
    from benchmarks import catalogue
    from bfemp.integrators import BACKWARD_EULER
    from bfemp.steppers.barrier import BarrierOptions, BarrierStepper

    if kind == "fem":
        model, dt = catalogue.fem_block_scene(2, (12, 3)).build(), 0.05
    else:
        model, dt = catalogue.mpm_block_scene(2, (8, 8), 4).build(), 0.01
    stepper = BarrierStepper(
        model, integrator=BACKWARD_EULER, dt=dt, options=BarrierOptions(tol=1e-6)
    )
    state = stepper.initialize(model.initial_state())
    seen = []
    for _ in range(3):
        state, _ = stepper.step(state)
        pot = stepper.potential
        seen.append((pot.frames, pot._stacker._rows))
    assert seen[1][1] is not None and seen[1][1] is seen[2][1]  # the stacked rows: kept
    if kind != "fem":
        assert seen[1][0] is not None  # the slip floor rotates the bottom nodes
        assert seen[1][0] is seen[2][0]  # frames kept, with their rotated pattern
