"""perf_explicit, quick mode: the facts behind the timings, not the timings (shared machine)."""

import json
import math

import pytest

from benchmarks import perf_explicit


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    out = tmp_path_factory.mktemp("perf_explicit")
    summary = perf_explicit.run("quick", out)
    return summary, json.loads((out / "perf_explicit.json").read_text())


def test_record_has_every_column(result):
    summary, data = result
    assert summary["json"].endswith("perf_explicit.json")
    (case,) = data["cases"].values()
    assert case["particles"] == 1600 and case["dx"] == pytest.approx(0.05)
    bfemp = case["bfemp"]
    assert bfemp["particle_steps_per_s"] > 0.0 and math.isfinite(bfemp["particle_steps_per_s"])
    assert sum(bfemp["shares"].values()) == pytest.approx(1.0)
    assert all(bfemp["shares"][k] > 0.0 for k in ("p2g", "force", "g2p"))
    assert case["term_route_s"]["total_s"] > 0.0 and case["fused_route_s"] > 0.0


def test_explicit_step_is_the_cfl_bound_and_barrier_steps_are_longer(result):
    _, data = result
    (case,) = data["cases"].values()
    c_p = math.sqrt(1e5 * 0.7 / (1.3 * 0.4) / 1000.0)  # (lam + 2 mu) / rho, nu = 0.3
    spin = perf_explicit.SPIN * math.sqrt(0.5)  # fastest particle: a corner of the block
    assert case["bfemp"]["dt_s"] <= 0.4 * case["dx"] / c_p
    assert case["bfemp"]["dt_s"] == pytest.approx(0.4 * case["dx"] / (c_p + spin), rel=2e-2)
    versus = case["single_field_vs_barrier"]
    assert versus["barrier"]["dt_s"] > 5 * versus["single_field"]["dt_s"]
    assert versus["barrier"]["newton_iterations"] >= 1


@pytest.mark.skipif(perf_explicit.ti is None, reason="taichi not installed")
def test_taichi_runs_the_same_scene(result):
    _, data = result
    (case,) = data["cases"].values()
    assert case["taichi"]["threads"] == perf_explicit.THREADS
    # both conserve momentum and nothing reaches the floor: the centres of mass coincide
    assert case["com_difference_m"] < 1e-10
