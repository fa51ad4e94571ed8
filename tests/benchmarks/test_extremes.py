"""Extremes, quick subset: every case passes (no penetration, J > 0, no NaN, bounded energy) or
stops with the named failure it is expected to; the independent checks catch what they claim."""

import json
import math

import numpy as np
import pytest

import bfemp
from benchmarks import extremes
from benchmarks._extreme_cases import CASES, build_scene, quick_cases


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    out = tmp_path_factory.mktemp("extremes")
    summary = extremes.run("quick", out)
    data = json.loads((out / "extremes.json").read_text())
    return summary, data, out


@pytest.fixture(scope="module")
def rows(result):
    return {row["name"]: row for row in result[1]["cases"]}


def test_writes_the_table(result):
    summary, data, out = result
    assert summary["json"] == str(out / "extremes.json")
    for key in ("cases", "n_pass", "n_unexplained", "wall_s", "steps", "newton_iterations"):
        assert key in data, key
    assert data["n_cases"] == len(quick_cases()) == len(data["cases"])
    table = (out / "extremes.md").read_text().splitlines()
    assert sum(line.startswith("| ") for line in table) == 1 + len(data["cases"])
    assert (out / "extremes.png").stat().st_size > 10_000


@pytest.mark.parametrize("case", [c.name for c in quick_cases()])
def test_case_has_its_expected_outcome(rows, case):
    row = rows[case]
    expect = next(c.expect for c in CASES if c.name == case)
    assert row["status"] == expect, row["outcome"]
    assert row["steps"] >= 1
    # whatever the outcome, nothing went wrong before it: the checks ran on every completed step
    assert row["penetrations"] == 0
    assert row["min_J"] > 0.0
    assert row["min_distance_geometric"] > 0.0
    if expect == "pass":
        assert row["steps"] == row["steps_planned"]
        assert row["energy_growth_max"] < extremes.ENERGY_TOL[row["config"]["integrator"]]
        # contact really happened, inside d-hat and at a positive distance, and the step
        # reports agree with the independent particle-to-boundary distance
        assert row["contact_steps"] >= 1
        assert 0.0 < row["min_distance"] < row["dhat_m"]
        assert row["min_distance_geometric"] == pytest.approx(row["min_distance"], rel=1e-9)
    else:
        assert row["outcome"].startswith(expect) and len(row["outcome"]) > len(expect) + 10


def test_no_unexplained_failures_in_the_quick_subset(result):
    data = result[1]
    assert data["n_unexplained"] == 0, data["unexplained"]
    assert data["no_nan"] and data["no_inversion"] and data["no_penetration"]


def test_a_very_soft_body_is_squashed_but_never_inverted(rows):
    """E = 1e3 Pa: the wave speed (1 m/s) is 40 times below the impact speed."""
    row = rows["E_1e3"]
    assert 0.0 < row["min_J"] < 0.05


def test_resting_block_stays_put(rows):
    row = rows["resting"]
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


def test_vertex_case_puts_particles_exactly_over_vertices():
    case = next(c for c in CASES if c.name == "vertex")
    scene, info = build_scene(case.config, "quick")
    model = scene.build()
    top = model.fem_X[model.fem_X[:, 1] == 0.0, 0]
    over = np.isin(model.mpm_X[:, 0], top)
    assert info["vertex_aligned_particles"] == np.count_nonzero(over) > 0
