"""blas_wall in quick mode: one benchmark runs as a child on each BLAS, and each child's record
names the BLAS it ran on (so the before / after wall times compare what they claim to)."""

import json

import pytest

from benchmarks import blas_wall
from benchmarks._blas_switch import reference_blas_env
from solvers.blas import cholmod_blas


def test_quick_runs_the_benchmark_on_both_blas(tmp_path):
    summary = blas_wall.run("quick", tmp_path)
    data = json.loads((tmp_path / "blas_wall.json").read_text())
    assert data["runs"] == json.loads(json.dumps(summary["runs"]))
    row = data["runs"]["slope"]
    opt = row["optimised"]
    assert "error" not in opt, opt
    assert opt["blas"] == cholmod_blas().name and opt["wall_s"] > 0.0
    assert opt["benchmark_wall_s"] > 0.0 and opt["wall_s"] > opt["benchmark_wall_s"]
    if reference_blas_env() is None:
        assert "not installed" in row["reference"]["error"]
        return
    ref = row["reference"]
    assert "error" not in ref, ref
    assert ref["blas"] == "reference"  # the loader switch took: the child names its BLAS
    assert row["speedup"] == pytest.approx(ref["wall_s"] / opt["wall_s"])


def test_unknown_mode_is_named():
    with pytest.raises(ValueError, match="mode must be one of"):
        blas_wall.run("partial", "unused")
