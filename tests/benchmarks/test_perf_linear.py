"""perf_fem, perf_mpm and perf_3d in quick mode: the records name the BLAS and the solver, give
the ratio Newton iteration / factorisation, and the reference BLAS beside the optimised one."""

import json
from pathlib import Path

import pytest

from benchmarks import perf_3d, perf_fem, perf_mpm
from solvers.blas import cholmod_blas

# the ratio Newton iteration / factorisation is a ratio of wall times: measured alone
pytestmark = pytest.mark.serial


@pytest.fixture(scope="module", params=["perf_fem", "perf_mpm", "perf_3d"])
def record(request, tmp_path_factory):
    module = {"perf_fem": perf_fem, "perf_mpm": perf_mpm, "perf_3d": perf_3d}[request.param]
    out = tmp_path_factory.mktemp(request.param)
    summary = module.run("quick", out)  # perf_fem/perf_mpm: *_quick.json, as the committed ones
    return request.param, json.loads(Path(summary["json"]).read_text())


def _cases(name, data):
    return data["solvers"] if name == "perf_3d" else data["cases"]


def test_record_names_the_blas_and_the_solvers(record):
    name, data = record
    la = data["environment"]["linear_algebra"]
    assert la["cholmod_blas"] == cholmod_blas().name
    assert la["solvers"]["cholmod"] and la["solvers"]["scipy"]
    for case in _cases(name, data).values():
        assert case["linear_solver"] in ("cholmod", "pardiso", "cg_amg")


def test_ratio_of_newton_iteration_to_factorisation_is_measured(record):
    name, data = record
    for case in _cases(name, data).values():
        assert case["factorize_s"] > 0.0
        # one solve per iteration, less one per chord step (at most one per factorisation:
        # NewtonOptions.chord_steps); the convergence test after a full step is a back-solve
        # with the last factorisation (the chord test), a new solve only where it cannot decide
        assert 1 <= case["linear_solves"] <= 2 * case["newton_iterations"] + 1
        assert case["newton_iterations"] <= 2 * case["linear_solves"]
        per_it = case["time_per_newton_iteration_s"]
        assert case["newton_over_factorisation"] == pytest.approx(per_it / case["factorize_s"])
        # a Newton iteration contains at least one factorisation's worth of work
        assert case["linear_solve_over_factorisation"] > 0.5
        if case["linear_solver"] != "cg_amg":  # (its floor is the CG solve)
            assert case["factorize_median_s"] >= case["factorize_s"]  # the floor is the least
        if name in ("perf_fem", "perf_mpm"):  # the same step three times, the median kept
            times = sorted(case["step_times_s"])
            assert len(times) == 3
            assert times[1] == pytest.approx(per_it * case["newton_iterations"])


def test_step_repeats_must_be_a_positive_int():
    from benchmarks._phases import newton_phases

    with pytest.raises(ValueError, match="step_repeats"):
        newton_phases(None, None, step_repeats=0)


def test_reference_blas_is_measured_beside_the_default_one(record):
    _, data = record
    side = data["blas_side_by_side"]
    assert side["default"]["blas"] == cholmod_blas().name
    if side["reference"] is not None and cholmod_blas().optimised:
        assert side["reference"]["blas"] == "reference"
        assert set(side["speedup"]) == set(side["default"]["factorize_s"])


def test_perf_3d_compares_every_installed_solver(record):
    name, data = record
    if name != "perf_3d":
        return
    solvers = data["solvers"]
    assert "cholmod" in solvers and "cg_amg" in solvers
    iters = {k: v["newton_iterations"] for k, v in solvers.items()}
    assert all(v["particles"] == solvers["cholmod"]["particles"] for v in solvers.values())
    assert data["fastest_step"] in solvers
    assert min(iters.values()) >= 1
