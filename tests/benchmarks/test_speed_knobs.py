"""Speed knobs, quick mode: each knob leaves the answer alone; the default one saves work."""

from benchmarks import speed_knobs


def test_speed_knobs_quick(tmp_path):
    summary = speed_knobs.run("quick", tmp_path)
    assert (tmp_path / "speed_knobs.json").exists()
    for case in summary["friction_back_solve"].values():
        # the back-solve test stops the friction loop where a Newton iteration would have
        assert case["max_position_difference_m"] < 1e-9
        assert case["on"]["factorisations"] < case["off"]["factorisations"]
        assert case["on"]["newton_iterations"] == case["off"]["newton_iterations"]
    for case in summary["warm_start"].values():
        # a different start, the same solution to the tolerance (1e-6 m/s x dt per step)
        assert case["max_position_difference_m"] < 1e-5
    share = summary["broad_phase_share"]
    assert 0.0 < share["share"] < 1.0 and share["candidate_pairs_s"] > 0.0
