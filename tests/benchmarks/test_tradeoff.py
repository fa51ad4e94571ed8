"""Trade study across strategies (issues 6, 17): the Pareto front, knob analysis and winners per
error range by hand, the plan of the sweeps (knobs from the strategies' options), bad input, and
a minimal quick sweep (two strategies on the rings, barrier on slope) run by local
processes and, for the two strategies on the rings, by a local Dask cluster with equal results;
replaying records reproduces errors."""

import argparse
import json
import math

import numpy as np
import pytest

import benchmarks.__main__ as bench_main
from benchmarks import tradeoff
from benchmarks._tradeoff_knobs import ladder, option_knobs
from benchmarks._tradeoff_report import (
    best_knob,
    close_call,
    crossovers,
    knob_effect,
    pareto_front,
    winner_sentences,
    winners,
)
from bfemp import cli

#: started first (tests/conftest.py): one of the suite's longest files
pytestmark = pytest.mark.slow

#: two cheap points per strategy: barrier along dt, augury along its iterations (rings), barrier
#: along its option tol (slope); the knobs not chosen keep their base values
MINIMAL = {
    "rings": {"barrier": {"dt": (2e-2, 1e-2), "tol": (1e-6,)}, "augury": {"iterations": (1, 0)}},
    "slope": {"barrier": {"dt": (1e-3,), "tol": (1e-7, 1e-8)}},
}
MINIMAL_KNOBS = "dt,tol,iterations"
MINIMAL_STRATEGIES = {"rings": "barrier,augury", "slope": "barrier"}


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


def test_winners_per_error_range_from_a_hand_made_table():
    # A: cheap and coarse, or costly and fine; B: in between, and the finest point of all
    table = [
        {"strategy": "A", "error": 1e-2, "wall_s": 1.0},
        {"strategy": "A", "error": 1e-4, "wall_s": 10.0},
        {"strategy": "B", "error": 1e-3, "wall_s": 3.0},
        {"strategy": "B", "error": 1e-5, "wall_s": 5.0},
        {"strategy": "B", "error": None, "wall_s": 0.1},  # failed: takes no part
        {"strategy": "C", "error": 2e-2, "wall_s": 2.0},  # never the cheapest
    ]
    ranges = winners(table)
    # targets >= 1e-2: A (1 s) beats C (2 s) and B (3 s); below 1e-2 B's 3 s and 5 s points
    # beat A's 10 s one, and only B reaches 1e-5
    assert [(r["error_from"], r["error_to"], r["winner"]) for r in ranges] == [
        (1e-2, math.inf, "A"),
        (1e-5, 1e-2, "B"),
    ]
    # at its tightest target (1e-2) C (error 2e-2) does not count: B is the runner-up
    assert ranges[0]["cost_s"] == 1.0 and ranges[0]["runner_up"] == "B"
    assert ranges[0]["runner_up_cost_s"] == 3.0
    # the merged range keeps the numbers of its tightest target (1e-5: B alone)
    assert ranges[1]["cost_s"] == 5.0 and ranges[1]["runner_up"] is None
    assert crossovers(ranges) == [{"error": 1e-2, "above": "A", "below": "B"}]
    text = " ".join(winner_sentences("slope", ranges))
    assert "below it B is faster than A on slope" in text
    assert "No strategy reached an error below 1e-05" in text
    assert "close call" not in text  # 1 s against 3 s: a firm lead
    # B's 3 s point made 1.04 s: within 5 % of A's 1 s at 1e-2, a close call there only
    near = [dict(p, wall_s=1.04) if p["wall_s"] == 3.0 else p for p in table]
    near_ranges = winners(near)
    assert [close_call(r) for r in near_ranges] == [True, False]
    text = winner_sentences("slope", near_ranges)
    assert "a close call (within 5% in cost" in text[0] and "close call" not in text[1]
    assert "; a close call at 0.01: within 5% in cost" in text[2], text[2]
    # a runner-up 6 % dearer is a firm lead
    assert not close_call(dict(near_ranges[0], runner_up_cost_s=1.06))
    # the CPU time as the cost can change the winner: B is cheaper in CPU at every target
    cpu = [dict(r, cpu_s=c) for r, c in zip(table, (4.0, 9.0, 2.0, 3.0, 0.1, 5.0), strict=True)]
    assert [r["winner"] for r in winners(cpu, "cpu_s")] == ["B"]
    assert winners([{"strategy": "A", "error": None, "wall_s": 1.0}]) == []


# ----------------------------------------------------------------------------- planning, input
def test_a_scene_without_any_error_is_plotted_with_the_reason_not_a_crash(tmp_path):
    """A scene whose reference run failed has no error at any point (measured: the full
    sine_boundary sweep's report stopped with "Data cannot be log-scaled"); its figure says
    so instead."""
    from benchmarks._tradeoff_report import plot_scene

    point = {"strategy": "lr", "label": "base", "role": "base", "knob": None, "sweeps": []}
    records = [{**point, "error": None, "wall_s": 214.6, "pareto": False}]
    path = plot_scene(records, tmp_path / "scene.png", "sine_boundary", "error")
    assert path.stat().st_size > 5_000


def test_each_strategy_sweeps_the_knobs_its_options_declare():
    # the declaration: options fields with "sweep" metadata
    assert set(option_knobs("barrier")) == {"tol"}
    assert set(option_knobs("augury")) == {"cfl_safety_fem", "cfl_safety_mpm", "tau", "iterations"}
    assert {"xpic_order", "corrections"} <= set(option_knobs("lr"))
    assert ladder({"finer": -1, "factor": 10.0}, 1e-6, "full") == pytest.approx((1e-5, 1e-6, 1e-7))
    # finer is out of range: quick mode goes one step coarser instead
    assert ladder({"finer": 1, "step": 1, "min": 1, "max": 2}, 2, "quick") == (1, 2)
    assert ladder({"finer": 1, "step": 4, "first": 1}, None, "full") == (None, 1, 5)
    assert ladder({"finer": -1, "factor": 2.0}, None, "quick") == ()  # tau = None is dt

    def knobs(scene: str, strategy: str) -> set[str]:
        points = tradeoff.plan("quick", scene, strategies=strategy)
        return {k for p in points for k in p["sweeps"]}

    # a fixed dt is a knob; at dt = "auto" the CFL fractions are, and dt is not
    assert knobs("rings", "barrier") == {"dx", "ppc", "dhat", "dt", "tol"}
    assert knobs("rings", "two_stage") == {"dx", "ppc", "dhat", "tol"} | {
        "cfl_safety_fem",
        "cfl_safety_mpm",
    }
    # augury has no barrier (no dhat); tau = None (dt) is not swept at dt = "auto", a set tau is
    assert knobs("rings", "augury") == {
        "dx",
        "ppc",
        "iterations",
        "cfl_safety_fem",
        "cfl_safety_mpm",
    }
    assert knobs("augury_blocks", "augury") == {"dx", "dt", "tau", "iterations"}
    assert knobs("slope", "lr") == {"dx", "ppc", "dt", "corrections", "xpic_order"}
    # the explicit slope's dt never goes above the stable step (6e-5 s)
    slope_dt = {p["settings"]["dt"] for p in tradeoff.plan("full", "slope", strategies="two_stage")}
    assert max(slope_dt) <= 6e-5


def test_plan_is_one_at_a_time_around_each_strategys_base_with_one_reference():
    points = tradeoff.plan("quick", "rings", "dt,ppc", strategies="barrier,two_stage")
    ids = [p["id"] for p in points]
    assert ids == [
        "rings/barrier/base",
        "rings/barrier/ppc=9",
        "rings/barrier/dt=5e-3",
        "rings/barrier/reference",
        "rings/two_stage/base",
        "rings/two_stage/ppc=9",
    ]
    base = tradeoff.strategy_base("rings", "barrier", "quick")
    assert points[0]["settings"] == base and base["options"] == {"tol": 1e-6}
    for p in points:
        if p["role"] == "sweep":
            ref = tradeoff.strategy_base("rings", p["strategy"], "quick")
            changed = {k for k in ref if p["settings"][k] != ref[k]}
            assert changed == {p["knob"]}, p["id"]
    # one reference per scene, the barrier run at the finest value of each of its knobs
    reference = [p for p in points if p["is_reference"]]
    assert [p["id"] for p in reference] == ["rings/barrier/reference"]
    assert reference[0]["settings"] == {**base, "dt": 5e-3, "ppc": 9}
    # without barrier among the strategies, its reference run is planned all the same (here the
    # finest barrier run is its ppc = 9 point: one knob swept)
    alone = tradeoff.plan("quick", "rings", "ppc", strategies="lr")
    assert [p["id"] for p in alone if p["is_reference"]] == ["rings/barrier/ppc=9"]
    assert {p["strategy"] for p in alone if not p["is_reference"]} == {"lr"}
    # a strategy that does not apply is skipped; lr_compression and augury_blocks have theirs
    assert {p["strategy"] for p in tradeoff.plan("quick", "hertz")} == {"barrier"}
    assert {p["strategy"] for p in tradeoff.plan("quick", "lr_compression")} == {"lr"}
    assert {p["scene"] for p in tradeoff.plan("full")} == set(tradeoff.SCENES)
    # every scene that a strategy does not run says why
    for scene, spec in tradeoff.SCENES.items():
        declared = set(spec["strategies"]) | set(spec["not_applicable"])
        assert declared == set(tradeoff._registry()), scene


def test_a_knob_declared_reference_at_base_keeps_the_base_in_the_reference_run():
    """sine_boundary's full reference keeps barrier's base tol (declared with its reason):
    it is then the dt = 5e-4 s sweep point, one run, marked as the reference; the quick
    reference, with no such declaration, takes the finest tol as before."""
    why = tradeoff.SCENES["sine_boundary"]["modes"]["full"]["reference_at_base"]
    assert set(why) == {"tol"} and "2 h" in why["tol"]
    full = tradeoff.plan("full", "sine_boundary", strategies="barrier")
    base = tradeoff.strategy_base("sine_boundary", "barrier", "full")
    (ref,) = [p for p in full if p["is_reference"]]
    assert ref["id"] == "sine_boundary/barrier/dt=5e-4" and ref["role"] == "reference"
    assert ref["settings"] == {**base, "dt": 5e-4}
    assert sum(p["settings"] == ref["settings"] for p in full) == 1
    quick = tradeoff.plan("quick", "sine_boundary", strategies="barrier")
    (qref,) = [p for p in quick if p["is_reference"]]
    assert qref["id"] == "sine_boundary/barrier/reference"
    assert qref["settings"]["options"]["tol"] == 1e-5
    # the scripted strip sets no stable step there: the FEM CFL fraction is no knob of the
    # explicit strategies (declared in no_knobs)
    knobs = {p["knob"] for p in tradeoff.plan("full", "sine_boundary")}
    assert "cfl_safety_mpm" in knobs and "cfl_safety_fem" not in knobs


def test_reference_runs_are_submitted_first_then_the_plans_order():
    records = tradeoff.plan("full", "rings,slope")
    ids = [r["id"] for r in records]
    assert ids.index("rings/barrier/reference") > 0  # the plan lists it after barrier's knobs
    order = tradeoff.run_order(records, list(range(len(records))))
    assert ids[order[0]] == "rings/barrier/reference"
    assert order[1:] == sorted(order[1:])  # the others keep the plan's order
    assert sorted(order) == list(range(len(records)))
    ref = ids.index("rings/barrier/reference")
    assert tradeoff.run_order(records, [1, 3, ref]) == [ref, 1, 3]  # a resumed sweep's rest
    assert tradeoff.run_order(records, [1, 3]) == [1, 3]


def test_bad_input_names_what_is_wrong(capsys, monkeypatch, tmp_path):
    with pytest.raises(ValueError, match="unknown knob 'dtt'; available: dt, dx"):
        tradeoff.plan("quick", None, "dt,dtt")
    with pytest.raises(ValueError, match="unknown scene 'ring'; available: augury_blocks"):
        tradeoff.plan("quick", "ring")
    # the old alias is gone: strategies go by the registry's names
    with pytest.raises(ValueError, match="unknown strategy 'bfemp'; available: barrier"):
        tradeoff.plan("quick", "rings", strategies="bfemp")
    with pytest.raises(ValueError, match="no scene among hertz runs any of the strategies lr"):
        tradeoff.plan("quick", "hertz", strategies="lr")
    with pytest.raises(ValueError, match="strategy 'lr' does not run hertz"):
        tradeoff.plan("quick", "hertz", sweeps={"hertz": {"lr": {"dt": (1e-3,)}}})
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
            "quick",
            tmp_path,
            scenes="slope",
            strategies="barrier",
            knobs="tol",
            scheduler="tcp://127.0.0.1:9",
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
    record = {"scene": "hertz", "settings": {"strategy": "lr", "options": {}}}
    assert cli.main(["sweep", "--point", json.dumps(record)]) == 2
    assert "hertz: strategy 'lr' does not run here" in capsys.readouterr().err


def _options(parser: argparse.ArgumentParser) -> set[str]:
    return {s for action in parser._actions for s in action.option_strings}


def test_bfemp_sweep_has_the_options_of_the_benchmark():
    bench = bench_main._parser()
    tradeoff.add_arguments(bench)
    parser, _ = cli._parser_and_plugins()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    assert _options(sub.choices["sweep"]) - {"--verbose"} == _options(bench)
    assert "--strategies" in _options(bench)


def test_the_command_line_passes_resume_and_the_points_folder_to_the_sweep(monkeypatch, tmp_path):
    seen = {}

    def fake_sweep(mode, out, **kwargs):  # noqa: ANN001, ANN003, ANN202
        seen.update(mode=mode, out=out, **kwargs)
        return {"json": "j", "md": "m", "scenes": []}

    monkeypatch.setattr(tradeoff, "sweep", fake_sweep)
    parser = bench_main._parser()
    tradeoff.add_arguments(parser)
    folder = str(tmp_path / "kept")
    argv = ["tradeoff", "--full", "--scenes", "slope", "--resume", "--points", folder]
    assert tradeoff.main_from_args(parser.parse_args(argv)) == 0
    assert seen["mode"] == "full" and seen["resume"] is True and seen["points"] == folder
    assert parser.parse_args(["tradeoff"]).points is None  # default: OUT/tradeoff_points/


# ----------------------------------------------------------------------------- a minimal sweep
@pytest.fixture(scope="module")
def minimal(tmp_path_factory):
    out = tmp_path_factory.mktemp("tradeoff")
    summary = tradeoff.sweep(
        "quick",
        out,
        scenes="rings,slope",
        strategies=MINIMAL_STRATEGIES,
        knobs=MINIMAL_KNOBS,
        workers=2,
        sweeps=MINIMAL,
    )
    return summary, json.loads((out / "tradeoff.json").read_text()), out


def _by_id(data: dict) -> dict:
    return {p["id"]: p for p in data["points"]}


def test_minimal_sweep_writes_records_plots_and_report(minimal):
    summary, data, out = minimal
    assert summary["json"] == str(out / "tradeoff.json")
    assert data["wall_s"] < 180.0
    assert data["scenes"] == ["rings", "slope"]
    assert data["strategies"] == {"rings": ["barrier", "augury"], "slope": ["barrier"]}
    # only the chosen strategies are listed as not run, each with why
    assert data["not_run"]["rings"] == {} and data["not_run"]["slope"] == {}
    assert data["warmup_s"] > 0.0 and data["warmup_failures"] == []
    points = _by_id(data)
    assert sorted(points) == [
        "rings/augury/base",
        "rings/augury/iterations=0",
        "rings/barrier/base",
        "rings/barrier/dt=2e-2",
        "slope/barrier/base",
        "slope/barrier/tol=1e-7",
    ]
    for p in points.values():
        for key in ("scene", "strategy", "settings", "mode", "threads", "error", "wall_s"):
            assert key in p, (p["id"], key)
        assert p["failure"] is None, (p["id"], p["failure"])
        assert p["error"] is not None and p["error"] >= 0.0
        assert p["wall_s"] > 0.0 and p["process_wall_s"] > p["wall_s"]
        # one thread per point: the process's CPU time cannot exceed its wall time by much
        assert 0.0 < p["cpu_s"] < 1.1 * p["wall_s"] + 0.5
        assert p["peak_memory_mb"] > 50.0 and p["mode"] == "quick"
        assert p["iterations"] > 0 if p["strategy"] == "barrier" else p["iterations"] == 0
        assert p["settings"]["strategy"] == p["strategy"]
        assert f"--id {p['id']}" in p["replay"]
        # the deepest penetration into a FEM body and the bound it is judged against (issue 40)
        assert p["max_penetration_m"] is not None and p["max_penetration_m"] >= 0.0
        if p["strategy"] == "barrier":
            assert p["penetration_bound_m"] == 0.0
        else:
            cells = p["penetration_bound_cells"]
            assert p["penetration_bound_m"] == pytest.approx(cells * p["penetration_grid_dx_m"])
        assert p["infeasible"] == (p["max_penetration_m"] > p["penetration_bound_m"])
        assert not (p["infeasible"] and p["pareto"])
    # the analytic errors are those the scenes' own metrics give
    slope = points["slope/barrier/tol=1e-7"]
    assert slope["error"] == slope["metrics"]["accel_rel_error"]
    assert slope["settings"]["options"] == {"tol": 1e-7} and slope["metrics"]["steps"] == 50
    # the Newton tolerance is the scene's at the base: 1e-8 m/s
    assert points["slope/barrier/base"]["settings"]["options"] == {"tol": 1e-8}
    for scene in data["scenes"]:
        front = data["pareto"][scene]
        assert front and all(points[i]["pareto"] for i in front)
        assert (out / f"tradeoff_{scene}.png").stat().st_size > 10_000
        # the winners are computed from the feasible points: the cheapest strategy at each target
        for r in data["winners"][scene]:
            reach = [
                p
                for p in points.values()
                if p["scene"] == scene and p["error"] <= r["error_from"] and not p["infeasible"]
            ]
            assert r["cost_s"] == min(p["wall_s"] for p in reach)
    md = (out / "tradeoff.md").read_text()
    for scene in data["scenes"]:
        assert f"## {scene}" in md
    assert "### Winner per error range" in md and "Non-dominated front" in md
    assert md.count("### Penetration") == len(data["scenes"])
    assert "Crossover" in md or len(data["winners"]["rings"]) == 1


def test_rings_errors_of_both_strategies_are_taken_against_the_barrier_reference(minimal):
    _, data, _ = minimal
    points = _by_id(data)
    base = points["rings/barrier/base"]
    # only dt is swept for barrier (tol has its base value): its finest run is the base itself
    assert base["is_reference"] and data["references"]["rings"]["id"] == "rings/barrier/base"
    assert base["error"] == 0.0
    for pid in ("rings/barrier/dt=2e-2", "rings/augury/base", "rings/augury/iterations=0"):
        p = points[pid]
        ref = p["reference"]["metrics"]
        assert ref["energy_loss_pct"] == base["metrics"]["energy_loss_pct"]
        loss = abs(p["metrics"]["energy_loss_pct"] / ref["energy_loss_pct"] - 1.0)
        duration = abs(p["metrics"]["contact_duration_s"] / ref["contact_duration_s"] - 1.0)
        assert p["error_parts"]["energy_loss_pct"] == pytest.approx(loss, rel=1e-12)
        assert p["error_parts"]["contact_duration_s"] == pytest.approx(duration, rel=1e-12)
        assert p["error"] == max(p["error_parts"].values()) > 0.0
    assert points["rings/augury/iterations=0"]["settings"]["options"]["iterations"] == 0
    # the reference's error is 0: barrier is the winner of the tightest range
    assert data["winners"]["rings"][-1]["winner"] == "barrier"
    assert data["best_knob"]["rings"]["barrier"] == "dt"


def test_dask_cluster_gives_the_results_of_local_processes(minimal, tmp_path):
    """The base point of each strategy on the rings, one per Dask worker: augury's error is
    taken against barrier's base as in the local sweep (the swept points would run the same
    way; more points than workers goes through the same ``_execute`` as the local sweep's six
    points on two processes)."""
    distributed = pytest.importorskip("distributed")
    _, data, _ = minimal
    with distributed.LocalCluster(
        n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None
    ) as cluster:
        summary = tradeoff.sweep(
            "quick",
            tmp_path,
            scenes="rings",
            strategies="barrier,augury",
            knobs="tol",  # barrier's tol sweep is its base value: the two base points alone
            scheduler=cluster.scheduler_address,
            sweeps=MINIMAL,
            warmup=False,  # the local sweep has filled numba's cache
        )
    assert summary["executor"]["kind"] == "dask"
    local = _by_id(data)
    assert sorted(p["id"] for p in summary["points"]) == ["rings/augury/base", "rings/barrier/base"]
    for point in summary["points"]:
        assert point["failure"] is None
        mine = local[point["id"]]
        assert point["error"] == mine["error"], point["id"]
        assert point["iterations"] == mine["iterations"]
        assert point["metrics"]["steps"] == mine["metrics"]["steps"]
    # the winners differ only where the timings do: the same error levels
    levels = [r["error_from"] for r in data["winners"]["rings"]]
    assert {r["error_from"] for r in summary["winners"]["rings"]} <= set(
        p["error"] for p in summary["points"]
    )
    assert levels[-1] == 0.0


def test_replaying_a_record_reproduces_its_error(minimal, capsys):
    _, data, out = minimal
    # the report is rebuilt from the recorded points alone: the same winners and fronts
    again = tradeoff.rerender(out / "tradeoff.json")
    assert again["winners"] == data["winners"] and again["pareto"] == data["pareto"]
    assert "### Winner per error range" in (out / "tradeoff.md").read_text()
    # rings: the error is recomputed against the reference metrics stored in the record
    args = ["tradeoff", "--replay", str(out / "tradeoff.json"), "--id", "rings/augury/base"]
    assert bench_main.main(args) == 0
    printed = capsys.readouterr().out
    assert "rings/augury/base: error" in printed and ": reproduced;" in printed
    # a record whose error does not match what the point gives is reported (exit 1)
    record = dict(_by_id(data)["slope/barrier/tol=1e-7"])
    record["error"] = 2.0 * record["error"]
    assert cli.main(["sweep", "--point", json.dumps(record)]) == 1
    printed = capsys.readouterr().out
    assert "NOT reproduced" in printed
    recorded = _by_id(data)["slope/barrier/tol=1e-7"]["error"]
    assert f"error {recorded} (recorded {record['error']})" in printed
    assert math.isfinite(recorded)


# ----------------------------------------------------------------------------- resuming a sweep
def test_a_resumed_sweep_runs_only_the_points_not_kept(minimal, tmp_path, monkeypatch):
    """The minimal sweep kept each point as it finished; with one of them deleted, a resumed
    sweep (from a points folder of its own, as a committed one) runs that one alone, gives
    every point the error of the first sweep and each kept point the commit that measured it."""
    import json
    import shutil

    from benchmarks import _tradeoff_point
    from benchmarks._tradeoff_cache import FOLDER, PointCache

    _, data, out = minimal
    kept = sorted((out / FOLDER).glob("*.json"))
    assert len(kept) == len(data["points"])  # one file per point, none for the warm-ups
    folder = tmp_path / "kept_points"
    shutil.copytree(out / FOLDER, folder)
    measured_elsewhere = "0" * 40  # as if an earlier commit with the same code measured them
    for path in folder.glob("*.json"):
        entry = json.loads(path.read_text())
        path.write_text(json.dumps({**entry, "commit": measured_elsewhere}))
    cache = PointCache(folder, data["environment"]["commit"])
    lost = _by_id(data)["slope/barrier/tol=1e-7"]
    cache.path(tradeoff._job(lost, None)).unlink()

    ran = []
    real = _tradeoff_point.execute_point

    def counting(job):  # noqa: ANN001, ANN202
        ran.append(job["settings"])
        return real(job)

    monkeypatch.setattr(_tradeoff_point, "execute_point", counting)
    again = tradeoff.sweep(
        "quick",
        tmp_path,
        scenes="rings,slope",
        strategies=MINIMAL_STRATEGIES,
        knobs=MINIMAL_KNOBS,
        workers=1,
        sweeps=MINIMAL,
        warmup=False,
        resume=True,
        points=folder,
    )
    assert not (tmp_path / FOLDER).exists()  # the points went to the folder given
    assert ran == [tradeoff._job(lost, None)["settings"]]
    assert sorted(again["resumed"]) == sorted(set(_by_id(data)) - {lost["id"]})
    first = _by_id(data)
    for p in again["points"]:
        assert p["resumed"] == (p["id"] != lost["id"])
        assert p["error"] == first[p["id"]]["error"], p["id"]
        if p["resumed"]:  # its measurement as first taken, times and commit included
            assert p["wall_s"] == first[p["id"]]["wall_s"]
        assert p["commit"] == (
            measured_elsewhere if p["resumed"] else data["environment"]["commit"]
        )
    assert cache.get(tradeoff._job(lost, None)) is not None  # kept again
    assert again["winners"]["slope"] and again["references"] == data["references"]


def test_the_point_cache_keys_on_code_settings_and_threads(tmp_path):
    from benchmarks._tradeoff_cache import PointCache

    job = {"module": "m", "settings": {"scene": "slope", "dt": 1e-3}, "threads": 1}
    cache = PointCache(tmp_path, "abc", code="code1")
    assert cache.get(job) is None
    assert cache.put("slope/x/base", job, {"metrics": {"e": 1.0}, "failure": None})
    assert cache.get(job) == {"metrics": {"e": 1.0}, "failure": None}
    # another commit of the same code: the same point, measured by the first commit
    later = PointCache(tmp_path, "def", code="code1")
    assert later.get(job) == cache.get(job) and later.entry(job)["commit"] == "abc"
    # other code, other settings or other threads: not the same point
    assert PointCache(tmp_path, "abc", code="code2").get(job) is None
    assert cache.get({**job, "settings": {"scene": "slope", "dt": 2e-3}}) is None
    assert cache.get({**job, "threads": 2}) is None
    # the timeout does not change what a point measures
    assert cache.get({**job, "timeout_s": 60.0}) is not None
    # points that gave no metrics (a timeout, a crash, a refusal raised before the run) are not
    # kept, so a resumed sweep runs them again
    other = {**job, "threads": 3}
    assert not cache.put("slope/x/base", other, {"metrics": None, "failure": "timed out"})
    assert cache.get(other) is None
    # a run that ended in a named step failure is its outcome, measured: kept like any other
    tunneled = {"metrics": {"steps": 692, "failure": "TUNNELED"}, "failure": "TUNNELED"}
    assert cache.put("slope/x/dt=2e-3", other, tunneled)
    assert cache.get(other) == tunneled
    # a damaged file is not a measurement: the point runs again
    cache.path(job).write_text("{not json")
    assert cache.get(job) is None


def test_the_code_version_changes_with_any_python_file_of_the_packages(tmp_path):
    from benchmarks._tradeoff_cache import code_version

    for package in ("bfemp", "benchmarks"):
        (tmp_path / package).mkdir()
        (tmp_path / package / "a.py").write_text("x = 1\n")
    (tmp_path / "bfemp" / "notes.md").write_text("docs")
    packages = ("bfemp", "benchmarks")
    first = code_version(tmp_path, packages, ())
    assert code_version(tmp_path, packages, ()) == first  # deterministic
    (tmp_path / "bfemp" / "notes.md").write_text("other docs")  # not code: the same
    assert code_version(tmp_path, packages, ()) == first
    (tmp_path / "benchmarks" / "a.py").write_text("x = 2\n")  # edited code: another digest
    edited = code_version(tmp_path, packages, ())
    assert edited != first
    (tmp_path / "benchmarks" / "a.py").rename(tmp_path / "benchmarks" / "b.py")  # renamed
    assert code_version(tmp_path, packages, ()) not in (first, edited)
    # the project's own digest covers its packages
    assert len(code_version()) == 20


def test_the_code_version_follows_the_point_modules_imports_and_nothing_else(tmp_path):
    """Of a package outside ``packages``, only the modules the point's modules import (in any
    statement, inside functions too, relative or absolute, at any depth) change the digest."""
    from benchmarks._tradeoff_cache import POINT_MODULES, ROOT, code_version, imported_modules

    bench = tmp_path / "bench"
    (bench / "sub").mkdir(parents=True)
    files = {
        "__init__.py": "",
        "point.py": "import math\n\ndef run():\n    from bench import scene\n    return scene\n",
        "scene.py": "from .sub.helper import f\nfrom bench.sub import other\n",
        "sub/__init__.py": "",
        "sub/helper.py": "def f():\n    return 1\n",
        "sub/other.py": "X = 1\n",
        "report.py": "from bench import scene\n",  # imports the scene; nobody imports it
    }
    for name, text in files.items():
        (bench / name).write_text(text)
    found = imported_modules(tmp_path, ("bench.point",))
    assert sorted(found) == [
        "bench",
        "bench.point",
        "bench.scene",
        "bench.sub",
        "bench.sub.helper",
        "bench.sub.other",
    ]
    first = code_version(tmp_path, (), ("bench.point",))
    (bench / "report.py").write_text("from bench import scene  # edited\n")
    assert code_version(tmp_path, (), ("bench.point",)) == first  # not imported: the same
    (bench / "sub" / "helper.py").write_text("def f():\n    return 2\n")  # two imports deep
    assert code_version(tmp_path, (), ("bench.point",)) != first
    with pytest.raises(ValueError, match="'bench.nothing' has no file"):
        imported_modules(tmp_path, ("bench.nothing",))
    # the project's points: the scene modules are in, the sweep's driver and report are not
    assert tradeoff.RUNS_MODULE in POINT_MODULES  # loaded by name: the digest must name it
    project = imported_modules(ROOT, POINT_MODULES)
    assert {"benchmarks.rings", "benchmarks.sine_boundary", "benchmarks.common"} <= set(project)
    assert not {"benchmarks.tradeoff", "benchmarks._tradeoff_report"} & set(project)


def test_a_sweep_shows_its_progress_point_by_point(monkeypatch, tmp_path, capsys):
    # issue 42: `bfemp sweep` was silent for minutes without --verbose
    from benchmarks import _tradeoff_point

    def fake_local(ids, jobs, workers, on_done=None):  # noqa: ANN001, ANN202
        results = []
        for k in range(len(ids)):
            results.append(_tradeoff_point._failed("not run (test)", 0.0))
            if on_done is not None:
                on_done(k, results[-1])
        return results

    monkeypatch.setattr(tradeoff, "execute_local", fake_local)
    summary = tradeoff.sweep(
        "quick",
        tmp_path,
        scenes="slope",
        strategies=MINIMAL_STRATEGIES,
        knobs=MINIMAL_KNOBS,
        workers=1,
        sweeps=MINIMAL,
        progress=True,
    )
    err = capsys.readouterr().err
    n = len(summary["points"])
    assert n >= 2 and "tradeoff points: 100%" in err and f"{n}/{n}" in err
    assert "tradeoff warm-up: 100%" in err
    assert any(p["id"] in err for p in summary["points"])  # the last point done is named
    seen = {}
    monkeypatch.setattr(tradeoff, "sweep", lambda mode, out, **kw: seen.update(kw) or summary)
    parser = bench_main._parser()
    tradeoff.add_arguments(parser)
    tradeoff.main_from_args(parser.parse_args(["tradeoff", "--quick", "--scenes", "slope"]))
    assert seen["progress"] is True  # the command line shows it


def test_verify_compares_the_points_not_what_their_times_decide():
    """The fronts, winners, crossovers and knob effects follow the points' wall times, which
    no rerun reproduces: ``verify`` leaves them out, and still sees a point's error move."""
    from benchmarks.runner import differences

    point = {"id": "slope/barrier/base", "error": 0.1, "wall_s": 2.0, "pareto": True}
    old = {
        "points": [point],
        "pareto": {"slope": ["slope/barrier/base"]},
        "warmup_s": 3.0,
        "winners": {"slope": [{"winner": "barrier", "cost_s": 2.0}]},
        "crossovers": {},
        "knob_effects": {"slope": {"barrier": {"dt": {"loglog_slope": -1.0}}}},
        "best_knob": {"slope": {"barrier": "dt"}},
    }
    new = json.loads(json.dumps(old))
    new["points"][0].update(wall_s=1.0, pareto=False)
    new.update(pareto={"slope": []}, warmup_s=9.0, winners={"slope": []}, best_knob={})
    new["knob_effects"]["slope"]["barrier"]["dt"]["loglog_slope"] = -2.0
    new["crossovers"] = {"slope": [{"error": 0.1}]}
    assert differences(old, new, timings=tradeoff.BENCHMARK.timings) == []
    new["points"][0]["error"] = 0.2
    assert differences(old, new, timings=tradeoff.BENCHMARK.timings) == [
        "/points[0]/error: 0.1, now 0.2"
    ]
