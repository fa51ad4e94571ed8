"""Quick modes of the two_stage benchmarks assert their (T) targets."""

import json

import pytest

from benchmarks import scenes, two_stage_gap

#: started first (tests/conftest.py): one of the suite's longest files
pytestmark = pytest.mark.slow


def _run(name, tmp_path_factory, **options):
    out = tmp_path_factory.mktemp(name)
    summary = scenes.run("quick", out, **options) if options else two_stage_gap.run("quick", out)
    assert summary["json"] == str(out / f"{name}.json")
    assert (out / f"{name}.png").stat().st_size > 5_000
    return json.loads((out / f"{name}.json").read_text())


def test_two_stage_rings_quick_keeps_momentum_and_never_penetrates(tmp_path_factory):
    data = _run("two_stage_rings", tmp_path_factory, strategy="two_stage", scene="rings")
    assert data["momentum_drift_rel"] < 1e-9
    assert data["min_distance"] > 0.0
    run = data["runs"]["apic"]
    assert run["penetrations"] == 0 and run["error"] is None and run["contact_steps"] > 50
    assert data["target_met"]


def test_two_stage_gap_quick_rests_within_dhat(tmp_path_factory):
    data = _run("two_stage_gap", tmp_path_factory)
    ts = data["cases"]["two_stage"]
    assert 0.0 < ts["gap_tail_min_m"] and ts["gap_at_rest_m"] <= data["dhat_m"]
    for case in ("levelset", "augury_pic"):  # the grid treatments rest farther off
        assert data["gap_at_rest_m"][case] > ts["gap_at_rest_m"]
    assert data["target_met"]


def test_two_stage_slope_quick_slides_at_the_analytic_acceleration(tmp_path_factory):
    data = _run("two_stage_slope", tmp_path_factory, strategy="two_stage", scene="slope")
    frictionless = next(c for c in data["variants"]["kappa_paper"]["cases"] if c["mu"] == 0.0)
    assert frictionless["error"] is None
    assert frictionless["accel_rel_error"] < scenes.TARGET_REL["quick"]
    assert data["targets"]["accel_met"]
    assert data["stable_dt_s"] >= scenes.DT


def _creeping_case(speed_after, f, eps_v=1e-5):
    """A released case whose box moves at 1e-3 m/s for 0.05 s, then at ``speed_after`` m/s."""
    tau = [k * 1e-3 for k in range(101)]
    v = [1e-3 if t < 0.05 - 1e-12 else speed_after for t in tau]
    return {
        "start": "auto",
        "eps_v": eps_v,
        "mu_over_tan_theta": f,
        "newton_iterations": 300,
        "steps": 100,
        "error": None,
        "series": {"tau_s": tau, "speed_along_m_s": v},
    }


def test_sticking_metrics_judge_the_creep_after_the_window_start():
    # the mollifier of BFEMP eq. 36 holds a rigid box where f1 = tan(theta) / mu:
    # v = eps_v (1 - sqrt(1 - 1 / f)), 0.4226 eps_v at f = 1.5, 0.7818 eps_v at f = 1.05
    stuck = _creeping_case(4e-6, 1.5)
    scenes.sticking_metrics(stuck, 0.05)
    assert stuck["creep_speed_mollifier_m_s"] == pytest.approx(4.226e-6, rel=1e-3)
    assert stuck["mean_speed_after_fit_start"] == pytest.approx(4e-6, rel=1e-9)
    assert stuck["max_speed_after_fit_start"] == pytest.approx(4e-6)  # the kick is before 0.05 s
    assert stuck["sticks"] and stuck["newton_per_step"] == 3.0
    assert abs(stuck["accel"]) < 1e-9
    sliding = _creeping_case(2e-5, 1.05)  # twice eps_v: not held
    scenes.sticking_metrics(sliding, 0.05)
    assert sliding["creep_speed_mollifier_m_s"] == pytest.approx(7.818e-6, rel=1e-3)
    assert not sliding["sticks"]
    # the window matters: from t = 0 the kick makes the same stuck box "slide"
    early = _creeping_case(4e-6, 1.5)
    scenes.sticking_metrics(early, 0.0)
    assert not early["sticks"]


def test_sticking_refuses_an_unknown_release():
    with pytest.raises(ValueError, match="release_from must be 'settled' or 'initial'"):
        scenes.sticking("full", scenes.STICKING_MODES["full"], release_from="moving")
