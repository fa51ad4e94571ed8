"""The ``[check]`` table (``bfemp.scenefile.checks``) on metrics columns a strategy does not
define (issue 42, defect 3): ``finite = true`` failed every explicit run on ``energy_contact``
(NaN by design) and a ``min`` check of ``min_distance`` leaked numpy's "All-NaN slice"
RuntimeWarning and compared NaN."""

import math
import warnings

from bfemp.io.metrics import MetricsLog, undefined_column
from bfemp.scenefile.checks import CheckRecorder, evaluate_checks

CHECK = {
    "finite": True,
    "min": {"min_distance": 1e-12},
    "max": {"min_distance": 1.0},
    "drift_max": {"min_distance": 1.0, "momentum_x": 1e-3},
}


def _metrics(contact_energy, min_distance):
    """Three rows of an explicit run's metrics: ``energy_contact`` and ``min_distance`` given
    per row (J, m); the momentum is conserved."""
    return MetricsLog(
        {
            "t": 0.01 * i,
            "energy_kinetic": 1.0,
            "energy_contact": contact_energy[i],
            "energy_total": 1.0,
            "momentum_x": 2.0,
            "min_distance": min_distance[i],
        }
        for i in range(3)
    )


def test_columns_nan_in_every_row_are_not_judged_and_their_checks_are_skipped():
    nan = math.nan
    metrics = _metrics([nan, nan, nan], [nan, nan, nan])
    assert undefined_column(metrics.column("energy_contact"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no RuntimeWarning from nanmin of an all-NaN column
        results = {r.name: r for r in evaluate_checks(CHECK, metrics, CheckRecorder())}
    assert results["finite"].ok and not results["finite"].skipped
    assert "not defined in this run, NaN in every row: energy_contact" in results["finite"].detail
    for name in ("min.min_distance", "max.min_distance", "drift_max.min_distance"):
        assert results[name].ok and results[name].skipped, name
        assert str(results[name]).startswith(f"skip {name}: min_distance is not defined")
    assert results["drift_max.momentum_x"].ok and not results["drift_max.momentum_x"].skipped


def test_a_column_that_turns_nan_after_finite_rows_still_fails_finite():
    metrics = _metrics([0.0, 0.5, math.nan], [1e-3, 2e-3, 1e-13])
    results = {r.name: r for r in evaluate_checks(CHECK, metrics, CheckRecorder())}
    assert not results["finite"].ok and "['energy_contact']" in results["finite"].detail
    assert not undefined_column(metrics.column("energy_contact"))
    low = results["min.min_distance"]  # a defined column is compared as before
    assert not low.ok and not low.skipped and str(low).startswith("FAIL min.min_distance")
