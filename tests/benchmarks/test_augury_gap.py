"""augury_gap quick: PIC stops at the closed-form gap, APIC closes it (AUG section 3.1)."""

import json

import pytest

from benchmarks import augury_gap


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    out = tmp_path_factory.mktemp("augury_gap")
    summary = augury_gap.run("quick", out)
    assert (out / "augury_gap.png").stat().st_size > 10_000
    return json.loads((out / "augury_gap.json").read_text()) | {"summary": summary}


def test_pic_stops_at_the_closed_form_gap_and_apic_closes_it(data):
    assert [row["tau"] for row in data["rows"]] == list(augury_gap.MODES["quick"])
    for row in data["rows"]:
        assert row["apic_final_gap"] < 1e-3
        assert abs(row["pic_final_gap"] - row["pic_closed_form_gap"]) < 1e-3
        assert row["pic_final_gap"] > 0.05
        assert row["sim_vs_ode_max"] < 1e-2
    assert data["target_met"]


def test_closed_form_reproduces_the_paper_table():
    for tau, gap in augury_gap.PAPER_PIC_GAPS.items():
        assert augury_gap.pic_closed_form_gap(tau, -1.0) == pytest.approx(gap, abs=1.5e-3)
