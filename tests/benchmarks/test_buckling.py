"""Buckling under friction, quick mode (paper section 6.6): the inner MPM ring pulls away from the
outer FEM ring as the crown is pressed down, less the more friction holds the rings together."""

import json

import numpy as np
import pytest

from benchmarks import buckling
from tests.benchmarks._records import check_written, record_fixture

#: started first (tests/conftest.py): one of the suite's longest files
pytestmark = pytest.mark.slow

result = record_fixture("buckling")


def test_writes_json_and_plot(result):
    data = check_written(
        result, "buckling_quick", "detachment_end_m u_buckle_m wall_s peak_memory_mb parameters"
    )
    assert [case["mu"] for case in data["cases"]] == list(buckling.MUS)


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


@pytest.mark.parametrize("plate_mu", [buckling.PLATE_MU, 0.0])
def test_the_papers_plate_holds_the_crown_only_with_its_own_friction(plate_mu, monkeypatch):
    """plate_quick presses with a FEM plate at mu = 10 (scene.set_friction) while the rings
    rub at 0: the crown nodes the plate touches move with it (measured: 0 m sideways); at plate
    mu = 0 (the control) they spread as the crown flattens (measured: 6 mm)."""
    import bfemp

    monkeypatch.setattr(buckling, "PLATE_MU", plate_mu)
    cfg = buckling.MODES["plate_quick"]
    sim = bfemp.Simulation(
        buckling._scene(cfg, 0.0), integrator="backward_euler", dt=cfg["dt"], tol=buckling.TOL
    )
    ring, plate = sim.model.fem_bodies
    x0 = sim.state.fem_x[ring.nodes].copy()
    for _ in range(4):  # 0.2 m of plate travel
        report = sim.step()
    assert report.contact_pairs > 0
    x = sim.state.fem_x[ring.nodes]
    bottom = sim.state.fem_x[plate.nodes][:, 1].min()
    touching = (x[:, 1] > bottom - 2.0 * buckling.DHAT) & (np.abs(x0[:, 0]) < 0.5)
    assert touching.sum() >= 2
    assert np.all(x0[touching, 1] - x[touching, 1] > 0.15)  # pushed down with the plate
    spread = np.abs(x[touching, 0] - x0[touching, 0]).max()
    if plate_mu > 0.0:
        assert spread < 1e-4, spread
    else:
        assert spread > 1e-3, spread


def test_records_of_cases_run_apart_merge_into_the_record_of_one_run(result, tmp_path):
    _, data, out = result
    shapes = np.load(out / "buckling_quick_final.npz")
    assert sorted(shapes.files) == sorted(
        f"{kind}_{mu:g}" for kind in ("mpm", "fem") for mu in buckling.MUS
    )
    # one record per mu, in reverse order, each with the shapes file beside it
    paths = []
    for k, case in enumerate(reversed(data["cases"])):
        folder = tmp_path / f"part{k}"
        folder.mkdir()
        (folder / "buckling.json").write_text(json.dumps({**data, "cases": [case]}))
        (folder / "buckling_final.npz").write_bytes((out / "buckling_quick_final.npz").read_bytes())
        paths.append(folder / "buckling.json")
    merged = buckling.merge(paths, tmp_path / "merged")
    assert [c["mu"] for c in merged["cases"]] == list(buckling.MUS)
    assert merged["u_buckle_m"] == data["u_buckle_m"]
    assert merged["detachment_end_m"] == data["detachment_end_m"]
    assert merged["ordered_at_end"] == data["ordered_at_end"]
    again = np.load(tmp_path / "merged" / "buckling_final.npz")
    for key in shapes.files:
        np.testing.assert_array_equal(again[key], shapes[key])
    assert (tmp_path / "merged" / "buckling.png").stat().st_size > 0


def test_a_budget_cuts_a_case_and_the_record_says_so(tmp_path):
    """A case past its wall budget stops after the step it is in; the record names the cut and
    does not claim the ordering of cases that did not reach the end."""
    summary = buckling.run("quick", tmp_path, mus=(0.0,), budget_s=0.0)
    case = summary["cases"][0]
    assert case["cut_at_budget_s"] == 0.0
    assert case["steps"] == 1
    assert case["u_end_m"] < summary["parameters"]["u_end"]
    assert summary["cut_cases"] == [0.0]
    assert summary["ordered_at_end"] is False


def test_plate_partial_is_the_partial_discretisation_pressed_by_the_papers_plate():
    """The plate_partial record's mode: partial's grid, mesh, dt and travel, with the FEM plate
    (a second FEM body above the crown) instead of the scripted cap."""
    cfg = buckling.MODES["plate_partial"]
    partial = buckling.MODES["partial"]
    assert {k: cfg[k] for k in partial} == partial and cfg["pusher"] == "plate"
    names = [b.name for b in buckling._scene(cfg, 0.5).build().fem_bodies]
    assert names == ["outer_ring", "plate"], names
    assert [b.name for b in buckling._scene(partial, 0.5).build().fem_bodies] == ["outer_ring"]
