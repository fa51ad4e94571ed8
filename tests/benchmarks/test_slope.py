"""Box on a slope, quick mode (paper section 6.4): sliding accelerations against
g (sin theta - mu cos theta), and the box held at the critical friction coefficient with a creep
speed of the order of eps_v."""

import math

import pytest

from benchmarks import slope
from tests.benchmarks._records import record_fixture

THETA = math.atan(slope.PHYSICS["tan_theta"])
G_SIN = slope.PHYSICS["g_m_s2"] * math.sin(THETA)
EPS_V = slope.PHYSICS["eps_v_m_s"]


result = record_fixture("slope")


def _case(cases, mu):
    (case,) = [c for c in cases if c["mu"] == mu]
    return case


def test_writes_json_with_the_spec_keys_and_a_plot(result):
    summary, data, out = result
    assert summary["json"] == str(out / "slope.json")
    assert (out / "slope.png").stat().st_size > 10_000
    assert [c["mu"] for c in data["cases"]] == [0.0, 0.1, 0.1999, 0.2]
    for case in data["cases"]:
        for key in ("mu", "accel", "accel_analytic", "accel_rel_error", "max_speed"):
            assert key in case, key
    for key in ("wall_s", "steps", "newton_iterations", "peak_memory_mb", "parameters"):
        assert key in data, key


def test_box_rests_on_the_slope_within_dhat_and_friction_converges(result):
    _, data, _ = result
    dhat = slope.PHYSICS["dhat_m"]
    assert data["failed_cases"] == []
    # settled: at rest against the barrier, just inside dhat, never touching
    assert data["settle"]["com_speed_at_release_m_s"] < 1e-6
    assert 0.99 * dhat < data["settle"]["min_gap_at_release_m"] < dhat
    for case in data["cases"]:
        assert case["error"] is None, case["error"]
        assert case["steps"] == data["parameters"]["release_steps"]
        assert 0.0 < case["min_distance_m"] < dhat, case["mu"]
        assert case["friction_converged"], case["mu"]


@pytest.mark.parametrize("mu", [0.0, 0.1, 0.1999])
def test_sliding_acceleration_matches_coulomb_within_1e_3(result, mu):
    _, data, _ = result
    case = _case(data["cases"], mu)
    expected = slope.PHYSICS["g_m_s2"] * (math.sin(THETA) - mu * math.cos(THETA))
    assert case["accel_analytic"] == pytest.approx(expected, rel=1e-14)
    assert case["accel_rel_error"] < 1e-3, case
    # it really slides: past the static threshold, and down the slope
    assert case["accel"] > 0.0
    assert case["final_speed"] > 2.0 * EPS_V


def test_critical_friction_holds_the_box_at_a_speed_of_order_eps_v(result):
    _, data, _ = result
    case = _case(data["cases"], 0.2)
    assert case["accel_analytic"] == 0.0
    # the mollified static friction lets the box creep up to eps_v, where Coulomb friction
    # balances gravity exactly: no acceleration, speed of the order of eps_v
    assert 0.3 * EPS_V < case["max_speed"] < 3.0 * EPS_V
    assert 0.3 * EPS_V < case["final_speed"] < 3.0 * EPS_V
    assert abs(case["accel"]) < 1e-4 * G_SIN


def test_near_critical_sliding_over_fem_boundary_vertices(result):
    _, data, _ = result
    case = _case(data["variants"]["fine_slope"]["cases"], 0.1999)
    assert case["accel_rel_error"] < 1e-3, case
