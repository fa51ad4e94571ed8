"""Extremes, quick subset, under every strategy: every case passes (no penetration, J > 0, no
NaN, bounded energy) or ends with the named outcome it is expected to; nothing is UNEXPLAINED;
the independent checks catch what they claim."""

import math

import numpy as np
import pytest

import bfemp
from benchmarks import extremes
from benchmarks._extreme_cases import CASES, build_scene, quick_cases
from benchmarks._extreme_strategies import EXPLICIT, MAX_STEPS, NO_CROSSING, STRATEGY_NAMES
from tests.benchmarks._records import record_fixture

#: started first (tests/conftest.py): one of the suite's longest files
pytestmark = pytest.mark.slow

#: the dt of every case but E_1e3 (1e-4 s and more) exceeds the explicit stable step at dx = 0.05
#: m (4.8e-5 s at E = 1e8 Pa): "REFUSED" there, and "REFUSED/X" means X for the extra run at
#: dt = "auto". E_1e3: c_p = 3.7 m/s, stable step 4.6e-4 s, so its dt = 1e-4 s runs as given.
REF = "REFUSED"
#: what augury, two_stage and lr share. E = 1e3 Pa: the block crushes the soft slab's top cells
#: through the contact and explicit elasticity steps one of them through J = 0 (no det F guard);
#: E = 1e12 Pa: stable step 4.8e-7 s, 4151 steps for 2 ms > MAX_STEPS; dt = 0.1 s: refused, no
#: auto run (it would repeat base's)
CONTACT_EXPLICIT = {
    "E_1e3": "INVERTED",
    "E_1e12": "REFUSED/TOO_MANY_STEPS",
    "nu_0.499": "REFUSED/pass",
    "dt_1e-1": REF,
}
#: per explicit strategy and quick case, the expected outcome, each with its reason
EXPECTED = {
    "single_field": {
        # FEM bodies meet nothing but level sets: the block passes through the slab
        "base": "REFUSED/PENETRATION",
        "E_1e3": "PENETRATION",
        # E = 1e12 Pa: stable step 4.8e-7 s, 4151 steps for 2 ms > MAX_STEPS
        "E_1e12": "REFUSED/TOO_MANY_STEPS",
        "nu_0.499": "REFUSED/PENETRATION",
        # dt = 0.1 s: refused; no auto run (it would repeat base's)
        "dt_1e-1": REF,
        # no barrier: d-hat and kappa are not knobs of it
        "dhat_1e-6": "NOT_APPLICABLE",
        "mass_1e4": "REFUSED/PENETRATION",
        "vertex": "REFUSED/PENETRATION",
        "kappa_1e0": "NOT_APPLICABLE",
        "kappa_1e16": "NOT_APPLICABLE",
        # the block falls through the fixed slab
        "resting": "REFUSED/PENETRATION",
    },
    "augury": {
        **CONTACT_EXPLICIT,  # nu_0.499: issue 40 (MPM normals outward) left no particle inside
        # AUG admits interpenetration (pitfall A9): a particle row ends inside the slab
        "base": "REFUSED/PENETRATION",
        "dhat_1e-6": "NOT_APPLICABLE",
        # the heavy block on the light slab: the contact holds (no particle inside)
        "mass_1e4": "REFUSED/pass",
        "vertex": "REFUSED/PENETRATION",
        "kappa_1e0": "NOT_APPLICABLE",
        "kappa_1e16": "NOT_APPLICABLE",
        # resting on the fixed slab (kinematic foreground of infinite inertia since issue 40;
        # it crept down at 0.02 m/s before)
        "resting": "REFUSED/pass",
    },
    "two_stage": {
        # the barrier's contact solve on explicit free motion: no crossing at the stable step
        "base": "REFUSED/pass",
        **CONTACT_EXPLICIT,
        # d-hat and kappa reach two_stage through scene.set_contact: they are run
        "dhat_1e-6": "REFUSED/pass",
        "mass_1e4": "REFUSED/pass",
        "vertex": "REFUSED/pass",
        # kappa = 1 Pa: as for barrier (step 4), stopping the block needs d / dhat below what
        # Newton resolves: the contact solve hits its cap of 200 (step 12, d = 4e-8 m)
        "kappa_1e0": "REFUSED/MAX_ITERATIONS",
        # kappa = 1e16 Pa: the contact solve (inertia + barrier, the elasticity is in x*) hits
        # its cap of 200 at the first contact step (step 3); barrier's, with the elasticity in
        # the same solve, takes at most 87 per step on this case
        "kappa_1e16": "REFUSED/MAX_ITERATIONS",
        # symplectic Euler keeps the landing's energy: the block bounces on the barrier
        "resting": "REFUSED/DRIFT",
    },
    "lr": {
        # one correction per step (lr's default since issue 40): the slab gets the block's
        # approach momentum and holds it (before, the paper's two corrections with f^{C,1}
        # gave it neither, and the lowest particle rows ended inside the slab)
        "base": "REFUSED/pass",
        **CONTACT_EXPLICIT,
        "dhat_1e-6": "NOT_APPLICABLE",
        "mass_1e4": "REFUSED/pass",
        "vertex": "REFUSED/pass",
        "kappa_1e0": "NOT_APPLICABLE",
        "kappa_1e16": "NOT_APPLICABLE",
        # the fixed slab is rigid in lr's contact law (issue 40; before, the block sank in)
        "resting": "REFUSED/pass",
    },
}
# barrier: the outcomes the cases declare (unchanged by the strategy column)
EXPECTED["barrier"] = {c.name: c.expect for c in quick_cases()}


result = record_fixture("extremes")


@pytest.fixture(scope="module")
def rows(result):
    return {(row["strategy"], row["name"]): row for row in result[1]["cases"]}


def test_expected_table_covers_every_strategy_and_quick_case():
    assert set(EXPECTED) == set(STRATEGY_NAMES)
    for strategy, table in EXPECTED.items():
        assert set(table) == {c.name for c in quick_cases()}, strategy


def test_writes_the_table(result):
    summary, data, out = result
    assert summary["json"] == str(out / "extremes_quick.json")
    for key in ("cases", "n_pass", "n_unexplained", "wall_s", "steps", "table", "by_strategy"):
        assert key in data, key
    assert data["strategies"] == list(STRATEGY_NAMES)
    assert data["n_cases"] == len(quick_cases())
    assert data["n_rows"] == len(data["cases"]) == len(quick_cases()) * len(STRATEGY_NAMES)
    lines = (out / "extremes_quick.md").read_text().splitlines()
    header = lines.index("| case | knob | " + " | ".join(STRATEGY_NAMES) + " |")
    body = lines[header + 2 : header + 2 + len(quick_cases())]
    assert all(line.startswith("| ") and line.count("<br>") >= 1 for line in body[:1])
    assert len(body) == len(quick_cases()) and lines[header + 2 + len(quick_cases())] == ""
    assert (out / "extremes_quick.png").stat().st_size > 10_000


CASE_IDS = [(s, c.name) for s in STRATEGY_NAMES for c in quick_cases()]


@pytest.mark.parametrize(("strategy", "case"), CASE_IDS, ids=[f"{s}-{c}" for s, c in CASE_IDS])
def test_case_has_its_expected_outcome(rows, strategy, case):
    row = rows[(strategy, case)]
    expect, _, expect_auto = EXPECTED[strategy][case].partition("/")
    assert row["status"] == expect, row["outcome"]
    assert row["outcome"].startswith(expect)
    if expect != "pass":
        assert len(row["outcome"]) > len(expect) + 20  # the reason is named
    if expect == "REFUSED" and strategy in EXPLICIT and case != "E_1e3":
        # the refusal names the bound, which is the step the auto run took
        assert "exceeds the explicit stable step" in row["outcome"]
        if expect_auto:
            assert f"{row['auto']['dt']:.6g} s" in row["outcome"]
    assert ("auto" in row) == bool(expect_auto)
    run = row["auto"] if expect_auto else row
    if expect_auto:
        assert run["status"] == expect_auto, run["outcome"]
    status = run["status"]
    if status in ("NOT_APPLICABLE", "REFUSED", "TOO_MANY_STEPS"):
        assert run["steps"] == 0  # decided before a single step
        if status == "TOO_MANY_STEPS":
            assert run["steps_planned"] > MAX_STEPS["quick"]
        return
    assert run["steps"] >= 1
    # whatever the outcome, the checks ran on every completed step and found what they promise
    if strategy in NO_CROSSING:
        assert run["penetrations"] == 0
        assert run["min_distance_geometric"] > 0.0
    if strategy == "barrier" or status != "INVERTED":
        assert run["min_J"] > 0.0
    if status == "pass":
        assert run["steps"] == run["steps_planned"]
        assert run["penetrations"] == 0
        assert run["energy_growth_max"] < extremes.ENERGY_TOL[run["integrator"]]
    if status == "PENETRATION":
        assert run["penetrations"] > 0 and strategy not in NO_CROSSING
        assert run["steps"] == run["steps_planned"]  # the run went on to the end
    if status == "INVERTED":
        # found in an accepted state by the benchmark's checks, or refused by the step itself
        # (two_stage checks J > 0 after its step: the states it kept all have J > 0)
        assert strategy in EXPLICIT
        assert run["min_J"] <= 0.0 or run["outcome"].startswith("INVERTED at step")
    if status == "DRIFT":
        assert run["drift_m"] > extremes.DRIFT_TOL * row["dhat_m"] and strategy in EXPLICIT
    if status == "pass" and strategy in NO_CROSSING:
        # contact really happened, inside d-hat and at a positive distance, and the step
        # reports agree with the independent particle-to-boundary distance
        assert run["contact_steps"] >= 1
        assert 0.0 < run["min_distance"] < row["dhat_m"]
        assert run["min_distance_geometric"] == pytest.approx(run["min_distance"], rel=1e-9)


def test_no_unexplained_failures_in_the_quick_subset(result):
    data = result[1]
    assert data["n_unexplained"] == 0, data["unexplained"]
    assert data["no_nan"]
    assert data["no_penetration"]["barrier"] and data["no_penetration"]["two_stage"]
    assert not data["no_penetration"]["single_field"]


def test_barrier_column_has_the_barrier_only_outcomes(result):
    """The barrier rows are those of ``extremes`` before the strategy columns (the cases'
    declared outcomes), and the per-strategy table agrees with the rows."""
    data = result[1]
    for case in quick_cases():
        assert data["table"][case.name]["barrier"] == case.expect
        for strategy in STRATEGY_NAMES:
            assert (
                data["table"][case.name][strategy].replace(" / auto: ", "/")
                == (EXPECTED[strategy][case.name])
            )


def test_a_very_soft_body_is_squashed_but_never_inverted(rows):
    """E = 1e3 Pa: the wave speed (1 m/s) is 40 times below the impact speed."""
    row = rows[("barrier", "E_1e3")]
    assert 0.0 < row["min_J"] < 0.05


def test_resting_block_stays_put(rows):
    row = rows[("barrier", "resting")]
    assert row["drift_m"] < extremes.DRIFT_TOL * row["dhat_m"]
    assert row["final_speed"] < 1e-3
    assert row["energy_growth_max"] <= 1e-9  # backward Euler: the landing only dissipates


def test_checks_catch_a_particle_inside_and_an_inverted_cell():
    case = next(c for c in CASES if c.name == "base")
    scene, info = build_scene(case.config, "quick")
    sim = bfemp.Simulation(scene, dt=1e-4)
    checks = extremes._Checks(sim, energy_ref=1.0, energy_tol=1e-2)
    assert checks() == []
    assert checks.min_geometric == pytest.approx(2 * case.config.dhat + 1e-3)
    sim.state.mpm_x[0] = (0.1, -0.05)  # inside the slab
    problems = checks()
    assert len(problems) == 1 and "1 particles inside" in problems[0]
    sim.state.mpm_x[0] = (0.1, 0.5)
    cell = sim.model.fem_cells[0]
    sim.state.fem_x[cell[0]], sim.state.fem_x[cell[1]] = (
        sim.state.fem_x[cell[1]].copy(),
        sim.state.fem_x[cell[0]].copy(),
    )
    assert any("inverted FEM cell" in p for p in checks())
    sim.state.mpm_v[3, 1] = math.nan
    assert checks()[0].startswith("non-finite mpm_v")


def test_checks_count_but_allow_crossing_where_the_strategy_makes_no_promise():
    case = next(c for c in CASES if c.name == "base")
    scene, _ = build_scene(case.config, "quick")
    sim = bfemp.Simulation(scene, strategy="single_field", dt="auto", allow_uncoupled=True)
    checks = extremes._Checks(sim, energy_ref=1.0, energy_tol=1e-2, crossing_allowed=True)
    assert checks() == [] and checks.first_penetration is None
    sim.state.mpm_x[:2] = ((0.1, -0.05), (0.2, -0.05))  # inside the slab
    assert checks() == []
    assert checks.max_penetrations == 2 and checks.first_penetration == 2


def test_too_many_steps_is_decided_before_running():
    """E = 1e12 Pa under an explicit strategy: the stable step is ~5e-7 s."""
    case = next(c for c in CASES if c.name == "E_1e12")
    row = extremes.run_case(case, "quick", "single_field")
    assert row["status"] == "REFUSED"
    auto = row["auto"]
    assert auto["status"] == "TOO_MANY_STEPS" and auto["steps"] == 0 and auto["wall_s"] == 0.0
    assert auto["steps_planned"] == math.ceil(case.config.duration / auto["dt"] - 1e-9)
    assert f"{auto['steps_planned']} steps" in auto["outcome"]


def test_an_auto_run_refused_for_another_reason_is_named():
    """two_stage refuses kappa = "auto" as well as the dt: the auto run is refused by name
    (it raised out of ``run_case`` before)."""
    case = next(c for c in CASES if c.name == "kappa_auto")
    row = extremes.run_case(case, "quick", "two_stage")
    assert row["status"] == "REFUSED" and "exceeds the explicit stable step" in row["outcome"]
    assert row["auto"]["status"] == "REFUSED"
    assert "kappa = 'auto' is not supported" in row["auto"]["outcome"]


@pytest.mark.parametrize("strategy", sorted(EXPLICIT))
def test_barrier_only_integrators_are_not_applicable_to_explicit_strategies(strategy):
    case = next(c for c in CASES if c.name == "newmark")
    row = extremes.run_case(case, "quick", strategy)
    assert row["status"] == "NOT_APPLICABLE" and "symplectic Euler" in row["outcome"]
    assert row["steps"] == 0


def test_strategy_option_of_the_command_line(tmp_path):
    assert extremes.resolve_strategies(None) == STRATEGY_NAMES
    assert extremes.resolve_strategies(["all"]) == STRATEGY_NAMES
    assert extremes.resolve_strategies(["lr", "barrier"]) == ("barrier", "lr")
    with pytest.raises(ValueError, match="nope"):
        extremes.resolve_strategies(["nope"])
    from benchmarks.__main__ import main

    # the CLI refuses an unknown strategy before running anything
    with pytest.raises(SystemExit):
        main(["extremes", "--quick", "--strategy", "nope", "--out", str(tmp_path)])


def test_vertex_case_puts_particles_exactly_over_vertices():
    case = next(c for c in CASES if c.name == "vertex")
    scene, info = build_scene(case.config, "quick")
    model = scene.build()
    top = model.fem_X[model.fem_X[:, 1] == 0.0, 0]
    over = np.isin(model.mpm_X[:, 0], top)
    assert info["vertex_aligned_particles"] == np.count_nonzero(over) > 0
