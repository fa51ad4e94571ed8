"""A buckling case longer than a session runs as budgeted segments that resume from the case's
checkpoint (``benchmarks._case_checkpoint``); the segments together equal one uninterrupted run."""

import json

import numpy as np
import pytest

from benchmarks import buckling
from benchmarks.__main__ import main
from benchmarks._case_checkpoint import PROGRESS_FILE, CaseCheckpoint
from bfemp.errors import SceneError
from bfemp.validation import validate_initial

#: the quick discretisation pressed 0.3 m (6 steps): the rings meet at the first step
CFG = dict(buckling.MODES["quick"], u_end=0.3)
MU = 0.2  # with friction, so that the lagged-friction loop is resumed too


@pytest.fixture(scope="module")
def uninterrupted():
    return buckling._run_one(CFG, MU)


@pytest.fixture(scope="module")
def segmented(tmp_path_factory):
    """The same case cut after every step (budget 0) and resumed until it ends."""
    folder = tmp_path_factory.mktemp("case")
    cuts = []
    for _ in range(10):
        case = buckling._run_one(CFG, MU, budget_s=0.0, checkpoint=CaseCheckpoint(folder))
        cuts.append(case["cut_at_budget_s"])
        if case["cut_at_budget_s"] is None:
            break
    return case, cuts, folder


def test_segments_resume_to_the_uninterrupted_case_bit_for_bit(uninterrupted, segmented):
    case, cuts, _ = segmented
    assert cuts == [0.0] * 5 + [None]  # one step per segment, the sixth ends the case
    assert len(case["segments_s"]) == 6
    assert case["wall_s"] == pytest.approx(sum(case["segments_s"]))
    assert uninterrupted["min_distance_m"] is not None  # the rings are in contact
    for key in ("steps", "u_end_m", "detachment_end_m", "newton_iterations", "min_distance_m"):
        assert case[key] == uninterrupted[key], key
    assert case["series"] == uninterrupted["series"]
    for key in ("final_mpm_x", "final_fem_x"):
        np.testing.assert_array_equal(case[key], uninterrupted[key])


def test_a_finished_case_resumes_without_stepping(segmented):
    case, _, folder = segmented
    again = buckling._run_one(CFG, MU, checkpoint=CaseCheckpoint(folder))
    assert again["segments_s"] == case["segments_s"]
    assert again["series"] == case["series"]


def test_a_checkpoint_of_another_scene_is_refused(segmented):
    _, _, folder = segmented
    with pytest.raises(SceneError, match="another model"):
        buckling._run_one(CFG, 0.0, checkpoint=CaseCheckpoint(folder))


def test_progress_of_another_step_than_the_checkpoint_is_named(segmented, tmp_path):
    _, _, folder = segmented
    copy = tmp_path / "case"
    copy.mkdir()
    for path in folder.iterdir():
        (copy / path.name).write_bytes(path.read_bytes())
    progress = json.loads((copy / PROGRESS_FILE).read_text())
    (copy / PROGRESS_FILE).write_text(json.dumps({**progress, "step": 3}))
    with pytest.raises(ValueError, match="progress.json is of step 3 but the checkpoint of step 6"):
        buckling._run_one(CFG, MU, checkpoint=CaseCheckpoint(copy))


def test_the_command_line_runs_a_budgeted_resumable_case_and_goes_on(tmp_path, capsys):
    args = ["buckling", "--quick", "--mu", "0", "--budget-s", "0", "--resumable"]
    assert main([*args, "--out", str(tmp_path)]) == 0
    first = json.loads((tmp_path / "buckling_quick.json").read_text())
    assert first["cut_cases"] == [0.0] and first["cases"][0]["steps"] == 1
    assert (tmp_path / "cases" / "quick_mu0" / "checkpoint.npz").is_file()
    assert main([*args, "--out", str(tmp_path)]) == 0
    second = json.loads((tmp_path / "buckling_quick.json").read_text())
    assert second["cases"][0]["steps"] == 2
    assert len(second["cases"][0]["segments_s"]) == 2
    assert "buckling: wrote" in capsys.readouterr().out


def test_a_negative_budget_is_a_usage_error(tmp_path, capsys):
    with pytest.raises(SystemExit) as stop:
        main(["buckling", "--quick", "--budget-s", "-1", "--out", str(tmp_path)])
    assert stop.value.code == 2
    assert "--budget-s must be >= 0" in capsys.readouterr().err


def test_plate_full_is_the_full_discretisation_pressed_by_the_papers_plate():
    cfg, full = buckling.MODES["plate_full"], buckling.MODES["full"]
    assert {k: cfg[k] for k in full if k != "max_newton"} == {
        k: v for k, v in full.items() if k != "max_newton"
    }
    assert (
        cfg["pusher"] == "plate"
        and cfg["max_newton"] == buckling.MODES["plate_partial"]["max_newton"]
    )


@pytest.mark.parametrize("mode", ["plate_quick", "plate_partial", "plate_full"])
def test_the_plate_starts_clear_of_the_crowns_barrier(mode):
    """The plate is placed where the scene accepts it at the start (no node within d-hat of
    another body): the full mesh has no node on the crown's top, so half d-hat above the arc
    put its highest nodes 0.83 mm from the plate, inside d-hat = 1 mm, and refused the run."""
    model = buckling._scene(buckling.MODES[mode], 0.5).build()
    validate_initial(model)
    outer, plate = (b for b in model.fem_bodies)
    gap = model.fem_X[plate.nodes, 1].min() - model.fem_X[outer.nodes, 1].max()
    assert buckling.DHAT < gap < 2.5 * buckling.DHAT, gap
