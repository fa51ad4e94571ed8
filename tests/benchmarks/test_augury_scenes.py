"""augury_scenes (smoke): the rings under augury beside two_stage and barrier, in one run."""

from benchmarks import scenes


def test_rings_under_augury_conserve_momentum_beside_the_others(tmp_path):
    rec = scenes.run("smoke", tmp_path, strategy="augury")
    runs = rec["rings"]["runs"]
    assert set(runs) == {"augury", "two_stage", "barrier"}
    for name, r in runs.items():
        assert r["error"] is None, (name, r["error"])
        assert r["contact_steps"] > 0  # the rings met within the smoke run
    # APIC augury conserves linear momentum exactly; so do the others
    assert rec["augury_momentum_drift_below_1e-10"]
    assert runs["two_stage"]["momentum_drift_rel"] < 1e-9
    assert runs["two_stage"]["penetrations"] == 0 and runs["barrier"]["penetrations"] == 0
    assert (tmp_path / "augury_scenes_smoke.json").exists()
