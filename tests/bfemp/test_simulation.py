"""The runner: frames and metrics written and readable; the demo; the scipy fallback path."""

import json
from pathlib import Path

import meshio
import numpy as np

import bfemp
from bfemp.demo import run_cantilever_demo, run_demo
from bfemp.io.vtk import read_pvd
from solvers.linear import ScipySolver


def _beam_scene():
    mesh = bfemp.shapes.rectangle((0, 0), (1.0, 0.2), h=0.1)
    scene = bfemp.Scene(dim=2, gravity=(0.0, -9.81))
    scene.add_fem(
        mesh,
        material=bfemp.NeoHookean(E=1e5, nu=0.3, density=500.0),
        name="beam",
        prescribed=bfemp.motion.Fixed(),
        prescribed_nodes=mesh.points[:, 0] < 1e-9,
    )
    return scene


def test_run_writes_readable_frames_metrics_and_plot(tmp_path):
    sim = bfemp.Simulation(_beam_scene(), integrator="newmark", dt=1e-2)
    metrics = sim.run(0.1, out=tmp_path, every=5, progress=False)
    frames = read_pvd(tmp_path / "beam.pvd")
    assert [round(t, 9) for t, _ in frames] == [0.0, 0.05, 0.1]
    last = meshio.read(frames[-1][1])
    assert np.allclose(last.points[:, :2], sim.state.fem_x)
    assert np.allclose(last.point_data["velocity"][:, :2], sim.state.fem_v)
    j = last.cell_data["J"][0]
    assert np.all(j > 0) and np.any(np.abs(j - 1) > 1e-6)
    assert np.all(last.cell_data["von_mises"][0] >= 0)
    assert len(metrics) == 11 and metrics.column("t")[-1] == sim.state.t
    assert (tmp_path / "metrics.csv").exists() and (tmp_path / "metrics.png").exists()
    # the beam sags: gravitational energy went into kinetic and elastic energy
    assert metrics.column("energy_gravity")[-1] < metrics.column("energy_gravity")[0]
    assert np.all(metrics.column("iterations_newton")[1:] >= 1)


def test_scipy_fallback_gives_the_same_trajectory_as_cholmod():
    a = bfemp.Simulation(_beam_scene(), dt=1e-2, tol=1e-10)
    b = bfemp.Simulation(_beam_scene(), dt=1e-2, tol=1e-10, linear_solver=ScipySolver())
    for _ in range(5):
        a.step()
        b.step()
    assert np.allclose(a.state.fem_x, b.state.fem_x, atol=1e-11)


def test_rings_demo_writes_its_outputs_conserves_momentum_and_keeps_the_rings_apart(tmp_path):
    summary = run_demo(tmp_path, t_end=0.04, progress=False)  # contact starts at 0.025 s
    outputs = summary["outputs"]
    for path in (*outputs["frames"], outputs["metrics"], *outputs["plots"], outputs["summary"]):
        assert Path(path).exists(), path
    assert json.loads(Path(outputs["summary"]).read_text())["steps"] == summary["steps"] == 20
    assert summary["contact_window_s"] is not None  # the rings did meet
    assert 0.0 < summary["min_distance"] < 1e-2  # inside the barrier's range, never touching
    assert summary["momentum_drift_rel"] < 1e-9


def test_cantilever_demo_writes_its_outputs_and_conserves_energy(tmp_path):
    summary = run_cantilever_demo(tmp_path, t_end=0.5, progress=False)
    outputs = summary["outputs"]
    for path in (outputs["frames"], outputs["metrics"], *outputs["plots"]):
        assert Path(path).exists(), path
    assert (tmp_path / "beam.pvd").exists() and (tmp_path / "demo.png").exists()
    e0, e1 = summary["energy_total_first"], summary["energy_total_last"]
    assert abs(e1 - e0) < 1e-2 * abs(e0)
    assert summary["min_tip_deflection_m"] < -0.1


def test_warm_start_reaches_the_same_trajectory():
    """Starting Newton from the predicted x^{n+1} changes where it starts, not where it stops:
    a swinging beam (no contact) and its positions agree to the tolerance."""
    runs = {}
    for warm in (False, True):
        sim = bfemp.Simulation(
            _beam_scene(), integrator="newmark", dt=1e-2, tol=1e-9, warm_start=warm
        )
        sim.run(0.2, progress=False)
        runs[warm] = sim
    assert runs[True].settings["warm_start"] and not runs[False].settings["warm_start"]
    x_cold, x_warm = runs[False].state.fem_x, runs[True].state.fem_x
    assert np.abs(x_warm - x_cold).max() < 1e-8  # tol 1e-9 m/s x dt x 20 steps, with margin
    its = {w: np.nansum(s.metrics.column("iterations_newton")) for w, s in runs.items()}
    assert its[True] <= its[False]
