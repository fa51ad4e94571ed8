"""Convergence under refinement, quick mode (paper section 6.5): an MPM box settles on a FEM box
and the centre-of-mass height at rest converges as dx = 1/N and dhat = 1/N^2 shrink."""

import numpy as np

from tests.benchmarks._records import check_written, record_fixture

result = record_fixture("refinement")


def test_writes_json_and_plot(result):
    check_written(result, "refinement_quick", "series wall_s peak_memory_mb parameters runs")


def test_every_resolution_comes_to_rest_above_the_fem_box(result):
    _, data, _ = result
    for by_ppc in data["runs"].values():
        for run in (by_ppc["reference"], *by_ppc["runs"]):
            assert run["error"] is None, run["error"]
            assert run["at_rest"], run["n"]
            # the barrier holds the box off the FEM box: closest pair within dhat = 1/N^2
            assert 0.0 < run["min_distance_m"] < run["dx_m"] ** 2, run["n"]
            # the soft box sinks under its own weight (rho g h / E = 0.25 strain): its centre
            # starts at 1.5 + dx m and settles well below, but stays above the FEM box top
            assert 1.0 < run["y_mpm"] < 1.45, run["n"]


def test_error_decreases_monotonically_with_refinement(result):
    _, data, _ = result
    for ppc, series in data["series"].items():
        assert series["ns"] == [4, 8, 12], ppc
        errors = np.array(series["errors"])
        assert np.all(errors > 0.0)
        assert np.all(np.diff(errors) < 0.0), (ppc, errors)
        assert np.all(np.diff(series["errors_mpm"]) < 0.0), (ppc, series["errors_mpm"])
        # at least first order over N = 4..12 (against the close reference N = 16 the fit
        # overestimates the order)
        assert series["order"] > 1.0, (ppc, series["order"])
