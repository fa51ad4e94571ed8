"""Run output: VTU frames and PVD collections read back, atomic writes, metrics CSV round trip,
a damaged frame read back, the lock of a run folder."""

import json
import logging
import math
import os
import socket
import stat
import subprocess
import sys

import meshio
import numpy as np
import pytest

from bfemp.errors import RunFolderError
from bfemp.io import Block, FrameWriter, MetricsLog, atomic_path, read_frames, read_pvd
from bfemp.io.outputs import LOCK_FILE, RunFolderLock, lock_holder


def _square_2d():
    points = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    cells = np.array([[0, 1, 2], [0, 2, 3]])
    return points, cells


def _tet_3d():
    points = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]])
    cells = np.array([[0, 1, 2, 3], [1, 2, 3, 4]])
    return points, cells


def _tmp_files(root):
    return [p for p in root.rglob("*") if p.name.endswith(".tmp")]


def _frames(rng, t):
    """A 2D triangle block and a 2D particle cloud at time t (positions move with t)."""
    points, cells = _square_2d()
    velocity = rng.standard_normal((4, 2))
    stress = rng.standard_normal((2, 2, 2))
    particles = rng.random((6, 2)) + t
    return [
        Block(
            "ring",
            points + t,
            cells,
            point_data={"velocity": velocity, "mass": np.arange(4.0), "fixed": np.arange(4) < 2},
            cell_data={"J": np.array([1.0, 0.9]), "stress": stress},
        ),
        Block("blob", particles, None, point_data={"volume": np.full(6, 0.25)}),
    ]


def test_2d_frames_read_back_with_padding(tmp_path):
    rng = np.random.default_rng(0)
    times = [0.0, 0.1, 0.25]
    frames = [_frames(rng, t) for t in times]
    with FrameWriter(tmp_path / "out") as writer:
        for t, blocks in zip(times, frames, strict=True):
            written = writer.write_frame(t, blocks)
            assert [p.name for p in written] == [f"frame_{writer.frame_index - 1:05d}.vtu"] * 2
    out = tmp_path / "out"
    for i, blocks in enumerate(frames):
        ring, blob = blocks
        mesh = meshio.read(out / "ring" / f"frame_{i:05d}.vtu")
        assert mesh.points.shape == (4, 3)
        np.testing.assert_array_equal(mesh.points[:, :2], ring.points)
        np.testing.assert_array_equal(mesh.points[:, 2], 0.0)
        np.testing.assert_array_equal(mesh.cells_dict["triangle"], ring.cells)
        v = mesh.point_data["velocity"]
        assert v.shape == (4, 3)
        np.testing.assert_array_equal(v[:, :2], ring.point_data["velocity"])
        np.testing.assert_array_equal(v[:, 2], 0.0)
        np.testing.assert_array_equal(mesh.point_data["mass"], np.arange(4.0))
        np.testing.assert_array_equal(mesh.point_data["fixed"], [1, 1, 0, 0])
        np.testing.assert_array_equal(mesh.cell_data["J"][0], [1.0, 0.9])
        # 2D tensors are flattened row-major, not padded.
        np.testing.assert_array_equal(
            mesh.cell_data["stress"][0], ring.cell_data["stress"].reshape(2, 4)
        )
        cloud = meshio.read(out / "blob" / f"frame_{i:05d}.vtu")
        np.testing.assert_array_equal(cloud.points[:, :2], blob.points)
        np.testing.assert_array_equal(cloud.cells_dict["vertex"], np.arange(6).reshape(6, 1))
        np.testing.assert_array_equal(cloud.point_data["volume"], 0.25)
    for name in ("ring", "blob"):
        entries = read_pvd(out / f"{name}.pvd")
        assert [t for t, _ in entries] == times
        assert [p for _, p in entries] == [out / name / f"frame_{i:05d}.vtu" for i in range(3)]
        assert all(p.is_file() for _, p in entries)
    assert _tmp_files(out) == []


def test_3d_tet_block_and_times_round_trip_exactly(tmp_path):
    points, cells = _tet_3d()
    displacement = np.arange(15.0).reshape(5, 3)
    times = [1e-4, 1.0 / 3.0, 2.0 / 3.0 + 1e-12]
    with FrameWriter(tmp_path, prefix="step") as writer:
        for t in times:
            writer.write_frame(
                t, [Block("cube", points, cells, point_data={"u": displacement * t})]
            )
    entries = read_pvd(tmp_path / "cube.pvd")
    assert [t for t, _ in entries] == times  # repr keeps every bit of the float64 time
    mesh = meshio.read(entries[-1][1])
    assert entries[-1][1].name == "step_00002.vtu"
    np.testing.assert_array_equal(mesh.points, points)
    np.testing.assert_array_equal(mesh.cells_dict["tetra"], cells)
    np.testing.assert_array_equal(mesh.point_data["u"], displacement * times[-1])


def test_block_absent_from_some_frames_is_listed_only_where_present(tmp_path):
    rng = np.random.default_rng(1)
    ring, blob = _frames(rng, 0.0)
    with FrameWriter(tmp_path) as writer:
        writer.write_frame(0.0, [ring])
        writer.write_frame(0.5, [ring, blob])
        writer.write_frame(1.0, [ring])
    assert [t for t, _ in read_pvd(tmp_path / "ring.pvd")] == [0.0, 0.5, 1.0]
    blob_entries = read_pvd(tmp_path / "blob.pvd")
    assert blob_entries == [(0.5, tmp_path / "blob" / "frame_00001.vtu")]


def test_failed_vtu_write_keeps_previous_files_and_pvd(tmp_path, monkeypatch):
    points, cells = _square_2d()
    with FrameWriter(tmp_path) as writer:
        writer.write_frame(0.0, [Block("a", points, cells, point_data={"p": np.ones(4)})])
    vtu = tmp_path / "a" / "frame_00000.vtu"
    pvd = tmp_path / "a.pvd"
    vtu_before, pvd_before = vtu.read_bytes(), pvd.read_bytes()

    def broken_write(path, *args, **kwargs):
        with open(path, "w") as f:
            f.write("partial garbage")
        raise OSError("disk full")

    monkeypatch.setattr(meshio, "write", broken_write)
    # A new run in the same directory writes frame 0 again, onto the same path.
    writer = FrameWriter(tmp_path)
    with pytest.raises(OSError, match="disk full"):
        writer.write_frame(0.0, [Block("a", points + 1.0, cells)])
    assert vtu.read_bytes() == vtu_before
    assert pvd.read_bytes() == pvd_before
    assert writer.frame_index == 0  # the failed frame did not count
    assert _tmp_files(tmp_path) == []
    monkeypatch.undo()
    np.testing.assert_array_equal(meshio.read(vtu).point_data["p"], 1.0)


def test_atomic_path_replaces_only_on_success(tmp_path):
    target = tmp_path / "sub" / "file.txt"
    with atomic_path(target) as tmp:
        assert tmp.parent == target.parent and tmp != target
        tmp.write_text("first")
    assert target.read_text() == "first"
    assert stat.S_IMODE(os.stat(target).st_mode) == 0o644
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        tmp.write_text("second, half writt")
        raise RuntimeError("interrupted")
    assert target.read_text() == "first"
    assert sorted(p.name for p in target.parent.iterdir()) == ["file.txt"]


def test_resume_continues_numbering_and_drops_recomputed_frames(tmp_path):
    points, cells = _square_2d()
    with FrameWriter(tmp_path) as writer:
        for t in (0.0, 0.1, 0.2, 0.3):
            writer.write_frame(t, [Block("a", points, cells)])
    # Restart from a checkpoint at t = 0.2: frames at 0.2 and 0.3 are recomputed.
    with FrameWriter(tmp_path, resume=True) as writer:
        assert writer.frame_index == 4
        writer.write_frame(0.2, [Block("a", points, cells)])
        writer.write_frame(0.3, [Block("a", points, cells)])
    entries = read_pvd(tmp_path / "a.pvd")
    assert [t for t, _ in entries] == [0.0, 0.1, 0.2, 0.3]
    assert [p.name for _, p in entries] == [
        "frame_00000.vtu",
        "frame_00001.vtu",
        "frame_00004.vtu",
        "frame_00005.vtu",
    ]


def test_frame_writer_rejects_bad_times_and_closed_use(tmp_path):
    points, cells = _square_2d()
    writer = FrameWriter(tmp_path)
    writer.write_frame(0.5, [Block("a", points, cells)])
    with pytest.raises(ValueError, match="t = 0.5 must be larger"):
        writer.write_frame(0.5, [Block("a", points, cells)])
    with pytest.raises(ValueError, match="t must be finite"):
        writer.write_frame(math.nan, [Block("a", points, cells)])
    with pytest.raises(ValueError, match="duplicate names \\['a'\\]"):
        writer.write_frame(1.0, [Block("a", points, cells), Block("a", points, cells)])
    with pytest.raises(ValueError, match="blocks\\[0\\] is not a Block"):
        writer.write_frame(1.0, [points])
    with pytest.raises(ValueError, match="prefix"):
        FrameWriter(tmp_path, prefix="../x")
    writer.close()
    with pytest.raises(RuntimeError, match="closed"):
        writer.write_frame(2.0, [Block("a", points, cells)])


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"name": "a/b"}, "block name 'a/b'"),
        ({"name": ""}, "block name ''"),
        ({"points": np.zeros((4, 4))}, "'ring': points have shape \\(4, 4\\)"),
        ({"points": np.zeros((0, 2)), "cells": None}, "'ring': points have shape \\(0, 2\\)"),
        ({"cells": np.array([[0.0, 1.0, 2.0]])}, "'ring': cells have dtype float64"),
        ({"cells": np.array([[0, 1, 2, 3]])}, "cells have shape \\(1, 4\\) for 2D"),
        ({"cells": np.array([[0, 1, 2], [0, 1, 4], [-1, 0, 1]])}, "cells \\[1, 2\\] index"),
        ({"point_data": {"v": np.zeros((3, 2))}}, "'ring': point_data 'v' has first dimension 3"),
        ({"cell_data": {"J": np.zeros(4)}}, "'ring': cell_data 'J' has first dimension 4"),
        ({"point_data": {"s": np.array(["x"] * 4)}}, "point_data 's' has dtype"),
        # numpy counts timedelta64 among the integers; it is not a real number a frame can hold
        ({"point_data": {"t": np.zeros(4, dtype="m8[s]")}}, "'t' has dtype timedelta64"),
        ({"point_data": {"z": np.zeros((4, 2, 2, 2))}}, "point_data 'z' has shape"),
        ({"point_data": {"": np.zeros(4)}}, "point_data name ''"),
    ],
)
def test_block_rejects_bad_input_naming_the_field(kwargs, message):
    points, cells = _square_2d()
    args = {"name": "ring", "points": points, "cells": cells, **kwargs}
    with pytest.raises(ValueError, match=message):
        Block(**args)


def test_point_cloud_cell_data_is_per_point():
    points = np.zeros((5, 3))
    Block("cloud", points, None, cell_data={"F": np.zeros((5, 3, 3))})
    with pytest.raises(ValueError, match="cell_data 'F' has first dimension 4, expected 5"):
        Block("cloud", points, None, cell_data={"F": np.zeros((4, 3, 3))})


def test_metrics_csv_round_trip_with_growing_columns(tmp_path):
    log = MetricsLog()
    log.append({"t": 0.0, "energy_kinetic": 1.0, "newton_iterations": 3})
    log.append({"t": 0.1, "energy_kinetic": 0.1 + 0.2, "newton_iterations": np.int64(4)})
    # Columns grow: a barrier energy appears once contact starts; one value is missing.
    log.append({"t": 0.2, "energy_barrier": np.float64(1e-300), "newton_iterations": 5})
    log.append({"t": 0.3, "energy_kinetic": math.inf, "min_distance": None, "converged": True})
    assert len(log) == 4
    assert log.columns == [
        "t",
        "energy_kinetic",
        "newton_iterations",
        "energy_barrier",
        "min_distance",
        "converged",
    ]
    np.testing.assert_array_equal(log.column("energy_barrier"), [np.nan, np.nan, 1e-300, np.nan])
    np.testing.assert_array_equal(log.column("energy_kinetic"), [1.0, 0.1 + 0.2, np.nan, np.inf])
    assert log.column("newton_iterations").dtype == np.float64
    assert log.last["converged"] == 1 and math.isnan(log.last["newton_iterations"])

    path = log.to_csv(tmp_path / "metrics.csv")
    assert _tmp_files(tmp_path) == []
    back = MetricsLog.from_csv(path)
    assert back.columns == log.columns and len(back) == len(log)
    for name in log.columns:
        np.testing.assert_array_equal(back.column(name), log.column(name))
    assert [type(r["newton_iterations"]) for r in back.rows[:3]] == [int] * 3
    assert back.rows[1]["energy_kinetic"] == 0.1 + 0.2  # bit-exact float round trip

    as_json = json.loads(json.dumps(log.as_dict(), allow_nan=False))
    assert as_json["energy_kinetic"] == [1.0, 0.1 + 0.2, None, None]
    assert as_json["newton_iterations"] == [3, 4, 5, None]


def test_metrics_rejects_bad_input(tmp_path):
    log = MetricsLog([{"t": 0.0}])
    with pytest.raises(ValueError, match="column 'energy': value 'high'"):
        log.append({"t": 1.0, "energy": "high"})
    assert len(log) == 1 and log.columns == ["t"]  # a rejected row changes nothing
    with pytest.raises(ValueError, match="column name ''"):
        log.append({"": 1.0})
    with pytest.raises(ValueError, match="row must be a mapping"):
        log.append([("t", 1.0)])
    with pytest.raises(ValueError, match="unknown metrics column 'x'"):
        log.column("x")
    with pytest.raises(ValueError, match="empty"):
        _ = MetricsLog().last
    bad = tmp_path / "bad.csv"
    bad.write_text("t,e\n0.0,1.0\n0.1,abc\n")
    with pytest.raises(ValueError, match="line 3, column 'e': 'abc' is not a number"):
        MetricsLog.from_csv(bad)
    bad.write_text("t,e\n0.0\n")
    with pytest.raises(ValueError, match="line 2: 1 fields, header has 2"):
        MetricsLog.from_csv(bad)
    bad.write_text("t,t\n0.0,1.0\n")
    with pytest.raises(ValueError, match="duplicate columns \\['t'\\]"):
        MetricsLog.from_csv(bad)


def test_read_frames_names_a_truncated_or_missing_frame(tmp_path):
    """Before: meshio printed "Couldn't read file" and called sys.exit(1)."""
    rng = np.random.default_rng(3)
    with FrameWriter(tmp_path) as writer:
        for t in (0.0, 0.5):
            writer.write_frame(t, _frames(rng, t))
    times, meshes = read_frames(tmp_path / "ring.pvd")
    assert times.tolist() == [0.0, 0.5] and meshes[1].points.shape == (4, 3)
    frame = tmp_path / "ring" / "frame_00001.vtu"
    frame.write_bytes(frame.read_bytes()[:300])
    with pytest.raises(RunFolderError, match=rf"^{frame}: frame at t = 0.5 s is corrupt \(300 "):
        read_frames(tmp_path / "ring.pvd")
    frame.unlink()
    with pytest.raises(RunFolderError, match=rf"^{frame}: frame at t = 0.5 s is missing"):
        read_frames(tmp_path / "ring.pvd")


def test_a_run_folder_lock_refuses_a_second_holder_and_takes_over_a_dead_ones(tmp_path, caplog):
    lock = RunFolderLock(tmp_path)
    holder = lock_holder(tmp_path)
    assert holder["pid"] == os.getpid() and holder["alive"] is True
    with pytest.raises(
        RunFolderError, match=rf"in use by another bfemp run \(pid {os.getpid()} on"
    ):
        RunFolderLock(tmp_path)  # flock conflicts between two opens, even in one process
    lock.release()
    assert not (tmp_path / LOCK_FILE).exists() and lock_holder(tmp_path) is None
    # the lock file of a killed run: its process has ended, nobody holds the flock
    ended = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"],
        capture_output=True,
        text=True,
        check=True,
    )
    pid = int(ended.stdout)
    record = {"pid": pid, "host": socket.gethostname(), "started": "2026-01-02T03:04:05+00:00"}
    (tmp_path / LOCK_FILE).write_text(json.dumps(record))
    assert lock_holder(tmp_path) is None  # bfemp info: not running
    with caplog.at_level(logging.WARNING, logger="bfemp.io.outputs"):
        lock = RunFolderLock(tmp_path)
    assert "took over the lock" in caplog.text
    assert f"pid {pid} on {socket.gethostname()}, started 2026-01-02T03:04:05+00:00" in caplog.text
    assert json.loads((tmp_path / LOCK_FILE).read_text())["pid"] == os.getpid()
    lock.release()
