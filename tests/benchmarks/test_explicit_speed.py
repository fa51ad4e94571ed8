"""explicit_speed: every explicit strategy beside barrier on one scene, with its cost split."""

from benchmarks import explicit_speed


def test_every_strategy_runs_to_the_same_time_with_its_split(tmp_path):
    rec = explicit_speed.run("smoke", tmp_path)
    (row,) = rec["rows"]
    for s in ("augury", "two_stage", "barrier"):
        r = row[s]
        assert r["steps"] * r["dt"] >= explicit_speed.T_END - 1e-12  # the same simulated time
        assert r["momentum_drift"] < 1e-9  # free bodies: momentum kept by every strategy
    for s in explicit_speed.EXPLICIT:
        r = row[s]
        assert 0.0 < r["contact_s_per_step"] and 0.0 < r["mechanics_s_per_step"]
        assert r["contact_s_per_step"] + r["mechanics_s_per_step"] <= 1.05 * r["s_per_step"]
        # the explicit strategies step far below the implicit barrier's dt
        assert r["dt"] < row["barrier"]["dt"]
    ts = row["two_stage"]
    assert ts["contact_steps"] > 0 and ts["newton_per_contact_step"] >= 1.0  # the bodies met
