"""Regression references (bfemp.regress, ``bfemp regress``): the shipped references reproduce,
and a drifted one is caught with the quantity and step named."""

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from bfemp import regress
from bfemp.cli import main
from bfemp.testing import assert_reference

pytest_plugins = ["pytester"]

REFERENCES = Path(__file__).resolve().parents[2] / "references"
NAMES = [r.name for r in regress.find_references(REFERENCES)]
FAST = "single_field_2d"  # explicit, ~0.3 s


def _copy(name, dest):
    for suffix in (".toml", ".npz", ".json"):
        shutil.copy(REFERENCES / f"{name}{suffix}", dest / f"{name}{suffix}")
    return regress.load_reference(dest / f"{name}.toml")


def _perturb(ref, quantity, index, factor):
    """Move one stored entry of ``quantity`` at stored index ``index`` by ``factor`` x its
    tolerance; returns the step number perturbed."""
    with np.load(ref.npz_path) as z:
        data = {k: np.array(z[k]) for k in z.files}
    stored = regress.read_trajectory(ref)
    strategy = stored.settings["strategy"]
    scale = float(np.max(np.abs(data[quantity])))
    allowed = regress.tolerance_of(ref, strategy, quantity).allowed(scale)
    data[quantity].reshape(len(data[quantity]), -1)[index, 0] += factor * allowed  # a view
    np.savez_compressed(ref.npz_path, **data)
    return int(data["step"][index])


def test_the_reference_set_covers_every_strategy_both_dimensions_and_fem_fem_contact():
    strategies, dims, fem_fem, friction = set(), set(), False, False
    for name in NAMES:
        meta = json.loads((REFERENCES / f"{name}.json").read_text())
        strategies.add(meta["settings"]["strategy"])
        text = (REFERENCES / f"{name}.toml").read_text()
        dims.add(int(re.search(r"^dim = (\d)", text, re.M).group(1)))
        fem_fem |= text.count("[[fem]]") >= 2 and "[[mpm]]" not in text and "[contact]" in text
        friction |= meta["settings"]["strategy"] == "barrier" and bool(
            re.search(r"^mu = 0\.[1-9]", text, re.M)
        )
    assert strategies == {"barrier", "single_field", "augury", "two_stage", "lr"}
    assert dims == {2, 3} and fem_fem and friction
    total = sum((REFERENCES / f"{n}.npz").stat().st_size for n in NAMES)
    assert total < 2_000_000  # bytes: the set ships with the repository


@pytest.mark.parametrize("name", NAMES)
def test_stored_reference_reproduces(name):
    report = assert_reference(REFERENCES / f"{name}.toml")
    assert report.ok and len(report.drifts) >= 4  # t and at least 3 physical quantities


def test_perturbed_reference_is_caught_naming_quantity_and_step(tmp_path, capsys):
    ref = _copy(FAST, tmp_path)
    assert main(["regress", FAST, "--dir", str(tmp_path)]) == 0  # untouched copy passes
    assert f"{FAST}: ok" in capsys.readouterr().out
    step = _perturb(ref, "mpm_v", 4, 10.0)
    assert main(["regress", FAST, "--dir", str(tmp_path)]) == 1
    out = capsys.readouterr()
    assert "DRIFT" in out.out and f"drift in {FAST}" in out.err
    (row,) = [line.split() for line in out.out.splitlines() if line.strip().startswith("mpm_v")]
    assert int(row[3]) == step and float(row[1]) > float(row[2])  # first step; dev > tol
    # within tolerance (half of it) the same copy passes again
    _copy(FAST, tmp_path)
    _perturb(ref, "mpm_v", 4, 0.5)
    assert main(["regress", FAST, "--dir", str(tmp_path)]) == 0


def test_a_one_percent_stiffer_material_is_a_drift(tmp_path):
    ref = _copy(FAST, tmp_path)
    text = ref.scene_file.read_text()
    ref.scene_file.write_text(text.replace('E = "50 kPa"', 'E = "50.5 kPa"'))
    report = regress.check(ref)
    assert not report.ok
    drifted = {d.quantity for d in report.drifted}
    assert {"mpm_v", "energy_elastic"} <= drifted and "t" not in drifted
    assert all(d.first_step > 0 for d in report.drifted)  # step 0 is the same initial state
    assert any("changed since the reference was written" in n for n in report.notes)


def test_update_rewrites_and_says_what_changed(tmp_path, capsys):
    ref = _copy(FAST, tmp_path)
    # This machine's own trajectory first: another CPU or numpy/numba build reproduces the
    # shipped one within tolerance, not bit for bit, and `changes` reports any difference.
    regress.update(ref)
    with np.load(ref.npz_path) as z:
        local = {k: np.array(z[k]) for k in z.files}
    _perturb(ref, "mpm_x", 3, 100.0)
    assert main(["regress", FAST, "--dir", str(tmp_path), "--update"]) == 0
    out = capsys.readouterr().out
    assert f"{FAST}: written" in out and "mpm_x" in out and "mpm_v" not in out
    meta = json.loads(ref.meta_path.read_text())
    assert set(meta["changes"]) == {"mpm_x"} and meta["changes"]["mpm_x"] > 0
    assert meta["bfemp_version"] and meta["settings"]["strategy"] == "single_field"
    assert meta["quantities"]["mpm_x"]["rtol"] == regress.DEFAULT_TOLERANCES["explicit"].rtol
    assert main(["regress", FAST, "--dir", str(tmp_path)]) == 0
    before = ref.meta_path.read_text()
    capsys.readouterr()
    assert main(["regress", FAST, "--dir", str(tmp_path), "--update"]) == 0
    assert "unchanged, not rewritten" in capsys.readouterr().out
    assert ref.meta_path.read_text() == before  # a no-op update leaves the files alone
    # a changed tolerance is a change of the reference, not of its trajectory
    text = ref.scene_file.read_text()
    assert text.rstrip().endswith("every = 6")  # the last line of [regress]
    ref.scene_file.write_text(text + "tolerances = { mpm_x = { atol = 1e-6, rtol = 0.0 } }\n")
    npz = ref.npz_path.read_bytes()
    assert main(["regress", FAST, "--dir", str(tmp_path), "--update"]) == 0
    out = capsys.readouterr().out
    assert "scene file changed" in out and "tolerances changed" in out and "mpm" not in out
    assert ref.npz_path.read_bytes() == npz  # the trajectory file is kept
    assert json.loads(ref.meta_path.read_text())["quantities"]["mpm_x"]["atol"] == 1e-6
    # the restored trajectory equals this machine's unperturbed one exactly
    with np.load(ref.npz_path) as a:
        assert set(a.files) == set(local)
        assert all(np.array_equal(a[k], local[k], equal_nan=True) for k in local)


def test_unknown_name_and_missing_trajectory_are_clear_errors(tmp_path, capsys):
    assert main(["regress", "no_such_scene", "--dir", str(REFERENCES)]) == 2
    err = capsys.readouterr().err
    assert "no_such_scene" in err and all(n in err for n in NAMES)
    ref = _copy(FAST, tmp_path)
    ref.npz_path.unlink()
    assert main(["regress", FAST, "--dir", str(tmp_path)]) == 2
    assert "--update" in capsys.readouterr().err


def test_regress_table_errors_name_the_field(tmp_path):
    path = tmp_path / "bad.toml"
    text = (REFERENCES / f"{FAST}.toml").read_text()
    path.write_text(text.replace("steps = 60", "steps = 0"))
    with pytest.raises(ValueError, match=r"regress\.steps"):
        regress.load_reference(path)
    path.write_text(text.replace("[regress]\n", '[regress]\nquantities = ["mpm_speed"]\n'))
    with pytest.raises(ValueError, match=r"unknown quantity 'mpm_speed'.*mpm_x"):
        regress.run_reference(regress.load_reference(path))
    path.write_text(
        text.replace("[regress]\n", '[regress]\nquantities = ["mpm_x", "momentum_y"]\n')
    )
    traj = regress.run_reference(regress.load_reference(path))
    assert set(traj.data) == {"t", "mpm_x", "momentum_y"} and traj.data["mpm_x"].shape[0] == 11


def test_compare_nan_and_shape_rules():
    ref = regress.Reference(name="r", scene_file=Path("r.toml"), steps=2, every=1)
    steps = np.arange(3)
    stored = regress.Trajectory(
        steps, {"d": np.array([np.nan, 1.0, 1.0]), "x": np.zeros((3, 2))}, {"strategy": "lr"}
    )
    same = regress.Trajectory(steps, {"d": np.array([np.nan, 1.0, 1.0]), "x": np.zeros((3, 2))})
    assert regress.compare(same, stored, ref).ok  # NaN matches NaN
    nan_late = regress.Trajectory(
        steps, {"d": np.array([np.nan, 1.0, np.nan]), "x": np.zeros((3, 2))}
    )
    (drift,) = regress.compare(nan_late, stored, ref).drifted
    assert drift.quantity == "d" and drift.first_step == 2 and drift.max_deviation == np.inf
    wrong = regress.Trajectory(steps, {"d": stored.data["d"], "x": np.zeros((3, 3))})
    (drift,) = regress.compare(wrong, stored, ref).drifted
    assert drift.quantity == "x" and "shape" in drift.note


def test_pytest_plugin_fixture_fails_a_drifted_reference(pytester, tmp_path):
    ref = _copy(FAST, tmp_path)
    pytester.makeconftest('pytest_plugins = ["bfemp.pytest_plugin"]')
    pytester.makepyfile(
        f"""
        def test_scene(bfemp_reference):
            bfemp_reference({str(ref.scene_file)!r})
        """
    )
    pytester.runpytest_inprocess().assert_outcomes(passed=1)
    _perturb(ref, "energy_elastic", 2, 10.0)
    result = pytester.runpytest_inprocess()
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*energy_elastic*"])
    pytester.runpytest_inprocess("--bfemp-update-references").assert_outcomes(passed=1)
    pytester.runpytest_inprocess().assert_outcomes(passed=1)
