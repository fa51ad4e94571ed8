"""The trade study's explicit strategies beside barrier (issue 17): the softened Hertz disk
(``hertz_soft``), the explicit strategies on ``sine_boundary`` and barrier and two_stage on the 3D
``augury_blocks``: what is planned (and why augury and lr do not run the softened disk, augury
not the sine boundary: measured), one cheap run of the softened disk per family (implicit and
explicit) with the analytic C from the softened E, and the committed quick record holding finite
errors of the explicit strategies on those scenes."""

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

import bfemp
from benchmarks import hertz, tradeoff
from benchmarks._tradeoff_runs import run_point

RECORD = Path(__file__).resolve().parents[2] / "benchmarks" / "records" / "tradeoff.json"


def test_the_explicit_strategies_are_planned_beside_barrier():
    def strategies(scene: str, mode: str = "quick") -> set[str]:
        return {p["strategy"] for p in tradeoff.plan(mode, scene)}

    assert strategies("hertz_soft") == {"barrier", "two_stage"}
    assert strategies("sine_boundary") == {"barrier", "two_stage", "lr"}
    assert strategies("augury_blocks") == {"augury", "barrier", "two_stage"}
    assert strategies("hertz") == {"barrier"}  # the paper's E: the explicit ones run hertz_soft
    # the explicit strategies sweep their own knobs there, the CFL fractions at dt = "auto"
    sine = {p["strategy"]: p for p in tradeoff.plan("quick", "sine_boundary")}
    lr = {
        k
        for p in tradeoff.plan("quick", "sine_boundary")
        if p["strategy"] == "lr"
        for k in p["sweeps"]
    }
    assert {"dx", "ppc", "corrections", "cfl_safety_mpm"} <= lr and "dt" not in lr
    assert sine["two_stage"]["settings"]["dt"] == "auto"
    # the strategies that do not run a scene say why, with the measured figures
    why = tradeoff.SCENES["hertz_soft"]["not_applicable"]
    assert "8.79 mm" in why["augury"] and "0.196 m" in why["lr"]
    assert "0.215 m deep" in tradeoff.SCENES["sine_boundary"]["not_applicable"]["augury"]


def test_plate_mesh_and_stress_force_by_hand():
    points, cells = hertz._plate(-1.2, 1.2, -0.2, 0.0, h=0.1)
    assert points.shape == (50, 2) and cells.shape == (48, 3)
    a, b, c = (points[cells[:, k]] for k in range(3))
    u, v = b - a, c - a
    area = 0.5 * np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0])
    assert area.sum() == pytest.approx(2.4 * 0.2, rel=1e-12) and area.min() > 0.0
    # a uniform compression sigma_yy over a disk of area A between plates 2 m apart: F = -s A / 2
    material = bfemp.LinearElastic(E=1e5, nu=0.3, density=100.0)
    deformation = np.tile(np.diag([1.0, 0.99]), (4, 1, 1))
    geo = {"material": material, "volume": np.full(4, 0.25), "y_top": 1.0, "y_bottom": -1.0}
    sigma_yy = material.cauchy_stress(deformation[:1])[0, 1, 1]
    expected = -sigma_yy * np.linalg.det(deformation[0]) * 1.0 / 2.0
    assert hertz.stress_force(deformation, geo, 0.0) == pytest.approx(expected, rel=1e-12)
    assert expected > 0.0  # compression pushes the plates apart


def _soft_point(strategy: str, **changes) -> dict:
    base = tradeoff.strategy_base("hertz_soft", strategy, "quick")
    return run_point({"scene": "hertz_soft", **base, **changes})


def test_soft_disk_by_barrier_fits_hertz_with_the_softened_constant():
    out = _soft_point("barrier")
    c_soft = math.pi * hertz.SOFT_E / (4.0 * (1.0 - hertz.NU**2) * hertz.RADIUS)
    assert out["C_hertz"] == pytest.approx(c_soft, rel=1e-12)
    assert out["failure"] is None and out["fit_samples"] >= 3
    assert math.isfinite(out["rel_error"]) and out["rel_error"] < 1.0
    # the particle-side force equals the bottom plate's (action and reaction) and the stresses
    # carry the same load (tensor virial, quasi-static)
    assert out["F_stress_end"] == pytest.approx(out["F_end"], rel=0.2)
    assert out["lowest_gap_min_m"] > 0.0


def test_soft_disk_by_two_stage_makes_contact_at_the_explicit_step():
    out = _soft_point("two_stage", t_end=0.12)  # 220 steps: the first 12 mm of the plate
    assert out["failure"] is None and out["iterations"] > 0
    assert out["dt_s"] < 1e-3 and out["steps"] == round(0.12 / out["dt_s"])
    assert out["F_end"] > 10.0 and out["lowest_gap_min_m"] > 0.0  # no particle in the plate


def test_the_quick_record_holds_the_explicit_strategies_with_finite_errors():
    data = json.loads(RECORD.read_text())
    points = data["points"]

    def errors(scene: str, strategy: str) -> list[float]:
        mine = [p for p in points if (p["scene"], p["strategy"]) == (scene, strategy)]
        assert mine, (scene, strategy)
        return [p["error"] for p in mine if p["failure"] is None]

    for scene, strategy in (
        ("hertz_soft", "barrier"),
        ("hertz_soft", "two_stage"),
        ("sine_boundary", "two_stage"),
        ("sine_boundary", "lr"),
        ("augury_blocks", "barrier"),
        ("augury_blocks", "two_stage"),
    ):
        found = errors(scene, strategy)
        assert found and all(math.isfinite(e) for e in found), (scene, strategy)
    # the report lists them and the winners are computed over every strategy of the scene
    md = RECORD.with_suffix(".md").read_text()
    sections = {part.split("\n", 1)[0]: part for part in md.split("\n## ")[1:]}
    assert "- **two_stage**" in sections["hertz_soft"]
    assert "| two_stage | base" in sections["hertz_soft"]
    sine = sections["sine_boundary"]
    for strategy in ("two_stage", "lr"):
        assert f"| {strategy} | base" in sine, strategy


def test_merging_a_rerun_replaces_its_scenes_and_keeps_the_others(tmp_path):
    record = tmp_path / "tradeoff_full.json"
    shutil.copy(RECORD, record)
    data = json.loads(RECORD.read_text())
    # a "rerun" of sine_boundary alone: the record's own sine points, one error changed
    rerun = dict(data, scenes=["sine_boundary"], merged=None)
    rerun["points"] = [dict(p) for p in data["points"] if p["scene"] == "sine_boundary"]
    lr = next(p for p in rerun["points"] if p["strategy"] == "lr")
    lr["error"] = 0.5 * lr["error"]
    for p in rerun["points"]:  # one point resumed from a stopped run's kept file
        p["resumed"] = p is lr
    rerun["environment"] = dict(data["environment"], commit="f" * 40)
    rerun["executor"] = dict(data["executor"], kind="dask", scheduler="tcp://h:1", workers=None)
    (tmp_path / "rerun.json").write_text(json.dumps(rerun))
    out = tradeoff.merge(record, tmp_path / "rerun.json")
    assert sorted(out["scenes"]) == sorted(data["scenes"])
    assert len(out["points"]) == len(data["points"])
    again = {p["id"]: p for p in out["points"]}
    assert again[lr["id"]]["error"] == lr["error"]
    assert again["rings/barrier/base"]["error"] == next(
        p["error"] for p in data["points"] if p["id"] == "rings/barrier/base"
    )
    assert out["merged"][-1]["scenes"] == ["sine_boundary"]
    md = (tmp_path / "tradeoff_full.md").read_text()
    # the plots are named after the record, beside it (not over the quick record's)
    assert (tmp_path / "tradeoff_full_sine_boundary.png").stat().st_size > 10_000
    assert not (tmp_path / "tradeoff_sine_boundary.png").exists()
    line = next(x for x in md.splitlines() if x.startswith("Scenes sine_boundary: run at"))
    assert "at commit `ffffffffff`" in line and "on Dask scheduler tcp://h:1," in line, line
    assert "; 1 of them measured by an earlier, stopped run of the same code" in line, line
    wall = sum(p["wall_s"] for p in rerun["points"])
    assert f"sum of the point wall times {wall:.1f} s)" in line, line
    # every point, merged or kept, replays from the merged record
    assert all(f"--replay {record} --id {p['id']}" in p["replay"] for p in out["points"])


def test_merging_a_rerun_of_some_strategies_keeps_the_others_against_the_new_reference(tmp_path):
    """A rerun of augury and lr on rings (with its own reference run) replaces their rows and
    the reference; barrier's and two_stage's rows stay, their errors taken again against the
    rerun's reference, so that one scene's errors share one reference."""
    record = tmp_path / "tradeoff_full.json"
    shutil.copy(RECORD, record)
    data = json.loads(RECORD.read_text())
    rings = [p for p in data["points"] if p["scene"] == "rings"]
    old_ref = data["references"]["rings"]
    new_ref = dict(old_ref, metrics={k: 1.05 * v for k, v in old_ref["metrics"].items()})
    rerun = dict(data, scenes=["rings"], merged=None)
    rerun["references"] = {"rings": new_ref}
    ran = ("barrier", "augury", "lr")  # barrier: the reference run only
    rerun["strategies"] = {"rings": list(ran)}
    rerun["strategy_notes"] = {"rings": {s: data["strategy_notes"]["rings"][s] for s in ran}}
    rerun["points"] = [
        dict(p, reference=new_ref)
        for p in rings
        if p["strategy"] in ("augury", "lr") or p["is_reference"]
    ]
    rerun["environment"] = dict(data["environment"], commit="e" * 40)
    (tmp_path / "rerun.json").write_text(json.dumps(rerun))
    plain = tradeoff.merge(record, tmp_path / "rerun.json")  # the default drops the others
    assert {p["strategy"] for p in plain["points"] if p["scene"] == "rings"} == {
        "augury",
        "lr",
        "barrier",
    }
    shutil.copy(RECORD, record)
    out = tradeoff.merge(record, tmp_path / "rerun.json", keep_other_strategies=True)
    merged = [p for p in out["points"] if p["scene"] == "rings"]
    assert sorted(p["id"] for p in merged) == sorted(p["id"] for p in rings)
    assert "two_stage" in out["strategies"]["rings"]
    for p in merged:
        if p["strategy"] in ("barrier", "two_stage") and not p["is_reference"] and p["error"]:
            keys = tradeoff.SCENES["rings"]["reference_keys"]
            expected = max(
                abs(p["metrics"][k] - new_ref["metrics"][k]) / abs(new_ref["metrics"][k])
                for k in keys
            )
            assert p["error"] == pytest.approx(expected, rel=1e-12)
            assert p["error_against"] == "reference run at " + "e" * 40
    # the other scenes are untouched
    sine = {p["id"]: p["error"] for p in data["points"] if p["scene"] == "sine_boundary"}
    assert {p["id"]: p["error"] for p in out["points"] if p["id"] in sine} == sine
