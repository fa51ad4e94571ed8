"""perf_contact, quick mode: correctness facts behind the timings, not the timings themselves.

Both libraries see the same pairs, energies and gradients (up to the known scaling of their
barriers), the CCD step sizes of both are conservative against the exact time of impact, and the
rings breakdown is taken in contact. Timings are recorded, never asserted (shared machine).
"""

import math

import numpy as np
import pytest

from benchmarks import perf_contact
from tests.benchmarks._records import check_written, record_fixture

needs_ipctk = pytest.mark.skipif(perf_contact.ipctk is None, reason="ipctk not installed")


result = record_fixture("perf_contact")


def test_writes_json_and_plot(result):
    data = check_written(
        result, "perf_contact_quick", "barrier_pairs_per_s ccd_s ccd_step rings_breakdown wall_s"
    )
    for key in ("steps", "newton_iterations", "peak_memory_mb", "parameters", "environment"):
        assert key in data, key
    for dim_key, rates in data["barrier_pairs_per_s"].items():
        assert rates["bfemp"] > 0.0 and math.isfinite(rates["bfemp"]), dim_key


def test_every_particle_has_exactly_one_facet_pair(result):
    _, data, _ = result
    for dim_key, case in data["cases"].items():
        kind = "pe" if dim_key == "2d" else "pt"
        by_kind = case["bfemp"]["pairs_by_kind"]
        assert by_kind[kind] == case["particles"] == 5000, dim_key
        assert sum(by_kind.values()) == by_kind[kind], dim_key  # no vertex/edge terms


@needs_ipctk
def test_bfemp_and_ipctk_agree_on_pairs_energy_and_gradient(result):
    _, data, _ = result
    for dim_key, agree in data["agreement"].items():
        assert agree["same_pair_count"], dim_key
        assert data["cases"][dim_key]["ipctk"]["pairs"] == data["cases"][dim_key]["pairs"]
        assert agree["energy_rel_diff"] < 1e-10, (dim_key, agree)
        assert agree["particle_gradient_rel_diff"] < 1e-8, (dim_key, agree)


def test_ccd_steps_are_conservative_and_useful(result):
    _, data, _ = result
    assert data["ccd_conservative"]
    for dim_key, step in data["ccd_step"].items():
        exact = step["exact"]
        # the closest particle sits >= 0.05 dhat away and moves 3 dhat: impact well inside [0, 1]
        assert 0.0 < exact < 1.0, dim_key
        # bfemp returns 0.9 x a conservative time of impact: never later than 0.9 x the exact one
        assert step["bfemp"] <= 0.9 * exact * (1.0 + 1e-12), (dim_key, step)
        assert step["bfemp"] > 0.5 * exact, (dim_key, step)  # not uselessly small
        if step["ipctk"] is not None:
            assert 0.0 < step["ipctk"] <= exact, (dim_key, step)


def test_rings_breakdown_is_taken_in_contact(result):
    _, data, _ = result
    ring = data["rings_breakdown"]
    dt = data["parameters"]["rings_dt_s"]
    # 2 m gap closing at 80 m/s: first contact at t = 0.025 s, later by at most the time to close
    # the half particle spacing between the MPM ring's outermost particles and its outer circle
    grid = ring["parameters"]
    lag = 0.5 * grid["dx"] / math.sqrt(grid["ppc"]) / 80.0
    assert 0.025 - dt - 1e-12 <= ring["first_contact_t"] <= 0.025 + lag + dt + 1e-12
    assert ring["barrier_pairs"] > 0 and ring["broad_phase_candidates"] >= ring["barrier_pairs"]
    assert ring["newton_iterations"] >= 1
    assert 0.0 < ring["ccd_step"] <= 1.0
    phases = ring["step_phases_s"]
    for key in ("hessian", "assemble", "factorize", "line_search", "step_bound", "setup", "g2p"):
        assert phases[key] > 0.0, key


def test_exact_time_of_impact_reference():
    # 2D: a point 1 m above a unit segment, moving 4 m down, meets it at t = 1/4
    verts = np.array([[-0.5, 0.0], [0.5, 0.0]])
    points = np.array([[0.1, 1.0], [5.0, 1.0]])  # the second one passes beside the segment
    t = perf_contact._exact_toi(points, verts, np.array([[0, 1]]), np.array([0.0, -4.0]))
    assert t == pytest.approx(0.25)
    # 3D: a point above a triangle's interior, moving down 2 m from 0.5 m: t = 1/4; outside: 1
    verts = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    faces = np.array([[0, 1, 2]])
    down = np.array([0.0, 0.0, -2.0])
    assert perf_contact._exact_toi(np.array([[0.2, 0.2, 0.5]]), verts, faces, down) == (
        pytest.approx(0.25)
    )
    assert perf_contact._exact_toi(np.array([[0.8, 0.8, 0.5]]), verts, faces, down) == 1.0


def test_runs_without_ipctk(monkeypatch):
    monkeypatch.setattr(perf_contact, "ipctk", None)
    case = perf_contact._measure_case(2, 200, repeats=1)
    assert case["ipctk"] is None and case["agreement"] is None
    assert case["ccd"]["ipctk_step"] is None and case["ccd"]["conservative"]
    assert case["pairs"] == 200 and case["bfemp"]["dofs_s"] > 0.0


def test_a_linear_solver_swapped_into_the_stepper_does_the_next_steps_factorisations():
    """perf_contact times each repeat of the rings step with a fresh linear solver so that the
    analysis is redone; the stepper's Newton loop must then factorise with that solver, not
    with the one the stepper was built with."""
    import bfemp
    from bfemp.integrators import BACKWARD_EULER, integrator_from_name
    from bfemp.steppers.barrier import BarrierOptions, BarrierStepper
    from solvers.linear import default_linear_solver

    scene = bfemp.Scene(dim=2, gravity=(0.0, -9.81))
    scene.add_fem(
        bfemp.shapes.rectangle((0.0, 0.0), (1.0, 0.5), h=0.25),
        name="block",
        material=bfemp.NeoHookean(E=1e5, nu=0.3, density=1000.0),
    )
    model = scene.build()
    stepper = BarrierStepper(
        model,
        integrator=integrator_from_name(BACKWARD_EULER),
        dt=1e-2,
        options=BarrierOptions(tol=1e-8),
    )
    old = stepper.linear_solver
    stepper.step(model.initial_state())
    used_by_old = old.n_numeric
    assert used_by_old > 0
    fresh = default_linear_solver()
    stepper.linear_solver = fresh
    _, report = stepper.step(model.initial_state())
    assert report.newton_iterations > 0
    assert fresh.n_numeric > 0  # the swapped-in solver factorised ...
    assert old.n_numeric == used_by_old  # ... and the old one no more
