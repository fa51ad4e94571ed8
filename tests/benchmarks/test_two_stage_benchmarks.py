"""Quick modes of the two_stage benchmarks assert their (T) targets."""

import json

from benchmarks import two_stage_gap, two_stage_rings, two_stage_slope


def _run(module, tmp_path_factory):
    out = tmp_path_factory.mktemp(module.NAME)
    module.run("quick", out)
    assert (out / f"{module.NAME}.png").stat().st_size > 5_000
    return json.loads((out / f"{module.NAME}.json").read_text())


def test_two_stage_rings_quick_keeps_momentum_and_never_penetrates(tmp_path_factory):
    data = _run(two_stage_rings, tmp_path_factory)
    assert data["momentum_drift_rel"] < 1e-9
    assert data["min_distance"] > 0.0
    run = data["runs"]["apic"]
    assert run["penetrations"] == 0 and run["error"] is None and run["contact_steps"] > 50
    assert data["target_met"]


def test_two_stage_gap_quick_rests_within_dhat(tmp_path_factory):
    data = _run(two_stage_gap, tmp_path_factory)
    ts = data["cases"]["two_stage"]
    assert 0.0 < ts["gap_tail_min_m"] and ts["gap_at_rest_m"] <= data["dhat_m"]
    for case in ("levelset", "augury_pic"):  # the grid treatments rest farther off
        assert data["gap_at_rest_m"][case] > ts["gap_at_rest_m"]
    assert data["target_met"]


def test_two_stage_slope_quick_slides_at_the_analytic_acceleration(tmp_path_factory):
    data = _run(two_stage_slope, tmp_path_factory)
    frictionless = next(c for c in data["variants"]["kappa_paper"]["cases"] if c["mu"] == 0.0)
    assert frictionless["error"] is None
    assert frictionless["accel_rel_error"] < two_stage_slope.TARGET_REL["quick"]
    assert data["targets"]["accel_met"]
    assert data["stable_dt_s"] >= two_stage_slope.DT
