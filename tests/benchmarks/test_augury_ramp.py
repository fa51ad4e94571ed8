"""augury_ramp smoke: a block on a 30 degree ramp sticks for mu above tan30, slides for mu = 0
(AUG section 3.3); the quick and full modes are run from the command line."""

import json

import pytest

from benchmarks import augury_ramp


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    out = tmp_path_factory.mktemp("augury_ramp")
    augury_ramp.run("smoke", out)
    assert (out / "augury_ramp.png").stat().st_size > 10_000
    return json.loads((out / "augury_ramp.json").read_text())


def test_mu_above_tan30_sticks_and_frictionless_slides(data):
    assert abs(data["control"]["slip_end"]) < 1e-3
    assert data["targets"]["mu_0.7_sticks"]
    for case in data["cases"]:
        assert case["mu"] == 0.0
        assert 0.0 < case["s_end"] < case["s_analytic"]  # never faster than free sliding
    # APIC at mu = 0 slips well beyond the sticking control (PIC at h = 1 barely slips: 5.4e-4 m
    # at t = 0.03 s, measured, below the control's 6.0e-4 m)
    apic = next(c for c in data["cases"] if c["transfer"] == "apic")
    assert apic["slip_end"] > 2.0 * abs(data["control"]["slip_end"])


def test_analytic_displacement():
    assert augury_ramp.analytic_s(0.0, 0.2) == pytest.approx(1.0)
    assert augury_ramp.analytic_s(0.2, 1.0) == pytest.approx(
        0.5 * 100 * (0.5 - 0.2 * 0.866025), rel=1e-5
    )
    assert augury_ramp.analytic_s(0.7, 1.0) == 0.0
