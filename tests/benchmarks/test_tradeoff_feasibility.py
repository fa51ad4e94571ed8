"""Trade study feasibility (issue 40, item 6): a point that penetrates a FEM body beyond its
strategy's stated bound is infeasible: drawn (a cross, with a legend entry), named in the report
with its depth against the bound, never on a Pareto front and never the winner of an error
range, even as the cheapest point at the best error. The bound is read from the stepper class
when the point runs (the values are measured by others and change), times the grid's dx."""

import json
import shutil
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import pytest

from benchmarks import _tradeoff_report, tradeoff
from benchmarks._penetration import penetration_bound
from benchmarks._tradeoff_report import infeasible, winners
from bfemp.steppers import stepper_class
from bfemp.steppers.capabilities import Capabilities

RECORD = Path(__file__).resolve().parents[2] / "benchmarks" / "records" / "tradeoff.json"


def _point(strategy: str, label: str, error: float, wall: float, depth, bound, **extra) -> dict:
    return {
        "id": f"rings/{strategy}/{label}",
        "scene": "rings",
        "strategy": strategy,
        "label": label,
        "role": "base" if label == "base" else "sweep",
        "knob": None if label == "base" else label.split("=")[0],
        "value": None,
        "sweeps": [],
        "finer": {},
        "is_reference": False,
        "settings": {"strategy": strategy},
        "error": error,
        "wall_s": wall,
        "cpu_s": wall,
        "iterations": 0,
        "peak_memory_mb": 100.0,
        "failure": None,
        "max_penetration_m": depth,
        "penetration_bound_m": bound,
        **extra,
    }


def _table() -> list[dict]:
    return [
        # the cheapest point at the best error, 3 mm deep against augury's 1 cell of 1 mm
        _point("augury", "base", 1e-3, 0.5, 3e-3, 1e-3)
        | {"penetration_bound_cells": 1.0, "penetration_grid_dx_m": 1e-3},
        # feasible: barrier, nothing inside (bound 0), the best error at a higher cost
        _point("barrier", "base", 1e-3, 2.0, 0.0, 0.0),
        # 1 nm inside against barrier's bound of 0: infeasible, though cheaper than its base
        _point("barrier", "dt=2e-2", 1e-3, 1.0, 1e-9, 0.0),
        # lr within its bound (equal to it is within): feasible, coarse and cheap
        _point("lr", "base", 1e-2, 0.8, 1e-3, 1e-3),
        # no measurement (a record from before it): not judged
        _point("two_stage", "base", 5e-2, 0.7, None, None),
    ]


def test_the_bound_is_strict_and_a_point_without_numbers_is_not_judged():
    table = _table()
    assert [infeasible(p) for p in table] == [True, False, True, False, False]
    # a finished record carries the flag; the measurement's own keys give it (_finish)
    done = tradeoff._finish(
        {"scene": "slope", "is_reference": False},
        {
            "metrics": {
                "accel_rel_error": 0.1,
                "max_penetration_m": 2e-3,
                "penetration_bound_m": 0.0,
            }
        },
        None,
    )
    assert done["infeasible"] and done["max_penetration_m"] == 2e-3
    assert done["penetration_bound_m"] == 0.0 and done["penetration_grid_dx_m"] is None
    clean = tradeoff._finish({"scene": "slope"}, {"metrics": {"accel_rel_error": 0.1}}, None)
    assert not clean["infeasible"] and clean["max_penetration_m"] is None


def test_an_infeasible_point_is_never_a_winner_nor_on_a_front_even_cheapest_at_the_best_error():
    table = _table()
    out = tradeoff.analyse(table, ["rings"])
    by_id = {p["id"]: p for p in table}
    assert out["infeasible"]["rings"] == ["rings/augury/base", "rings/barrier/dt=2e-2"]
    # the front: lr (0.8 s, 1e-2) and barrier's base (2 s, 1e-3); two_stage (0.7 s, 5e-2) too
    front = sorted(pid for pid, p in by_id.items() if p["pareto"])
    assert front == ["rings/barrier/base", "rings/lr/base", "rings/two_stage/base"]
    assert not by_id["rings/augury/base"]["strategy_pareto"]  # nor on its strategy's own front
    ranges = out["winners"]["rings"]
    assert all(r["winner"] != "augury" and r["runner_up"] != "augury" for r in ranges)
    # the feasible control wins the best error, at its own cost, not the infeasible 1 s point
    assert (ranges[-1]["error_from"], ranges[-1]["winner"], ranges[-1]["cost_s"]) == (
        1e-3,
        "barrier",
        2.0,
    )
    assert [r["winner"] for r in ranges] == ["two_stage", "lr", "barrier"]
    # without the penetration numbers the same table has augury as the winner everywhere
    plain = [{k: v for k, v in p.items() if k != "max_penetration_m"} for p in _table()]
    assert [r["winner"] for r in winners(plain)] == ["augury"]


def test_an_infeasible_point_is_named_in_the_report_and_drawn_as_a_cross(tmp_path, monkeypatch):
    """The quick record's cheapest rings point at the coarsest targets (the front point of the
    winner at the top error range) made infeasible: the report names it with its depth and
    bound and the winner changes; the plot draws it with a legend entry."""
    record = tmp_path / "tradeoff.json"
    shutil.copy(RECORD, record)
    data = json.loads(record.read_text())
    top = data["winners"]["rings"][0]
    strategy = top["winner"]
    target = next(
        p
        for p in data["points"]
        if p["scene"] == "rings"
        and p["strategy"] == strategy
        and p["pareto"]
        and p[data["cost"]] == top["cost_s"]
    )
    label = target["label"]
    target.update(
        max_penetration_m=0.0123,
        penetration_bound_m=0.005,
        penetration_bound_cells=0.5,
        penetration_grid_dx_m=0.01,
        penetration_mpm_grid_dx_m=0.01,
        penetration_contact_grid_dx_m=0.02,
    )
    record.write_text(json.dumps(data))
    figures = []

    class Keep(_tradeoff_report.Figure):
        def savefig(self, *args, **kwargs):
            figures.append(self)
            return super().savefig(*args, **kwargs)

    monkeypatch.setattr(_tradeoff_report, "Figure", Keep)
    out = tradeoff.rerender(record)
    assert target["id"] in out["infeasible"]["rings"]
    points = {p["id"]: p for p in out["points"]}
    assert points[target["id"]]["infeasible"] and not points[target["id"]]["pareto"]
    # the winners are those of the scene's feasible points
    others = [
        p
        for p in out["points"]
        if p["scene"] == "rings" and p["id"] not in out["infeasible"]["rings"]
    ]
    assert out["winners"]["rings"] == winners(others, out["cost"])
    assert out["winners"]["rings"] != data["winners"]["rings"]
    md = record.with_suffix(".md").read_text()
    rings = md.split("\n## rings")[1].split("\n## ")[0]
    named = next(
        line for line in rings.splitlines() if f"**Infeasible**: rings, **{strategy}**" in line
    )
    assert f"rings, **{strategy}** at {label}" in named
    assert "went 0.0123 m inside a FEM body, beyond its bound of 0.005 m" in named
    assert "(0.5 cell(s) of the 0.01 m MPM grid)" in named
    front = next(line for line in rings.splitlines() if line.startswith("Non-dominated front"))
    assert f"{strategy}/{label} " not in front
    assert f"| {strategy} | {label} (infeasible) |" in rings and "0.0123 / 0.005" in rings
    # a scene without FEM bodies has nothing to judge, and says so
    lrc = md.split("\n## lr_compression")[1].split("\n## ")[0]
    assert "No point on lr_compression has both a penetration depth and a bound" in lrc
    # the rings figure: a cross for the point, a legend entry for infeasible points
    rings_fig = next(f for f in figures if f.axes[0].get_title().startswith("rings"))
    ax = rings_fig.axes[0]
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert any(text.startswith("infeasible") for text in legend), legend
    crosses = [
        line
        for line in ax.get_lines()
        if line.get_marker() == "X" and list(line.get_xdata()) == [target[out["cost"]]]
    ]
    assert len(crosses) == 1


def _stub(cls: type, **attrs) -> object:
    stepper = object.__new__(cls)
    for name, value in attrs.items():
        setattr(stepper, name, value)
    return stepper


def test_the_bound_is_read_from_the_stepper_class_when_the_point_runs(monkeypatch):
    augury, lr = stepper_class("augury"), stepper_class("lr")
    grid = SimpleNamespace(grid=SimpleNamespace(dx=0.02))
    # whatever the declared values are now, the bound follows them: cells x the grid's dx
    for cls, cells in ((augury, 0.75), (lr, 2.5)):
        monkeypatch.setattr(
            cls, "capabilities", replace(cls.capabilities, penetration_bound_cells=cells)
        )
    # cells of the MPM grid (the point's dx) where the scene has one, both spacings recorded
    a = penetration_bound(_stub(augury, grid_dx=0.004, model=grid))
    assert a == {
        "penetration_bound_cells": 0.75,
        "penetration_mpm_grid_dx_m": 0.02,
        "penetration_contact_grid_dx_m": 0.004,
        "penetration_grid_dx_m": 0.02,
        "penetration_bound_m": pytest.approx(0.015),
    }
    b = penetration_bound(_stub(lr, model=grid))
    assert b["penetration_bound_m"] == pytest.approx(0.05) and b["penetration_grid_dx_m"] == 0.02
    # augury on FEM bodies alone (augury_blocks): cells of its own contact grid
    fem_only = penetration_bound(_stub(augury, grid_dx=0.004, model=SimpleNamespace(grid=None)))
    assert fem_only["penetration_bound_m"] == pytest.approx(0.003)
    assert fem_only["penetration_grid_dx_m"] == 0.004
    # barrier and two_stage: 0 m on any grid; single_field: no bound
    for name in ("barrier", "two_stage"):
        assert (
            penetration_bound(_stub(stepper_class(name), model=grid))["penetration_bound_m"] == 0.0
        )
    none = penetration_bound(_stub(stepper_class("single_field"), model=grid))
    assert none["penetration_bound_m"] is None and none["penetration_bound_cells"] is None

    class NoGrid:  # a bound in cells with no grid to count them on: none in metres
        capabilities = Capabilities(
            pairs={"mpm-fem": "contact"},
            friction=False,
            needs_contact_settings=False,
            penetration_bound_cells=1.0,
            penetration_note="test",
        )

    assert (
        penetration_bound(_stub(NoGrid, model=SimpleNamespace(grid=None)))["penetration_bound_m"]
        is None
    )


def test_a_point_run_records_its_depth_and_the_bound_of_its_strategy_class(monkeypatch):
    """A few steps of the slope by augury in this process (the trade study's warm-up length):
    the point's metrics carry the column's largest value and the bound of the class as it is
    when the point runs, counted on the point's MPM grid (its dx), augury's contact grid
    recorded beside it."""
    from benchmarks import _tradeoff_runs

    cls = stepper_class("augury")
    monkeypatch.setattr(
        cls, "capabilities", replace(cls.capabilities, penetration_bound_cells=0.375)
    )
    settings = tradeoff.strategy_base("slope", "augury", "quick")
    settings |= tradeoff.SCENES["slope"]["warmup"]
    metrics = _tradeoff_runs.run_point({"scene": "slope", **settings})
    assert metrics["failure"] is None
    depth = metrics["max_penetration_m"]
    assert depth is not None and depth >= 0.0
    assert metrics["penetration_bound_cells"] == 0.375
    assert metrics["penetration_grid_dx_m"] == metrics["penetration_mpm_grid_dx_m"]
    assert metrics["penetration_grid_dx_m"] == pytest.approx(settings["dx"])
    assert metrics["penetration_bound_m"] == pytest.approx(0.375 * settings["dx"])
    assert metrics["penetration_contact_grid_dx_m"] > 0.0
