"""The command line end to end on a tiny scene: run, resume, info, bench dispatch, and errors
printed as one line without a traceback (exit 2), failed checks (exit 1), Ctrl-C (exit 130), a
run killed by SIGKILL (shown interrupted, resumed, or restarted as the hint says), damaged run
folders (exit 2)."""

import json
import logging
import os
import signal
import subprocess
import sys
import types
from pathlib import Path

import meshio
import numpy as np
import pytest

import bfemp
from bfemp.cli import main
from bfemp.io.metrics import MetricsLog
from bfemp.io.vtk import read_pvd

TINY = """
[scene]
dim = 2
gravity = [0.0, -9.81]

[simulation]
integrator = "newmark"
dt = 0.01
tol = 1e-8

[run]
t_end = 0.06
every = 2
checkpoint_every = 2

[materials.m]
E = 1e5
nu = 0.3
density = 500.0

[[fem]]
name = "beam"
material = "m"
mesh = { shape = "rectangle", lower = [0.0, 0.0], upper = [1.0, 0.2], h = 0.1 }
prescribed = { type = "fixed" }
prescribed_nodes = { box = { lower = [-inf, -inf], upper = [1e-9, inf] } }

[check]
finite = true
energy_drift_max = 0.01
"""


@pytest.fixture
def scene_file(tmp_path):
    path = tmp_path / "tiny.toml"
    path.write_text(TINY)
    return path


@pytest.fixture
def no_plots(monkeypatch):
    """Skip the metrics and snapshot PNGs (0.6 s per run) where a test does not look at them."""
    monkeypatch.setattr(bfemp._run_folder, "plot_metrics", lambda *args, **kwargs: None)
    monkeypatch.setattr(bfemp._run_folder, "write_snapshot_sheet", lambda *args, **kwargs: None)


def _run(*args):
    return main(["run", *map(str, args), "--quiet"])


def test_run_writes_frames_metrics_manifest_and_checkpoint(scene_file, tmp_path, capsys):
    out = tmp_path / "out"
    assert _run(scene_file, "--out", out, "--check") == 0
    printed = capsys.readouterr().out
    assert "run finished: t = 0.06 s, step 6" in printed and "check ok" in printed
    frames = read_pvd(out / "beam.pvd")
    assert [round(t, 9) for t, _ in frames] == [0.0, 0.02, 0.04, 0.06]
    last = meshio.read(frames[-1][1])
    assert last.point_data["velocity"].shape == (last.points.shape[0], 3)
    assert np.all(last.cell_data["J"][0] > 0) and np.all(last.cell_data["von_mises"][0] >= 0)
    assert np.any(last.point_data["velocity"][:, 1] < 0)  # the beam falls
    metrics = MetricsLog.from_csv(out / "metrics.csv")
    assert len(metrics) == 7 and (out / "metrics.png").stat().st_size > 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["status"] == "completed"
    assert manifest["parameters"]["scene_file"] == str(scene_file.resolve())
    assert manifest["parameters"]["simulation"]["dt"] == 0.01
    assert manifest["parameters"]["run"] == {"t_end": 0.06, "every": 2, "checkpoint_every": 2}
    assert manifest["model"]["fem_bodies"][0]["nodes"] == 33
    assert manifest["versions"]["numpy"] == np.__version__ and "commit" in manifest["git"]
    assert (out / "scene.toml").read_text() == TINY
    assert json.loads((out / "checkpoint.json").read_text())["step"] == 6


def test_resume_from_the_command_line_equals_one_run(scene_file, tmp_path, no_plots):
    whole, parts = tmp_path / "whole", tmp_path / "parts"
    assert _run(scene_file, "--out", whole) == 0
    assert _run(scene_file, "--out", parts, "--t-end", 0.03) == 0
    assert _run(scene_file, "--out", parts, "--resume") == 0
    a, b = (MetricsLog.from_csv(d / "metrics.csv") for d in (whole, parts))
    for c in (c for c in a.columns if not c.startswith("time_")):
        assert np.array_equal(a.column(c), b.column(c), equal_nan=True), c
    files = sorted(p.relative_to(whole) for p in whole.rglob("*.vtu"))
    assert files == sorted(p.relative_to(parts) for p in parts.rglob("*.vtu"))
    for rel in [*files, Path("beam.pvd")]:
        assert (whole / rel).read_bytes() == (parts / rel).read_bytes(), rel
    manifest = json.loads((parts / "manifest.json").read_text())
    assert [s["from_step"] for s in manifest["sessions"]] == [0, 3]


def test_resume_keeps_the_frame_interval_given_to_the_first_session(scene_file, tmp_path, no_plots):
    """``--every 3`` on the first session, ``--resume`` without it (as the interrupt hint says):
    the continuation took the scene file's ``every = 2`` (issue 42, defect 2); now the
    checkpoint's, so the frames are those of one run."""
    whole, parts = tmp_path / "whole", tmp_path / "parts"
    assert _run(scene_file, "--out", whole, "--every", 3) == 0
    assert _run(scene_file, "--out", parts, "--t-end", 0.03, "--every", 3) == 0
    assert _run(scene_file, "--out", parts, "--resume") == 0
    assert [round(t, 9) for t, _ in read_pvd(parts / "beam.pvd")] == [0.0, 0.03, 0.06]
    assert (whole / "beam.pvd").read_bytes() == (parts / "beam.pvd").read_bytes()
    manifest = json.loads((parts / "manifest.json").read_text())
    assert manifest["parameters"]["run"]["every"] == 3


def test_resume_towards_an_end_time_before_the_checkpoint_is_refused(
    scene_file, tmp_path, capsys, no_plots
):
    out = tmp_path / "out"
    assert _run(scene_file, "--out", out, "--t-end", 0.04) == 0
    capsys.readouterr()
    before = (out / "checkpoint.json").read_text(), (out / "manifest.json").read_text()
    err = _error(capsys, ["run", str(scene_file), "--out", str(out), "--resume", "--t-end", "0.02"])
    assert "--t-end: t_end = 0.02 s is earlier than the checkpoint" in err
    assert "at t = 0.04 s" in err, err
    # nothing was touched: the run can still be resumed
    assert ((out / "checkpoint.json").read_text(), (out / "manifest.json").read_text()) == before
    sim = bfemp.Simulation.from_file(scene_file)  # the Python API refuses it too
    with pytest.raises(ValueError, match=r"t_end = 0.02 s is earlier than the time t = 0.04 s of"):
        sim.run(0.02, out=out, resume=True, progress=False)
    assert _run(scene_file, "--out", out, "--resume") == 0


def test_info_summarises_a_result_folder(scene_file, tmp_path, capsys, no_plots):
    out = tmp_path / "out"
    _run(scene_file, "--out", out)
    capsys.readouterr()
    assert main(["info", str(out)]) == 0
    text = capsys.readouterr().out
    for fragment in ("status:        completed", "beam: 33 nodes", "6 steps", "beam.pvd: 4"):
        assert fragment in text, (fragment, text)
    assert "checkpoint:    step 6, t = 0.06 s" in text
    assert main(["info", str(out), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["metrics"]["newton"]["total"] >= 6 and info["frames"] == {"beam": 4}


def _error(capsys, argv, code=2):
    assert main(argv) == code
    err = capsys.readouterr().err
    assert err.startswith("bfemp: error: ") and "Traceback" not in err, err
    return err


def test_mistakes_print_one_line_and_exit_2(scene_file, tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text(TINY.replace("nu = 0.3", "nu = 0.5"))
    err = _error(capsys, ["run", str(bad)])
    assert f"{bad}: materials.m.nu: must be < 0.5" in err and "incompressible" in err
    bad.write_text(TINY.replace("dt = 0.01", 'dt = "1 cm"'))
    assert "simulation.dt: unit 'cm' is a length" in _error(capsys, ["run", str(bad)])
    assert "scene file not found" in _error(capsys, ["run", str(tmp_path / "none.toml")])
    assert "not a bfemp result folder" in _error(capsys, ["info", str(tmp_path)])
    assert "--every: must be an integer >= 1" in _error(
        capsys, ["run", str(scene_file), "--every", "0"]
    )
    assert "no checkpoint" in _error(
        capsys, ["run", str(scene_file), "--out", str(tmp_path / "fresh"), "--resume"]
    )
    assert "unknown benchmark 'nope'" in _error(capsys, ["bench", "nope"])


def test_a_failing_check_exits_1_and_dry_run_only_reads(scene_file, tmp_path, capsys, no_plots):
    failing = tmp_path / "failing.toml"
    failing.write_text(TINY + "max = { energy_total = -1e9 }\n")
    assert _run(failing, "--out", tmp_path / "out", "--check") == 1
    captured = capsys.readouterr()
    assert "check FAIL max.energy_total" in captured.out and "a check failed" in captured.err
    assert _run(scene_file, "--out", tmp_path / "dry", "--dry-run") == 0
    assert "tiny.toml: ok: 33 FEM nodes" in capsys.readouterr().out
    assert not (tmp_path / "dry").exists()


def test_a_second_run_into_the_same_folder_needs_overwrite(scene_file, tmp_path, capsys, no_plots):
    out = tmp_path / "out"
    assert _run(scene_file, "--out", out) == 0
    (out / "scene.toml").write_text("# the first run's scene\n")
    err = _error(capsys, ["run", str(scene_file), "--out", str(out), "--quiet"])
    assert "holds the outputs of an earlier run" in err and "--overwrite" in err
    assert (out / "scene.toml").read_text() == "# the first run's scene\n"  # nothing touched
    (out / "beam").joinpath("frame_00099.vtu").write_text("stale")
    assert _run(scene_file, "--out", out, "--overwrite", "--animate", "gif") == 0
    assert not (out / "beam" / "frame_00099.vtu").exists()
    assert (out / "animation.gif").read_bytes()[:6] == b"GIF89a"
    assert (out / "scene.toml").read_text() == TINY
    assert json.loads((out / "manifest.json").read_text())["sessions"][0]["resumed"] is False


def test_ctrl_c_exits_130_with_the_resume_command(scene_file, tmp_path, capsys, monkeypatch):
    """With a checkpoint the hint is --resume; without one (stopped before the first) it is
    --overwrite, since --resume is refused there (it said --resume in both cases)."""
    out = tmp_path / "out"

    def interrupted(self, *args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(bfemp.Simulation, "run", interrupted)
    assert _run(scene_file, "--out", out) == 130
    err = capsys.readouterr().err
    assert "interrupted at t = 0 s" in err and "no checkpoint was written" in err
    assert f"start again with: bfemp run {scene_file} --out {out} --overwrite" in err
    out.mkdir()
    (out / "checkpoint.npz").write_bytes(b"")  # the run wrote one before it was interrupted
    assert _run(scene_file, "--out", out) == 130
    assert f"continue with: bfemp run {scene_file} --out {out} --resume" in capsys.readouterr().err
    # the options a continuation must repeat are in the hint (the intervals are the checkpoint's)
    assert _run(scene_file, "--out", out, "--quick", "--t-end", 0.04, "--every", 3) == 130
    hint = f"continue with: bfemp run {scene_file} --out {out} --resume --quick --t-end 0.04\n"
    assert hint in capsys.readouterr().err


def test_bench_calls_the_registered_run(tmp_path, monkeypatch, capsys):
    import benchmarks.__main__ as registry

    calls = []
    fake = types.ModuleType("fake_bench")
    fake.run = lambda mode, out: calls.append((mode, out)) or {"json": f"{out}/fake.json"}
    monkeypatch.setitem(sys.modules, "fake_bench", fake)
    monkeypatch.setitem(registry.BENCHMARKS, "fake", "fake_bench")
    assert main(["bench", "fake", "--quick", "--out", str(tmp_path)]) == 0
    assert main(["bench", "fake"]) == 0
    assert main(["bench", "fake", "--mode", "partial"]) == 0
    assert calls == [("quick", str(tmp_path)), ("full", "results"), ("partial", "results")]
    assert f"fake: wrote {tmp_path}/fake.json" in capsys.readouterr().out


def test_bench_names_a_mode_the_benchmark_lacks(capsys):
    """Both command lines pass --mode through; the benchmark's own error names the modes."""
    import benchmarks.__main__ as bench_main

    message = _error(capsys, ["bench", "rings", "--mode", "fastest"])
    assert "bench rings: mode must be one of ['full', 'partial', 'quick']" in message
    with pytest.raises(SystemExit) as exc:
        bench_main.main(["hertz", "--mode", "fastest"])
    assert exc.value.code == 2
    assert "mode must be one of ['full', 'quick', 'refined']" in capsys.readouterr().err


def test_console_entry_point_reports_errors_without_traceback(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text(TINY.replace("[simulation]", "[simulaton]"))
    proc = subprocess.run(
        [sys.executable, "-m", "bfemp", "run", str(bad)], capture_output=True, text=True
    )
    assert proc.returncode == 2
    assert proc.stderr.startswith(f"bfemp: error: {bad}: unknown key 'simulaton'")
    assert "did you mean 'simulation'" in proc.stderr and "Traceback" not in proc.stderr


@pytest.mark.parametrize("quiet", [False, True])
def test_the_superlu_fallback_warning_prints_once_and_not_with_quiet(scene_file, tmp_path, quiet):
    """Without scikit-sparse the command line says so once (it printed the hint twice: a log
    line and the RuntimeWarning), and --quiet silences it (the warning ignored it)."""
    fake = tmp_path / "no_sksparse" / "sksparse"
    fake.mkdir(parents=True)
    (fake / "__init__.py").write_text('raise ImportError("hidden by the test")\n')
    root = Path(bfemp.__file__).resolve().parents[1]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(fake.parent), str(root)])}
    args = [sys.executable, "-m", "bfemp", "run", str(scene_file), "--dry-run"]
    done = subprocess.run(
        args + (["--quiet"] if quiet else []), env=env, capture_output=True, text=True, check=True
    )
    assert "ok:" in done.stdout
    assert done.stderr.count("falling back to scipy's SuperLU") == (0 if quiet else 1), done.stderr


def test_a_first_run_says_it_compiles_the_kernels_and_where_they_go(
    scene_file, tmp_path, capsys, monkeypatch, no_plots
):
    """An empty numba cache: ``bfemp run`` says that it compiles the kernels and names the
    cache (not with --quiet); a cache with an index file: nothing is said."""
    from numba.core import config

    from bfemp._numba_cache import first_run_notice

    cache = tmp_path / "numba_cache"
    # numba chose each kernel's cache when bfemp was imported: this only moves where we look
    monkeypatch.setattr(config, "CACHE_DIR", str(cache))
    assert main(["run", str(scene_file), "--out", str(tmp_path / "a"), "--t-end", "0.02"]) == 0
    err = capsys.readouterr().err
    assert "compiling numba kernels on first run" in err and str(cache) in err
    assert _run(scene_file, "--out", tmp_path / "b", "--t-end", "0.02") == 0
    assert "compiling" not in capsys.readouterr().err
    (cache / "bfemp_0").mkdir(parents=True)
    (cache / "bfemp_0" / "kernel.nbi").write_bytes(b"")
    assert first_run_notice() is None
    assert first_run_notice(str(tmp_path / "elsewhere")) is not None


KILLED = """
import os, signal, sys
import bfemp

def die(sim):
    if sim.state.step == int(sys.argv[3]):
        os.kill(os.getpid(), signal.SIGKILL)

sim = bfemp.Simulation.from_file(sys.argv[1])
sim.run(0.06, out=sys.argv[2], every=2, checkpoint_every=2, progress=False, callback=die)
"""


def _killed_run(scene_file, out, step):
    """Run the tiny scene (checkpoints at even steps) in another process and SIGKILL it after
    step ``step``; return its pid."""
    root = Path(bfemp.__file__).resolve().parents[1]
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(root), os.environ.get("PYTHONPATH", "")]),
    }
    args = [sys.executable, "-c", KILLED, str(scene_file), str(out), str(step)]
    proc = subprocess.Popen(
        args, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == -signal.SIGKILL, err
    return proc.pid


def test_a_killed_run_is_shown_interrupted_and_its_session_recorded_on_resume(
    scene_file, tmp_path, capsys, caplog, no_plots
):
    """Before: `bfemp info` said "running", the resume left the killed session without a
    status, and nothing said that the killed run's lock was taken over (there was none)."""
    out = tmp_path / "out"
    pid = _killed_run(scene_file, out, 3)  # after the checkpoint of step 2
    assert json.loads((out / "manifest.json").read_text())["status"] == "running"  # as left
    assert main(["info", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "status:        interrupted (the session ended without recording its end" in printed
    assert "--resume continues from the checkpoint at step 2" in printed, printed
    assert main(["info", str(out), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["status"] == "interrupted"
    with caplog.at_level(logging.WARNING, logger="bfemp.io.outputs"):
        assert _run(scene_file, "--out", out, "--resume") == 0
    assert "took over the lock" in caplog.text and f"pid {pid} on " in caplog.text, caplog.text
    sessions = json.loads((out / "manifest.json").read_text())["sessions"]
    assert [s["status"] for s in sessions] == ["interrupted", "completed"]
    assert "killed or crashed" in sessions[0]["message"]
    assert "resumed from the checkpoint at step 2" in sessions[0]["message"]
    assert sessions[1]["from_step"] == 2 and sessions[1]["to_step"] == 6
    assert not (out / ".bfemp.lock").exists()
    assert main(["info", str(out)]) == 0
    assert "status:        completed" in capsys.readouterr().out


def test_a_run_killed_before_its_first_checkpoint_restarts_as_the_hint_says(
    scene_file, tmp_path, capsys, no_plots
):
    """Before: the hint said "run without --resume", which refuses the folder."""
    out = tmp_path / "out"
    _killed_run(scene_file, out, 1)
    err = _error(capsys, ["run", str(scene_file), "--out", str(out), "--resume"])
    assert "no checkpoint in" in err and "with --overwrite instead of --resume" in err, err
    assert _run(scene_file, "--out", out, "--overwrite") == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["status"] == "completed" and len(manifest["sessions"]) == 1


def test_damaged_run_folders_and_a_file_as_out_exit_2_naming_the_file(
    scene_file, tmp_path, capsys, no_plots
):
    """Before: a truncated checkpoint gave a traceback (exit 1), a truncated manifest was
    replaced on --resume, --out naming a file printed "[Errno 17] File exists"."""
    out = tmp_path / "out"
    assert _run(scene_file, "--out", out, "--t-end", 0.02) == 0
    resume = ["run", str(scene_file), "--out", str(out), "--resume"]
    checkpoint = (out / "checkpoint.npz").read_bytes()
    (out / "checkpoint.npz").write_bytes(checkpoint[: len(checkpoint) // 2])
    err = _error(capsys, resume)
    assert err.startswith(f"bfemp: error: {out / 'checkpoint.npz'}: corrupt checkpoint: not a")
    (out / "checkpoint.npz").write_bytes(checkpoint)
    truncated = (out / "manifest.json").read_text()[:150]
    (out / "manifest.json").write_text(truncated)
    for argv in (resume, ["info", str(out)]):
        err = _error(capsys, argv)
        assert err.startswith(f"bfemp: error: {out / 'manifest.json'}: corrupt run manifest: not")
    assert (out / "manifest.json").read_text() == truncated  # not replaced
    a_file = tmp_path / "a_file"
    a_file.write_text("")
    err = _error(capsys, ["run", str(scene_file), "--out", str(a_file)])
    assert (
        err.startswith(f"bfemp: error: {a_file}: the output folder is a file")
        and "Errno" not in err
    )


# --------------------------------------------------------------------------- issue 42 (minor)
def test_resume_and_overwrite_together_are_refused(scene_file, tmp_path, capsys):
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as info:  # argparse: one or the other
        main(["run", str(scene_file), "--out", str(out), "--resume", "--overwrite"])
    assert info.value.code == 2
    assert "--overwrite: not allowed with argument --resume" in capsys.readouterr().err
    assert not out.exists()
    sim = bfemp.Simulation.from_file(scene_file)
    with pytest.raises(ValueError, match=r"resume=True continues .* overwrite=True deletes"):
        sim.run(0.02, out=out, resume=True, overwrite=True, progress=False)


def test_mp4_without_ffmpeg_is_an_input_error_exit_2(scene_file, tmp_path, capsys, monkeypatch):
    from matplotlib import animation

    monkeypatch.setattr(animation.FFMpegWriter, "isAvailable", classmethod(lambda cls: False))
    err = _error(capsys, ["run", str(scene_file), "--out", str(tmp_path / "o"), "--animate", "mp4"])
    assert "needs ffmpeg" in err and "'gif'" in err
    assert not (tmp_path / "o").exists()  # refused before the run


def test_regress_finds_the_checkout_references_from_any_folder(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)  # no references/ here
    assert main(["regress", "single_field_2d", "--quiet"]) == 0
    assert "single_field_2d" in capsys.readouterr().out


def test_a_fem_body_prints_in_one_short_line():
    scene = bfemp.Scene(dim=2)
    mesh = bfemp.shapes.rectangle((0.0, 0.0), (4.0, 0.5), h=0.05)
    body = scene.add_fem(mesh, material=bfemp.NeoHookean(E=1e6, nu=0.3, density=1e3), name="p")
    text = repr(body)
    assert "\n" not in text and len(text) < 200, text
    assert text.startswith("FemBody(name='p', index=0, nodes=0:") and "NeoHookean" in text
    assert f"boundary={body.boundary.shape[0]} edges" in text


def test_info_counts_the_newton_iterations_of_the_failed_step(
    scene_file, tmp_path, capsys, no_plots
):
    # issue 42: the failed step (at its iteration cap) is not in metrics.csv, so `bfemp info`
    # showed the largest count of the steps that converged as the run's maximum
    from dataclasses import replace

    sim = bfemp.Simulation.from_file(scene_file)
    step = sim.stepper.step

    def failing_third(state):
        new, report = step(state)
        if report.step < 3:
            return new, report
        raise bfemp.StepError(replace(report, success=False, iterations={"newton": 99}))

    sim.stepper.step = failing_third
    out = tmp_path / "out"
    with pytest.raises(bfemp.StepError):
        sim.run(0.06, out=out, progress=False)
    converged = sim.metrics.column("iterations_newton")[1:]
    assert converged.size == 2 and converged.max() < 99
    assert main(["info", str(out), "--json"]) == 0
    newton = json.loads(capsys.readouterr().out)["metrics"]["newton"]
    assert newton["max"] == 99 and newton["total"] == converged.sum() + 99
    assert newton["failed_step"] == {"step": 3, "iterations": 99}
    assert main(["info", str(out)]) == 0
    assert "max 99); the failed step 3: 99" in capsys.readouterr().out


def test_a_run_past_t_end_says_where_it_ended_and_why(scene_file, caplog):
    # issue 42: runs end on whole steps (0.300539 s for 0.3 s with dt = "auto"), silently
    sim = bfemp.Simulation.from_file(scene_file, dt=0.025)
    with caplog.at_level(logging.INFO, logger="bfemp.simulation"):
        sim.run(0.06, progress=False)
    assert sim.state.step == 3 and sim.state.t == pytest.approx(0.075)
    assert "the run ends at t = 0.075 s" in caplog.text and "t_end = 0.06 s" in caplog.text
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="bfemp.simulation"):
        sim.run(0.1, progress=False)  # 0.075 + 0.025: lands on t_end, nothing to say
    assert sim.state.t == pytest.approx(0.1) and "the run ends at" not in caplog.text
