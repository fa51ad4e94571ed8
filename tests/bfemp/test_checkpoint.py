"""Checkpoint/restart: a resumed run equals the uninterrupted one bit for bit (state, metrics
without the wall-clock time_* columns, VTU frames and PVD files), after a normal stop, a crash
(frames written after the last checkpoint), Ctrl-C and a double Ctrl-C; refusals and atomicity;
run folders that are damaged (checkpoint, manifest, frame), in use, or a file, and the temporary
files of a killed run (issue 44, defect 6)."""

import json
import logging
import os
import shutil
import signal
import threading
import warnings
import zipfile

import numpy as np
import pytest

import bfemp
from bfemp import checkpoint as ckpt_module
from bfemp.checkpoint import read_checkpoint
from bfemp.errors import SceneError
from bfemp.io.metrics import MetricsLog
from bfemp.manifest import run_info

DT, EVERY = 0.01, 3
T_END = 12 * DT


def _scene(E=1e5):
    """A clamped FEM beam beside an MPM block falling on a slip floor (Newmark, APIC)."""
    scene = bfemp.Scene(dim=2, gravity=(0.0, -9.81))
    mesh = bfemp.shapes.rectangle((0.0, 1.0), (1.0, 1.2), h=0.1)
    mat = bfemp.NeoHookean(E=E, nu=0.3, density=500.0)
    scene.add_fem(
        mesh,
        material=mat,
        name="beam",
        prescribed=bfemp.motion.Fixed(),
        prescribed_nodes=mesh.points[:, 0] < 1e-9,
    )
    x, vol = bfemp.sample.box((2.0, 0.1), (2.4, 0.5), dx=0.1, ppc=4)
    scene.add_mpm(x, vol, material=mat, velocity=(0.5, 0.0), name="block")
    scene.set_grid(dx=0.1)
    scene.add_boundary(bfemp.levelset.HalfPlane(point=(0.0, 0.0), normal=(0.0, 1.0)), "slip")
    return scene


def _sim(**kwargs):
    return bfemp.Simulation(_scene(**kwargs), integrator="newmark", dt=DT, tol=1e-8)


def _run(sim, out, t_end=T_END, **kwargs):
    return sim.run(t_end, out=out, every=EVERY, progress=False, **kwargs)


@pytest.fixture(scope="module", autouse=True)
def no_plots():
    """The metrics and snapshot PNGs (0.6 s per run with matplotlib) are not what these tests
    check."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(bfemp._run_folder, "plot_metrics", lambda *args, **kwargs: None)
        mp.setattr(bfemp._run_folder, "write_snapshot_sheet", lambda *args, **kwargs: None)
        yield


@pytest.fixture(scope="module")
def reference(tmp_path_factory, no_plots):
    out = tmp_path_factory.mktemp("uninterrupted")
    sim = _sim()
    _run(sim, out, checkpoint_every=4)
    return sim, out


def _bits(a):
    a = np.ascontiguousarray(a, dtype=np.float64)
    return a.view(np.int64)


def _assert_same_run(sim_a, out_a, sim_b, out_b):
    assert sim_a.state.t == sim_b.state.t and sim_a.state.step == sim_b.state.step
    arrays_b = sim_b.state.arrays()
    for name, value in sim_a.state.arrays().items():
        assert np.array_equal(_bits(value), _bits(arrays_b[name])), name
    for ma, mb in ((sim_a.metrics, sim_b.metrics), *_csv_pair(out_a, out_b)):
        cols = [c for c in ma.columns if not c.startswith("time_")]
        assert cols == [c for c in mb.columns if not c.startswith("time_")]
        for c in cols:
            assert np.array_equal(_bits(ma.column(c)), _bits(mb.column(c))), c
    frames_a = sorted(p.relative_to(out_a) for p in out_a.rglob("*.vtu"))
    frames_b = sorted(p.relative_to(out_b) for p in out_b.rglob("*.vtu"))
    assert frames_a == frames_b and len(frames_a) == 2 * (T_END / DT // EVERY + 1)
    for rel in frames_a:
        assert (out_a / rel).read_bytes() == (out_b / rel).read_bytes(), rel
    for name in ("beam.pvd", "block.pvd"):
        assert (out_a / name).read_bytes() == (out_b / name).read_bytes()


def _csv_pair(out_a, out_b):
    return [
        (MetricsLog.from_csv(out_a / "metrics.csv"), MetricsLog.from_csv(out_b / "metrics.csv"))
    ]


def test_resume_after_a_stop_equals_the_uninterrupted_run(reference, tmp_path):
    first = _sim()
    _run(first, tmp_path, t_end=5 * DT)  # stops between two frames
    assert read_checkpoint(tmp_path).state.step == 5
    resumed = _sim()
    _run(resumed, tmp_path, resume=True)
    _assert_same_run(*reference, resumed, tmp_path)
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert [s["resumed"] for s in manifest["sessions"]] == [False, True]
    assert manifest["sessions"][1]["from_step"] == 5 and manifest["status"] == "completed"


def test_resume_after_a_crash_drops_frames_past_the_checkpoint(reference, tmp_path):
    _run(_sim(), tmp_path, t_end=4 * DT)
    saved = tmp_path / "saved"
    saved.mkdir()
    for name in ("checkpoint.npz", "checkpoint.json"):
        shutil.copy(tmp_path / name, saved / name)
    _run(_sim(), tmp_path, t_end=8 * DT, resume=True)  # frames at steps 6 written
    for name in ("checkpoint.npz", "checkpoint.json"):  # ... then the crash: back to step 4
        shutil.copy(saved / name, tmp_path / name)
    shutil.rmtree(saved)
    resumed = _sim()
    _run(resumed, tmp_path, resume=True)
    _assert_same_run(*reference, resumed, tmp_path)


def _interrupt_at(step, times):
    def callback(sim):
        if sim.state.step == step:
            for _ in range(times):
                os.kill(os.getpid(), signal.SIGINT)

    return callback


def test_ctrl_c_writes_a_checkpoint_and_the_run_resumes_bit_for_bit(reference, tmp_path):
    sim = _sim()
    # the handler in place before the run (Python's default, or SIG_IGN under nohup / `&`)
    before = signal.getsignal(signal.SIGINT)
    with pytest.raises(KeyboardInterrupt):
        _run(sim, tmp_path, callback=_interrupt_at(7, 1))
    assert sim.state.step == 7 and read_checkpoint(tmp_path).state.step == 7
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert manifest["status"] == "interrupted" and "step 7" in manifest["message"]
    assert signal.getsignal(signal.SIGINT) is before  # handler restored
    resumed = _sim()
    _run(resumed, tmp_path, resume=True)
    _assert_same_run(*reference, resumed, tmp_path)


def test_a_second_ctrl_c_aborts_and_the_last_periodic_checkpoint_remains(reference, tmp_path):
    with pytest.raises(KeyboardInterrupt):
        _run(_sim(), tmp_path, checkpoint_every=4, callback=_interrupt_at(6, 2))
    assert read_checkpoint(tmp_path).state.step == 4
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert "without a checkpoint" in manifest["message"]
    resumed = _sim()
    _run(resumed, tmp_path, resume=True)
    _assert_same_run(*reference, resumed, tmp_path)


def test_resume_refuses_another_model_and_warns_on_other_settings(reference, tmp_path, caplog):
    _run(_sim(), tmp_path, t_end=2 * DT)
    with pytest.raises(SceneError, match="another model"):
        _run(_sim(E=2e5), tmp_path, resume=True)
    other_dt = bfemp.Simulation(_scene(), integrator="newmark", dt=DT / 2, tol=1e-8)
    with caplog.at_level(logging.WARNING, logger="bfemp.checkpoint"):
        other_dt.load_checkpoint(tmp_path)
    assert "will differ from an uninterrupted one" in caplog.text and other_dt.state.step == 2
    with pytest.raises(SceneError, match="no checkpoint"):
        _run(_sim(), tmp_path / "empty", resume=True)
    with pytest.raises(ValueError, match="resume=True needs out"):
        _sim().run(T_END, resume=True)


def test_a_failed_step_leaves_a_checkpoint_of_the_last_good_state(tmp_path):
    sim = bfemp.Simulation(_scene(), dt=DT, tol=1e-14, max_newton_iterations=1)
    with pytest.raises(bfemp.StepError):
        sim.run(T_END, out=tmp_path, progress=False)
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert manifest["status"] == "failed" and "MAX_ITERATIONS" in manifest["message"]
    assert read_checkpoint(tmp_path).state.step == 0
    assert len(MetricsLog.from_csv(tmp_path / "metrics.csv")) == 1


def test_checkpoint_writes_are_atomic(tmp_path, monkeypatch):
    sim = _sim()
    sim.step()
    sim.save_checkpoint(tmp_path)
    before = (tmp_path / "checkpoint.npz").read_bytes()
    sim.step()

    def broken_savez(fh, **arrays):
        fh.write(b"half a checkpoint")
        raise OSError("disk full")

    monkeypatch.setattr(ckpt_module.np, "savez", broken_savez)
    with pytest.raises(OSError, match="disk full"):
        sim.save_checkpoint(tmp_path)
    assert (tmp_path / "checkpoint.npz").read_bytes() == before
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]
    monkeypatch.undo()
    restored = _sim()
    restored.load_checkpoint(tmp_path)
    assert restored.state.step == 1 and len(restored.metrics) == 2


def _contact_sim():
    """An MPM block hitting a fixed FEM floor, kappa = "auto" (which doubles during the run:
    the stepper carries it from step to step) and friction."""
    scene = bfemp.Scene(dim=2, gravity=(0.0, -9.81))
    mat = bfemp.NeoHookean(E=1e4, nu=0.3, density=500.0)
    floor = bfemp.shapes.rectangle((-0.5, -0.2), (1.5, 0.0), h=0.1)
    scene.add_fem(floor, material=mat, prescribed=bfemp.motion.Fixed(), name="floor")
    x, vol = bfemp.sample.box((0.2, 0.02), (0.6, 0.42), dx=0.1, ppc=4)
    scene.add_mpm(x, vol, material=mat, velocity=(0.0, -1.0), name="block")
    scene.set_grid(dx=0.1)
    scene.set_contact(dhat=1e-3, kappa="auto", mu=0.1)
    return bfemp.Simulation(scene, dt=DT, tol=1e-7)


def test_contact_with_adaptive_kappa_resumes_bit_for_bit(tmp_path):
    reference = _contact_sim()
    reference.run(10 * DT, out=tmp_path / "a", every=2, progress=False)
    kappa = reference.metrics.column("kappa")
    assert kappa[-1] > kappa[7] > kappa[1]  # kappa changed after the checkpoint below
    _contact_sim().run(7 * DT, out=tmp_path / "b", every=2, progress=False)
    resumed = _contact_sim()
    resumed.run(10 * DT, out=tmp_path / "b", every=2, progress=False, resume=True)
    for name, value in reference.state.arrays().items():
        assert np.array_equal(_bits(value), _bits(resumed.state.arrays()[name])), name
    for c in reference.metrics.columns:
        if not c.startswith("time_"):
            assert np.array_equal(
                _bits(reference.metrics.column(c)), _bits(resumed.metrics.column(c))
            ), c


def test_an_interrupt_in_the_final_writes_leaves_the_manifest_interrupted(tmp_path, monkeypatch):
    def interrupted_plot(*args, **kwargs):
        raise KeyboardInterrupt  # Ctrl-C (twice) while the metrics PNG is drawn

    monkeypatch.setattr(bfemp._run_folder, "plot_metrics", interrupted_plot)
    with pytest.raises(KeyboardInterrupt):
        _run(_sim(), tmp_path, t_end=2 * DT)
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert manifest["status"] == "interrupted" and manifest["sessions"][-1]["status"] != "running"
    assert "metrics.png" in manifest["message"] and "not written" in manifest["message"]
    # the metrics table and the checkpoint come first: the run resumes from its end
    assert read_checkpoint(tmp_path).state.step == 2
    assert len(MetricsLog.from_csv(tmp_path / "metrics.csv")) == 3


def test_a_first_ctrl_c_in_the_final_writes_lets_them_finish(tmp_path, monkeypatch):
    written = []

    def plot_then_ctrl_c(*args, **kwargs):
        os.kill(os.getpid(), signal.SIGINT)
        written.append("metrics.png")

    monkeypatch.setattr(bfemp._run_folder, "plot_metrics", plot_then_ctrl_c)
    monkeypatch.setattr(
        bfemp._run_folder, "write_snapshot_sheet", lambda out: written.append("snapshots.png")
    )
    with pytest.raises(KeyboardInterrupt):
        _run(_sim(), tmp_path, t_end=2 * DT)
    assert written == ["metrics.png", "snapshots.png"]
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert manifest["status"] == "interrupted" and "(all written)" in manifest["message"]


# ---------------------------------------------------------------- damaged and shared run folders
# (issue 44, defect 6: each of these failed before the fix, as said in its docstring)


def _copy_of(reference, tmp_path):
    """A copy of the reference run folder (checkpoint at step 12), to damage."""
    out = tmp_path / "run"
    shutil.copytree(reference[1], out)
    return out


def _files(out):
    return {p.relative_to(out): p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}


@pytest.mark.parametrize(
    "damage", ["truncated", "garbage", "damaged member", "damaged member header"]
)
def test_a_corrupt_checkpoint_is_refused_naming_the_file(reference, tmp_path, damage):
    """Before: zipfile.BadZipFile escaped (truncated, damaged member: a traceback, exit 1), and
    a garbage file was blamed on ``allow_pickle``."""
    out = _copy_of(reference, tmp_path)
    path = out / "checkpoint.npz"
    data = bytearray(path.read_bytes())
    if damage == "truncated":
        data = data[: len(data) // 2]
    elif damage == "garbage":
        data = b"x" * 1000
    elif damage == "damaged member":  # the zip directory intact, the data of a member overwritten
        data[len(data) // 3 : len(data) // 3 + 64] = bytes(64)
    else:  # the .npy header of the largest member overwritten (np.savez stores, uncompressed;
        # numpy parses the header before the member's CRC is checked at its end)
        with zipfile.ZipFile(path) as archive:
            member = max(archive.infolist(), key=lambda info: info.file_size)
        start = member.header_offset
        lengths = int.from_bytes(data[start + 26 : start + 30], "little")  # name, extra field
        header = start + 30 + (lengths & 0xFFFF) + (lengths >> 16) + 10  # after magic, length
        data[header : header + 10] = bytes(10)  # numpy: tokenize.TokenError, not a ValueError
    path.write_bytes(bytes(data))
    before = _files(out)
    with pytest.raises(bfemp.RunFolderError) as err:
        _run(_sim(), out, t_end=14 * DT, resume=True)
    message = str(err.value)
    assert message.startswith(f"{path}: corrupt checkpoint: "), message
    if not damage.startswith("damaged member"):
        assert "not a complete zip archive" in message, message
    assert "pickle" not in message and "--overwrite" in message
    assert _files(out) == before  # refused before anything was changed


def test_a_truncated_frame_before_the_checkpoint_is_refused(reference, tmp_path):
    """Before: the resume went on and the run folder kept a frame no reader can open."""
    out = _copy_of(reference, tmp_path)
    frame = out / "beam" / "frame_00004.vtu"  # the frame at the checkpoint, t = 0.12 s
    frame.write_bytes(frame.read_bytes()[:700])
    before = _files(out)
    with pytest.raises(bfemp.RunFolderError) as err:
        _run(_sim(), out, t_end=14 * DT, resume=True)
    assert str(err.value).startswith(
        f"{frame}: corrupt frame of block 'beam' at t = 0.12 s: 700 bytes, not ending with "
        "</VTKFile> (truncated)"
    ), str(err.value)
    assert _files(out) == before


def test_a_corrupt_manifest_is_refused_not_replaced(reference, tmp_path):
    """Before: a truncated manifest.json was replaced by a new one (the earlier sessions lost)
    with only a log line."""
    out = _copy_of(reference, tmp_path)
    path = out / "manifest.json"
    path.write_text(path.read_text()[:200])
    before = _files(out)
    with pytest.raises(bfemp.RunFolderError) as err:
        _run(_sim(), out, t_end=14 * DT, resume=True)
    assert str(err.value).startswith(f"{path}: corrupt run manifest: not valid JSON (truncated?)")
    assert "earlier sessions" in str(err.value)
    assert _files(out) == before


def test_a_second_writer_is_refused_naming_the_holder(reference, tmp_path):
    """Two runs into one folder at once (here two threads; two processes are refused alike).
    Before: both ran, and the manifest kept only the session that finished last."""
    out = _copy_of(reference, tmp_path)
    inside, leave = threading.Event(), threading.Event()

    def hold(sim):
        inside.set()
        assert leave.wait(120)

    first = threading.Thread(
        target=lambda: _run(_sim(), out, t_end=14 * DT, resume=True, callback=hold)
    )
    first.start()
    try:
        assert inside.wait(120)  # the first run is inside its time loop
        with pytest.raises(bfemp.RunFolderError) as err:
            _run(_sim(), out, t_end=16 * DT, resume=True)
        info = run_info(out)  # bfemp info: running, by this process
        assert info["status"] == "running" and info["running"]["pid"] == os.getpid()
    finally:
        leave.set()
        first.join(120)
    message = str(err.value)
    assert message.startswith(
        f"{out}: the folder is in use by another bfemp run (pid {os.getpid()}"
    )
    assert ", started 20" in message and ".bfemp.lock" in message, message
    manifest = json.loads((out / "manifest.json").read_text())
    assert [s["status"] for s in manifest["sessions"]] == ["completed", "completed"]
    assert manifest["sessions"][1]["to_step"] == 14
    assert not (out / ".bfemp.lock").exists()  # released


def test_temporary_files_of_a_killed_run_are_removed_on_resume(reference, tmp_path):
    """Before: a 0-byte ``.metrics.png.*.tmp`` (a write cut by SIGKILL) survived the resume."""
    out = _copy_of(reference, tmp_path)
    ours = [
        out / ".metrics.png.k3j_9xq2.tmp",
        out / ".checkpoint.npz.a1b2c3d4.tmp",
        out / ".beam.pvd.0f9e8d7c.tmp",
        out / "beam" / ".frame_00005.vtu.zz0011yy.tmp",
    ]
    theirs = [out / ".notes.txt.a1b2c3d4.tmp", out / "beam" / "mine.tmp", out / "x.tmp"]
    for path in ours + theirs:
        path.write_bytes(b"")
    _run(_sim(), out, t_end=14 * DT, resume=True)
    assert [p.name for p in ours if p.exists()] == []
    assert all(p.exists() for p in theirs)  # not of a run's write: the user's


def test_out_naming_a_file_is_refused(tmp_path):
    """Before: ``FileExistsError: [Errno 17] File exists`` from ``mkdir``."""
    path = tmp_path / "a_file"
    path.write_text("mine")
    with pytest.raises(bfemp.RunFolderError, match=rf"^{path}: the output folder is a file"):
        _run(_sim(), path)
    with pytest.raises(bfemp.RunFolderError, match="cannot create the output folder: Not a dir"):
        _run(_sim(), path / "sub")
    assert path.read_text() == "mine"


def test_a_run_stopped_before_its_first_checkpoint_restarts_as_the_hint_says(reference, tmp_path):
    """Aborted (double Ctrl-C; a SIGKILL alike) before the first checkpoint. Before: the hint
    said to run without ``resume``, which refuses a folder holding a run."""
    with pytest.raises(KeyboardInterrupt):
        _run(_sim(), tmp_path, checkpoint_every=4, callback=_interrupt_at(2, 2))
    assert not (tmp_path / "checkpoint.npz").exists()
    with pytest.raises(bfemp.RunFolderError, match="no checkpoint") as err:
        _run(_sim(), tmp_path, resume=True)
    assert "stopped before its first checkpoint" in err.value.hint
    assert "overwrite=True instead of resume=True" in err.value.hint
    sim = _sim()
    _run(sim, tmp_path, overwrite=True)  # what the hint says
    _assert_same_run(*reference, sim, tmp_path)


def test_resume_keeps_the_frame_and_checkpoint_intervals_of_the_run(reference, tmp_path):
    """The README's ``load_run(out).run(t_end, out=out, resume=True)``, with no ``every``:
    it wrote a frame every step (``every`` defaulted to 1, with a warning about it) instead of
    the run's every 3 (issue 42, defect 2). Now the intervals are the checkpoint's (frames)
    and the manifest's (checkpoints), and the continued run equals the uninterrupted one."""
    first = _sim()
    _run(first, tmp_path, t_end=5 * DT, checkpoint_every=4)
    resumed = bfemp.load_run(tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)  # no RESUME_EVERY_CHANGED
        resumed.run(T_END, out=tmp_path, progress=False, resume=True)
    _assert_same_run(*reference, resumed, tmp_path)  # frames every 3 steps, bit for bit
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert manifest["parameters"]["run"]["every"] == EVERY
    assert manifest["parameters"]["run"]["checkpoint_every"] == 4
    # an interval given on resume wins, and the change is warned about once
    _run(_sim(), tmp_path / "b", t_end=5 * DT)
    with pytest.warns(bfemp.BfempWarning, match="RESUME_EVERY_CHANGED: .* every 2 steps"):
        _sim().run(T_END, out=tmp_path / "b", every=2, progress=False, resume=True)
