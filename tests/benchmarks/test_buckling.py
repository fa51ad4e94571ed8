"""Buckling under friction, quick mode (paper section 6.6): the inner MPM ring pulls away from the
outer FEM ring as the crown is pressed down, less the more friction holds the rings together."""

import json

import numpy as np
import pytest

from benchmarks import buckling


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    out = tmp_path_factory.mktemp("buckling")
    summary = buckling.run("quick", out)
    return summary, json.loads((out / "buckling.json").read_text()), out


def test_writes_json_and_plot(result):
    summary, data, out = result
    assert summary["json"] == str(out / "buckling.json")
    assert (out / "buckling.png").stat().st_size > 10_000
    assert [case["mu"] for case in data["cases"]] == list(buckling.MUS)
    for key in ("detachment_end_m", "u_buckle_m", "wall_s", "peak_memory_mb", "parameters"):
        assert key in data, key


def test_every_case_reaches_the_end_without_touching(result):
    _, data, _ = result
    assert data["failed_cases"] == []
    u_end = data["parameters"]["u_end"]
    for case in data["cases"]:
        assert case["error"] is None, case["error"]
        assert case["u_end_m"] == pytest.approx(u_end, rel=1e-9)
        # the rings meet (a pair within dhat) and never touch
        assert 0.0 < case["min_distance_m"] < buckling.DHAT, case["mu"]


def test_detachment_grows_with_the_push(result):
    _, data, _ = result
    for case in data["cases"]:
        d = np.array(case["series"]["detachment_m"])
        # the inner ring's crown runs ahead of the outer ring: a separation of a good part of
        # the 1 m per 3 m of push, not the barrier's 1e-3 m
        assert d[-1] > 0.1, case["mu"]
        assert d[-1] > d[len(d) // 2] > 0.0, case["mu"]


def test_friction_delays_the_detachment(result):
    _, data, _ = result
    end = [data["detachment_end_m"][str(mu)] for mu in buckling.MUS]
    assert end[0] > end[1] > end[2], end
    assert data["ordered_at_end"]
