"""Trade study (issue 6): the Pareto front and knob analysis by hand, the plan of the sweeps, bad
input, and a minimal quick sweep of the three scenes (two points each) run by local processes
and, for the same slope points, by a local Dask cluster; replaying records reproduces errors."""

import argparse
import json
import math

import numpy as np
import pytest

import benchmarks.__main__ as bench_main
from benchmarks import rings, tradeoff
from benchmarks._tradeoff_report import best_knob, knob_effect, pareto_front
from bfemp import cli

#: two cheap points per scene: along dt (rings, slope) or tol (hertz); the other knob of the
#: pair is held at its base value so that it adds no point
MINIMAL = {
    "rings": {"dt": (2e-2, 1e-2), "tol": (1e-6,)},
    "slope": {"dt": (2e-3, 1e-3), "tol": (1e-8,)},
    "hertz": {"dt": (6e-2,), "tol": (1e-3, 1e-4)},
}


# ----------------------------------------------------------------------------- analysis
def test_pareto_front_by_hand():
    cost = [3.0, 1.0, 2.0, 4.0, 2.0, 5.0, np.nan, 0.5]
    error = [1.0, 5.0, 3.0, 0.5, 4.0, 0.5, 0.1, np.nan]
    # (1, 5) (2, 3) (3, 1) (4, 0.5) are non-dominated; (2, 4) loses to (2, 3), (5, 0.5) to
    # (4, 0.5); NaN cost or error takes no part
    assert pareto_front(cost, error).tolist() == [1, 2, 0, 3]
    # identical points: the first only; a cheaper point with equal error dominates
    assert pareto_front([1.0, 1.0, 0.5], [2.0, 2.0, 2.0]).tolist() == [2]
    assert pareto_front([1.0, 2.0], [1.0, 0.5]).tolist() == [0, 1]
    assert pareto_front([], []).tolist() == []
    with pytest.raises(ValueError, match="one shape"):
        pareto_front([1.0, 2.0], [1.0])


def test_knob_effect_slopes_and_the_best_knob():
    # dt: error ~ time^-2; dx: error ~ time^-0.5; both refined toward smaller values
    dt = knob_effect(
        [
            {"value": 1e-3, "time_s": 2.0, "error": 2.5e-3},
            {"value": 2e-3, "time_s": 1.0, "error": 1e-2},
        ],
        -1,
    )
    assert dt["verdict"] == "buys accuracy"
    assert dt["coarse"]["value"] == 2e-3 and dt["fine"]["value"] == 1e-3
    assert dt["loglog_slope"] == pytest.approx(-2.0)
    assert dt["error_drop_per_s"] == pytest.approx(7.5e-3)
    dx = knob_effect(
        [
            {"value": 0.2, "time_s": 1.0, "error": 1e-2},
            {"value": 0.1, "time_s": 4.0, "error": 5e-3},
        ],
        -1,
    )
    assert dx["loglog_slope"] == pytest.approx(-0.5)
    # ppc refines upward; here finer is worse; a failed point (error None) is skipped
    ppc = knob_effect(
        [
            {"value": 4, "time_s": 1.0, "error": 1e-3},
            {"value": 9, "time_s": 2.0, "error": 2e-3},
            {"value": 16, "time_s": 3.0, "error": None},
        ],
        1,
    )
    assert ppc["verdict"] == "no gain" and ppc["points"] == 2
    assert best_knob({"dt": dt, "dx": dx, "ppc": ppc}) == "dt"
    # a knob that lowers the error without costing time wins outright
    tol = knob_effect(
        [
            {"value": 1e-4, "time_s": 1.0, "error": 1e-2},
            {"value": 1e-6, "time_s": 1.01, "error": 1e-3},
        ],
        -1,
    )
    assert tol["verdict"] == "free" and tol["loglog_slope"] is None
    assert best_knob({"dt": dt, "tol": tol}) == "tol"
    # a fine end that is the reference run (error 0) is an unbounded slope
    ref = knob_effect(
        [
            {"value": 2e-2, "time_s": 1.0, "error": 0.2},
            {"value": 1e-2, "time_s": 3.0, "error": 0.0},
        ],
        -1,
    )
    assert ref["reaches_zero"] and ref["verdict"] == "buys accuracy"
    assert best_knob({"dt": dt, "dx": ref}) == "dx"
    assert knob_effect([{"value": 1.0, "time_s": 1.0, "error": 1.0}], -1)["verdict"] == "n/a"
    assert best_knob({"ppc": ppc}) is None


# ----------------------------------------------------------------------------- planning, input
def test_plan_is_one_at_a_time_around_the_base_with_a_finest_reference():
    points = tradeoff.plan("quick", "rings", "dt,ppc")
    base = tradeoff.SCENES["rings"]["modes"]["quick"]["base"]
    ids = [p["id"] for p in points]
    assert ids == ["rings/base", "rings/dt=2e-2", "rings/dt=5e-3", "rings/ppc=9", "rings/reference"]
    assert points[0]["settings"] == base and points[0]["sweeps"] == ["dt", "ppc"]
    for p in points[1:-1]:
        changed = {k for k in base if p["settings"][k] != base[k]}
        assert changed == {p["knob"]}, p["id"]
    reference = points[-1]
    assert reference["is_reference"] and reference["sweeps"] == []
    assert reference["settings"] == {**base, "dt": 5e-3, "ppc": 9}
    for p in points:
        assert set(p["settings"]) == set(rings.POINT_KEYS)
        assert p["mode"] == "quick" and p["strategy"] == "bfemp" and p["threads"] == 1
    # a reference equal to a sweep point is that point; analytic scenes have no reference
    only_dt = tradeoff.plan("quick", "rings", "dt")
    assert [p["id"] for p in only_dt if p["is_reference"]] == ["rings/dt=5e-3"]
    assert not any(p["is_reference"] for p in tradeoff.plan("quick", "slope,hertz", "dt"))
    # a scene without any chosen knob is skipped; the full mode is defined for every scene
    assert {p["scene"] for p in tradeoff.plan("quick", None, "eps_v")} == {"slope", "hertz"}
    assert {p["scene"] for p in tradeoff.plan("full")} == set(tradeoff.SCENES)


def test_bad_input_names_what_is_wrong(capsys, monkeypatch, tmp_path):
    with pytest.raises(ValueError, match="unknown knob 'dtt'; available: strategy, dt"):
        tradeoff.plan("quick", None, "dt,dtt")
    with pytest.raises(ValueError, match="unknown scene 'ring'; available: hertz, rings, slope"):
        tradeoff.plan("quick", "ring")
    with pytest.raises(ValueError, match="no scene among rings has any of the knobs eps_v"):
        tradeoff.plan("quick", "rings", "eps_v")
    with pytest.raises(ValueError, match="rings: unknown strategy 'ipc'"):
        tradeoff.plan("quick", "rings", "strategy", sweeps={"rings": {"strategy": ("ipc",)}})
    with pytest.raises(ValueError, match="knob dt must be a positive number"):
        tradeoff.plan("quick", "slope", "dt", sweeps={"slope": {"dt": (-1.0,)}})
    with pytest.raises(ValueError, match="--cost must be 'wall' or 'cpu'"):
        tradeoff.sweep("quick", tmp_path, scenes="slope", cost="gpu")
    with pytest.raises(ValueError, match="--scheduler must be a Dask scheduler address"):
        tradeoff.sweep("quick", scheduler="localhost:8786")
    # a well-formed address nobody listens on: refused before any point runs
    monkeypatch.setattr(tradeoff, "CONNECT_TIMEOUT_S", 1.0)
    with pytest.raises(ValueError, match="cannot reach the Dask scheduler at tcp://127.0.0.1:9"):
        tradeoff.sweep(
            "quick", tmp_path, scenes="slope", knobs="strategy", scheduler="tcp://127.0.0.1:9"
        )
    # both command lines: a usage error naming the mistake, exit status 2
    with pytest.raises(SystemExit) as exit_info:
        bench_main.main(["tradeoff", "--quick", "--knobs", "dt,nope"])
    assert exit_info.value.code == 2
    assert "unknown knob 'nope'" in capsys.readouterr().err
    assert cli.main(["sweep", "--quick", "--scenes", "slope,nowhere"]) == 2
    assert "bfemp: error: unknown scene 'nowhere'" in capsys.readouterr().err
    assert cli.main(["sweep", "--point", "{not json"]) == 2
    assert "--point is not valid JSON" in capsys.readouterr().err


def _options(parser: argparse.ArgumentParser) -> set[str]:
    return {s for action in parser._actions for s in action.option_strings}


def test_bfemp_sweep_has_the_options_of_the_benchmark():
    bench = bench_main._parser()
    tradeoff.add_arguments(bench)
    parser, _ = cli._parser_and_plugins()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    assert _options(sub.choices["sweep"]) - {"--verbose"} == _options(bench)


# ----------------------------------------------------------------------------- a minimal sweep
@pytest.fixture(scope="module")
def minimal(tmp_path_factory):
    out = tmp_path_factory.mktemp("tradeoff")
    summary = tradeoff.sweep("quick", out, knobs="dt,tol", workers=2, sweeps=MINIMAL)
    return summary, json.loads((out / "tradeoff.json").read_text()), out


def _by_id(data: dict) -> dict:
    return {p["id"]: p for p in data["points"]}


def test_minimal_sweep_writes_records_plots_and_summary(minimal):
    summary, data, out = minimal
    assert summary["json"] == str(out / "tradeoff.json")
    # the parallel sweep of 6 points (a few seconds each) stays well inside a couple of minutes
    assert data["wall_s"] < 180.0
    assert data["scenes"] == ["hertz", "rings", "slope"]
    assert data["warmup_s"] > 0.0 and data["warmup_failures"] == []
    points = _by_id(data)
    assert sorted(points) == [
        "hertz/base",
        "hertz/tol=1e-3",
        "rings/base",
        "rings/dt=2e-2",
        "slope/base",
        "slope/dt=2e-3",
    ]
    for p in points.values():
        for key in ("scene", "settings", "strategy", "mode", "threads", "error", "wall_s"):
            assert key in p, (p["id"], key)
        assert p["failure"] is None, (p["id"], p["failure"])
        assert p["error"] is not None and p["error"] >= 0.0
        assert p["wall_s"] > 0.0 and p["process_wall_s"] > p["wall_s"]
        # one thread per point: the process's CPU time cannot exceed its wall time by much
        assert 0.0 < p["cpu_s"] < 1.1 * p["wall_s"] + 0.5
        assert p["newton_iterations"] > 0 and p["peak_memory_mb"] > 50.0
        assert p["mode"] == "quick" and p["strategy"] == "bfemp"
        assert f"--id {p['id']}" in p["replay"]
    # the analytic errors are those the scenes' own metrics give
    slope = points["slope/dt=2e-3"]
    assert slope["error"] == slope["metrics"]["accel_rel_error"]
    assert slope["settings"]["dt"] == 2e-3 and slope["metrics"]["steps"] == 40
    hertz = points["hertz/tol=1e-3"]
    assert hertz["error"] == pytest.approx(abs(hertz["metrics"]["C_fit_over_C_hertz"] - 1.0))
    for scene in data["scenes"]:
        front = data["pareto"][scene]
        assert front and all(points[i]["pareto"] for i in front)
        assert (out / f"tradeoff_{scene}.png").stat().st_size > 10_000
    md = (out / "tradeoff.md").read_text()
    for scene in data["scenes"]:
        assert f"## {scene}" in md
    assert "Most accuracy per second: dt" in md and "Pareto front (error against wall time)" in md


def test_rings_error_is_taken_against_the_finest_run(minimal):
    _, data, _ = minimal
    points = _by_id(data)
    base, coarse = points["rings/base"], points["rings/dt=2e-2"]
    # only dt is swept (tol has its base value): the finest run is the base itself
    assert base["is_reference"] and data["references"]["rings"]["id"] == "rings/base"
    assert base["error"] == 0.0
    ref = coarse["reference"]["metrics"]
    assert ref["energy_loss_pct"] == base["metrics"]["energy_loss_pct"]
    loss = abs(coarse["metrics"]["energy_loss_pct"] / ref["energy_loss_pct"] - 1.0)
    duration = abs(coarse["metrics"]["contact_duration_s"] / ref["contact_duration_s"] - 1.0)
    assert coarse["error_parts"]["energy_loss_pct"] == pytest.approx(loss, rel=1e-12)
    assert coarse["error_parts"]["contact_duration_s"] == pytest.approx(duration, rel=1e-12)
    assert coarse["error"] == max(coarse["error_parts"].values()) > 0.0
    assert data["best_knob"]["rings"] == "dt"


def test_dask_cluster_gives_the_errors_of_local_processes(minimal, tmp_path):
    distributed = pytest.importorskip("distributed")
    _, data, _ = minimal
    with distributed.LocalCluster(
        n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None
    ) as cluster:
        summary = tradeoff.sweep(
            "quick",
            tmp_path,
            scenes="slope",
            knobs="dt,tol",
            scheduler=cluster.scheduler_address,
            sweeps=MINIMAL,
            warmup=False,  # the local sweep has filled numba's cache
        )
    assert summary["executor"]["kind"] == "dask"
    local = _by_id(data)
    for point in summary["points"]:
        assert point["failure"] is None
        assert point["error"] == local[point["id"]]["error"], point["id"]
        assert point["newton_iterations"] == local[point["id"]]["newton_iterations"]


def test_replaying_a_record_reproduces_its_error(minimal, capsys):
    _, data, out = minimal
    # rings: the error is recomputed against the reference metrics stored in the record
    args = ["tradeoff", "--replay", str(out / "tradeoff.json"), "--id", "rings/dt=2e-2"]
    assert bench_main.main(args) == 0
    printed = capsys.readouterr().out
    assert "rings/dt=2e-2: error" in printed and ": reproduced;" in printed
    # a record whose error does not match what the point gives is reported (exit 1)
    record = dict(_by_id(data)["slope/dt=2e-3"])
    record["error"] = 2.0 * record["error"]
    assert cli.main(["sweep", "--point", json.dumps(record)]) == 1
    printed = capsys.readouterr().out
    assert "NOT reproduced" in printed
    recorded = _by_id(data)["slope/dt=2e-3"]["error"]
    assert f"error {recorded} (recorded {record['error']})" in printed
    assert math.isfinite(recorded)
