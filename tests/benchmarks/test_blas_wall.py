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


def test_rings_transfers_runs_rings_full_without_its_compared_integrator(tmp_path, monkeypatch):
    seen = []
    real_run = blas_wall.subprocess.run  # the module is shared: git in environment() uses it

    def fake_run(command, **kwargs):
        if "benchmarks" not in command:
            return real_run(command, **kwargs)
        seen.append(command)
        raise blas_wall.subprocess.TimeoutExpired(command, kwargs["timeout"])

    monkeypatch.setattr(blas_wall.subprocess, "run", fake_run)
    summary = blas_wall.run("rings_transfers", tmp_path, timeout_s=1.0, blas="optimised")
    row = summary["runs"]["rings"]
    assert row["options"] == ["--no-compare"] and "speedup" not in row
    assert "timed out" in row["optimised"]["error"] and "reference" not in row
    assert summary["blas"] == "optimised" and len(seen) == 1
    assert seen[0][2:6] == ["benchmarks", "rings", "--full", "--no-compare"]
    with pytest.raises(ValueError, match="blas must be one of"):
        blas_wall.run("rings_transfers", tmp_path, blas="mkl")


def test_rings_no_compare_option_reaches_run():
    from benchmarks import rings
    from benchmarks.__main__ import _parser

    parser = _parser()
    rings.BENCHMARK.arguments(parser)
    assert parser.parse_args(["rings", "--full"]).compare is True
    args = parser.parse_args(["rings", "--full", "--no-compare"])
    assert args.compare is False and args.mode == "full"


def test_a_half_merged_from_another_record_gives_the_speedup(tmp_path, monkeypatch):
    def fake_child(name, mode, options, folder, env, timeout):
        return {"wall_s": 10.0, "benchmark_wall_s": 9.0, "blas": "openblas", "run_wall_s": {}}

    monkeypatch.setattr(blas_wall, "_run_child", fake_child)
    other = tmp_path / "reference.json"
    half = {"wall_s": 25.0, "benchmark_wall_s": 24.0, "blas": "reference", "run_wall_s": {}}
    other.write_text(
        json.dumps(
            {
                "benchmark": "blas_wall",
                "mode": "rings_transfers",
                "blas": "reference",
                "runs": {"rings": {"reference": half}},
                "environment": {"commit": "abc", "load_average_1min": 0.1},
            }
        )
    )
    summary = blas_wall.run("rings_transfers", tmp_path / "out", blas="optimised", merge=other)
    row = summary["runs"]["rings"]
    assert row["reference"]["merged"] is True and "merged" not in row["optimised"]
    assert row["speedup"] == pytest.approx(2.5) and row["benchmark_speedup"] == pytest.approx(
        24 / 9
    )
    assert summary["merged_from"]["commit"] == "abc"
    with pytest.raises(ValueError, match="not a blas_wall record of mode 'hertz'"):
        blas_wall.run("hertz", tmp_path / "out", blas="optimised", merge=other)
