"""The benchmark runner: one registry, the record it writes, and ``verify``'s comparison."""

import ast
import json
import math
from pathlib import Path

import pytest

from benchmarks import runner
from benchmarks.__main__ import BENCHMARKS, main
from benchmarks.runner import Benchmark, differences, verify


def _fake(calls):
    def measure(mode, cfg, scale=1.0):
        calls.append((mode, dict(cfg), scale))
        return {"value": cfg["n"] * scale, "wall_s": 1.5}

    def plot(payload, png):
        png.write_bytes(b"png")

    return Benchmark("fake", "A fake.\n\nMore.", {"quick": {"n": 2}}, measure, plot=plot)


def test_the_runner_checks_the_mode_and_writes_the_record_and_plot(tmp_path):
    calls = []
    bench = _fake(calls)
    assert bench.title == "A fake."
    with pytest.raises(ValueError, match=r"mode must be one of \['quick'\], got 'full'"):
        bench.run("full", tmp_path)
    assert calls == []  # nothing measured for an unknown mode
    summary = bench.run("quick", tmp_path, scale=3.0)
    assert calls == [("quick", {"n": 2}, 3.0)]
    record = json.loads((tmp_path / "fake.json").read_text())
    assert summary["json"] == str(tmp_path / "fake.json") and summary["png"].endswith("fake.png")
    assert record["benchmark"] == "fake" and record["mode"] == "quick" and record["value"] == 6.0
    assert record["wall_s"] == 1.5  # the measurement's own time is kept
    assert record["peak_memory_mb"] > 0 and "commit" in record["environment"]


def test_every_benchmark_is_registered_and_the_merged_names_stay():
    for name in ("rings", "slope", "hertz", "tradeoff", "scenes", "two_stage_gap"):
        assert name in BENCHMARKS, name
    for old in ("augury_scenes", "lr_scenes", "two_stage_rings", "two_stage_slope"):
        assert BENCHMARKS[old] == "benchmarks.scenes", old
    scenes = runner.catalogue()["scenes"]
    assert scenes.stem("quick", {"strategy": "augury"}) == "augury_scenes_quick"
    assert scenes.stem("quick", {"strategy": "two_stage", "scene": "slope"}) == "two_stage_slope"


def test_a_name_registered_twice_is_refused():
    bench = _fake([])
    runner.register(bench)
    try:
        with pytest.raises(ValueError, match="'fake' registered twice"):
            runner.register(_fake([]))
    finally:
        del runner.REGISTRY["fake"]


def test_differences_skip_timings_and_find_everything_else():
    old = {
        "wall_s": 1.0,
        "a": {"x": [1.0, 2.0], "dt_s": 0.1, "phase_s": {"solve": 3.0}},
        "environment": {"commit": "abc"},
        "nan": math.nan,
    }
    new = {
        "wall_s": 9.0,
        "a": {"x": [1.0, 2.0], "dt_s": 0.1, "phase_s": {"solve": 4.0}},
        "environment": {"commit": "def"},
        "nan": math.nan,
    }
    assert differences(old, new) == []
    new["a"]["x"][1] = 2.0000000000000004  # one ulp: not the same record
    new["a"]["dt_s"] = 0.2  # a physical time, not a timing
    new["extra"] = 1
    assert differences(old, new) == [
        "/a/dt_s: 0.1, now 0.2",
        "/a/x[1]: 2.0, now 2.0000000000000004",
        "/extra: only in the new record",
    ]


def test_verify_names_an_unknown_benchmark(capsys):
    with pytest.raises(SystemExit):
        main(["verify", "no_such_benchmark"])
    assert "invalid choice: 'no_such_benchmark'" in capsys.readouterr().err


def test_verify_refuses_a_committed_record_of_another_mode(tmp_path):
    """hertz's committed record is its full run: a quick rerun is not compared with it."""
    (tmp_path / "hertz.json").write_text(json.dumps({"mode": "full"}))
    with pytest.raises(ValueError, match="hertz.json is a full run, not quick"):
        verify("hertz", "quick", records=tmp_path)


def test_figure_draws_without_a_display(tmp_path):
    from benchmarks.common import figure

    fig, (left, right) = figure((4.0, 3.0), 1, 2, layout="constrained")
    left.plot([0.0, 1.0], [1.0, 0.0])
    right.bar([0, 1], [2.0, 3.0])
    fig.savefig(tmp_path / "f.png", dpi=50)
    assert (tmp_path / "f.png").stat().st_size > 1_000
    assert fig.get_size_inches().tolist() == [4.0, 3.0]


def test_scenes_takes_its_options_from_the_command_line_and_the_old_names(monkeypatch, tmp_path):
    from benchmarks import scenes

    seen = []

    def fake_run(self, mode, out, **options):
        seen.append((self.name, mode, options))
        return {"json": str(tmp_path / "x.json")}

    monkeypatch.setattr(Benchmark, "run", fake_run)
    assert main(["scenes", "--quick", "--strategy", "lr", "--out", str(tmp_path)]) == 0
    assert main(["two_stage_slope", "--mode", "partial", "--out", str(tmp_path)]) == 0
    assert seen == [
        ("scenes", "quick", {"strategy": "lr"}),
        ("scenes", "partial", {"strategy": "two_stage", "scene": "slope"}),
    ]
    assert scenes.BENCHMARK.stem("partial", seen[1][2]) == "two_stage_slope"


def stepper_internals(source: str) -> list[str]:
    """The reaches into a stepper's internals in a module's source: ``<...>stepper._name``,
    the private solve ``ScriptedSolve`` and imports of ``bfemp.steppers._*`` modules."""
    found = []
    for node in ast.walk(ast.parse(source)):
        line = getattr(node, "lineno", 0)
        if isinstance(node, ast.Attribute) and node.attr.startswith("_"):
            owner = node.value
            name = owner.id if isinstance(owner, ast.Name) else getattr(owner, "attr", "")
            if name.endswith("stepper") and not node.attr.startswith("__"):
                found.append(f"{line}: {name}.{node.attr}")
        elif isinstance(node, ast.Name | ast.alias) and "ScriptedSolve" in (
            getattr(node, "id", None),
            getattr(node, "name", None),
        ):
            found.append(f"{line}: ScriptedSolve")
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith(
            "bfemp.steppers._"
        ):
            found.append(f"{line}: from {node.module}")
    return found


def test_the_guard_finds_every_kind_of_reach():
    source = (
        "from bfemp.steppers._barrier_solve import ScriptedSolve\n"
        "n = sim.stepper._fem_fg.size\n"
        "stepper._solver.solve()\n"
        "ok = stepper.phases(state).x0, stepper.fem_foreground, term._cache\n"
    )
    assert stepper_internals(source) == [
        "1: from bfemp.steppers._barrier_solve",
        "1: ScriptedSolve",
        "2: stepper._fem_fg",
        "3: stepper._solver",
    ]


def test_benchmarks_inspect_steppers_through_their_public_hooks_only():
    """Benchmarks read a step through ``BarrierStepper.phases`` and public properties (``fem_
    foreground``, ``linear_solver``) and switch rules through options, never through a
    stepper's private names (which change without notice)."""
    root = Path(runner.__file__).resolve().parent
    reaches = {
        path.name: found
        for path in sorted(root.rglob("*.py"))
        if (found := stepper_internals(path.read_text()))
    }
    assert reaches == {}


def test_a_benchmarks_own_options_reach_its_measure_and_unset_ones_stay_out(monkeypatch, tmp_path):
    """``Benchmark.arguments`` adds a benchmark's options to ``python -m benchmarks NAME``; the
    values given reach ``run`` (and so ``measure``), options left unset do not (an alias's
    options stand, the measure's defaults apply)."""
    seen = []

    def fake_run(self, mode, out, **options):
        seen.append((self.name, mode, options))
        return {"json": str(tmp_path / "x.json")}

    monkeypatch.setattr(Benchmark, "run", fake_run)
    assert main(["fuzz", "--quick", "--workers", "3", "--resume", "--out", str(tmp_path)]) == 0
    assert main(["extremes", "--mode", "quick", "--strategy", "lr", "--out", str(tmp_path)]) == 0
    assert main(["conformance", "--out", str(tmp_path)]) == 0
    assert seen == [
        ("fuzz", "quick", {"workers": 3, "resume": True}),
        ("extremes", "quick", {"strategy": ["lr"]}),
        ("conformance", "full", {}),
    ]


def test_needs_out_passes_the_output_folder_to_measure(tmp_path):
    got = []

    def measure(mode, cfg, out):
        got.append(out)
        return {"n": cfg["n"]}

    bench = Benchmark("fake_out", "Fake.", {"quick": {"n": 1}}, measure, needs_out=True)
    assert bench.run("quick", tmp_path)["n"] == 1 and got == [tmp_path]
