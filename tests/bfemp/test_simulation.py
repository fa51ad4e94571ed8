"""The runner: frames and metrics written and readable; the demo; the scipy fallback path."""

import json
from pathlib import Path

import meshio
import numpy as np
import pytest

import bfemp
from bfemp import scenefile
from bfemp.checkpoint import model_fingerprint
from bfemp.demo import colliding_rings_scene, run_cantilever_demo, run_demo
from bfemp.errors import SceneError
from bfemp.io import read_frames, read_metrics
from bfemp.io.snapshots import read_snapshots, snapshot_figure
from bfemp.io.vtk import read_pvd
from bfemp.manifest import run_info
from bfemp.runs import load_run
from solvers.linear import ScipySolver

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


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
    # the scene file the README lists, which rebuilds the demo's model
    model = bfemp.scenefile.read_scene(Path(outputs["scene"])).build()
    assert model_fingerprint(model) == model_fingerprint(colliding_rings_scene().build())
    assert (tmp_path / "snapshots.png").read_bytes()[:8] == PNG_MAGIC
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


def _panels(fig):
    return [ax for ax in fig.axes if ax.get_title().startswith("t = ")]


def test_an_earlier_run_in_the_folder_is_refused_or_replaced_with_overwrite(tmp_path):
    """Stale frames of another mesh are never listed as outputs of a new run."""
    other = bfemp.Simulation(_beam_scene(), dt=1e-2)
    other.run(0.02, out=tmp_path, progress=False)
    (tmp_path / "beam.pvd").rename(tmp_path / "foo.pvd")  # an earlier run of another body
    (tmp_path / "beam").rename(tmp_path / "foo")
    (tmp_path / "notes.txt").write_text("mine")
    sim = bfemp.Simulation(_beam_scene(), dt=1e-2)
    with pytest.raises(SceneError, match="earlier run .*foo.pvd.*overwrite"):
        sim.run(0.02, out=tmp_path, progress=False)
    assert (tmp_path / "foo.pvd").exists() and (tmp_path / "manifest.json").exists()
    sim.run(0.02, out=tmp_path, progress=False, overwrite=True)
    assert not (tmp_path / "foo.pvd").exists() and not (tmp_path / "foo").exists()
    assert (tmp_path / "notes.txt").read_text() == "mine"  # not an output: left alone
    assert run_info(tmp_path)["frames"] == {"beam": 3}


def test_every_run_writes_a_snapshot_sheet_and_an_animation_on_request(tmp_path):
    sim = bfemp.Simulation(_beam_scene(), integrator="newmark", dt=1e-2)
    with pytest.raises(ValueError, match="animation must be 'gif' or 'mp4'"):
        sim.run(0.1, out=tmp_path, progress=False, animation="avi")
    assert not (tmp_path / "manifest.json").exists()  # refused before anything ran
    sim.run(0.1, out=tmp_path, every=1, progress=False, animation="gif")
    assert (tmp_path / "snapshots.png").read_bytes()[:8] == PNG_MAGIC
    snaps = read_snapshots(tmp_path)  # 11 frames: 6 evenly spaced, first and last kept
    assert len(snaps) == 6 and snaps[0].t == 0.0 and snaps[-1].t == sim.state.t
    assert np.allclose(snaps[-1].bodies[0].points, sim.state.fem_x)
    assert len(_panels(snapshot_figure(snaps))) == 6
    from PIL import Image

    with Image.open(tmp_path / "animation.gif") as gif:
        assert gif.format == "GIF" and gif.n_frames == 11


def test_a_run_reads_back_into_python(tmp_path):
    """Frames, metrics and the simulation itself come back from the run folder."""
    sim = bfemp.Simulation(_beam_scene(), integrator="newmark", dt=1e-2)
    sim.run(0.06, out=tmp_path, every=2, progress=False)
    times, meshes = read_frames(tmp_path / "beam.pvd")
    assert np.allclose(times, [0.0, 0.02, 0.04, 0.06])
    assert np.array_equal(meshes[-1].points[:, :2], sim.state.fem_x)
    assert np.array_equal(meshes[-1].point_data["velocity"][:, :2], sim.state.fem_v)
    metrics = read_metrics(tmp_path)
    assert np.array_equal(metrics.column("energy_total"), sim.metrics.column("energy_total"))
    back = load_run(tmp_path)  # from scene.toml (written by the Python run) + checkpoint
    assert scenefile.load(tmp_path / "scene.toml").simulation["integrator"] == "newmark"
    assert back.settings == sim.settings and back.state.step == 6
    assert model_fingerprint(back.model) == model_fingerprint(sim.model)
    assert np.array_equal(back.state.fem_x, sim.state.fem_x)
    back.step()  # and it continues
    assert back.state.step == 7


def test_per_body_metrics_add_up_and_contact_forces_obey_newtons_third_law(tmp_path):
    """The 3D example: an MPM cube landing on a fixed FEM plate."""
    sf = scenefile.load(EXAMPLES / "cube_on_plate_3d.toml")
    sim = bfemp.Simulation.from_file(sf)
    sim.run(0.024, progress=False)
    m = sim.metrics
    for c in "xyz":
        total = m.column(f"body.cube.momentum_{c}") + m.column(f"body.plate.momentum_{c}")
        assert np.allclose(total, m.column(f"momentum_{c}"), rtol=0.0, atol=1e-12)
    for kind in ("kinetic", "elastic", "gravity"):
        total = m.column(f"body.cube.energy_{kind}") + m.column(f"body.plate.energy_{kind}")
        assert np.allclose(total, m.column(f"energy_{kind}"), rtol=1e-12, atol=1e-12)
    on_cube = np.stack([m.column(f"contact_force.cube.plate_{c}") for c in "xyz"], axis=1)
    on_plate = np.stack([m.column(f"contact_force.plate.cube_{c}") for c in "xyz"], axis=1)
    touching = m.column("contact_pairs") > 0
    assert touching.any() and np.all(on_cube[touching, 2] > 0.0)  # the plate pushes up
    assert np.allclose(on_cube + on_plate, 0.0, atol=1e-9 * np.abs(on_cube).max())
    assert np.all(on_cube[~touching[:, None].repeat(3, 1)] == 0.0)
    # the same total as the per-particle forces of Simulation.contact_forces()
    fem, mpm = sim.contact_forces()
    assert np.allclose(mpm.sum(axis=0), on_cube[-1], rtol=1e-10, atol=1e-12)
    assert np.allclose(fem.sum(axis=0), on_plate[-1], rtol=1e-10, atol=1e-12)


def test_contact_forces_are_attributed_to_the_pair_of_bodies_that_touch():
    """Two MPM blocks fall onto one FEM floor; only the lower one lands within the run."""
    scene = bfemp.Scene(dim=2, gravity=(0.0, -9.81))
    mat = bfemp.NeoHookean(E=1e4, nu=0.3, density=500.0)
    floor = bfemp.shapes.rectangle((-0.5, -0.2), (1.5, 0.0), h=0.1)
    scene.add_fem(floor, material=mat, prescribed=bfemp.motion.Fixed(), name="floor")
    for name, y0 in (("low", 0.02), ("high", 0.4)):
        x0 = 0.0 if name == "low" else 0.8
        x, vol = bfemp.sample.box((x0, y0), (x0 + 0.3, y0 + 0.3), dx=0.1, ppc=4)
        scene.add_mpm(x, vol, material=mat, velocity=(0.0, -1.0), name=name)
    scene.set_grid(dx=0.1)
    scene.set_contact(dhat=1e-3, kappa=1e4)
    sim = bfemp.Simulation(scene, dt=1e-2, tol=1e-7)
    sim.run(0.08, progress=False)
    m = sim.metrics

    def force(a, b):
        return np.stack([m.column(f"contact_force.{a}.{b}_{c}") for c in "xy"], axis=1)

    assert "contact_force.low.high_x" not in m  # particles never touch particles
    low, high = force("low", "floor"), force("high", "floor")
    assert np.any(low[:, 1] > 0.0) and np.all(low[:, 1] >= 0.0)  # the floor pushes up
    assert np.all(high == 0.0)  # the high block is still in the air
    for a, b in (("low", "floor"), ("high", "floor")):
        assert np.allclose(force(a, b), -force(b, a), rtol=0.0, atol=1e-12)
    # the pair totals are the per-particle forces of Simulation.contact_forces() summed by body
    _, mpm = sim.contact_forces()
    for body in sim.model.mpm_bodies:
        total = mpm[body.particles].sum(axis=0)
        assert np.allclose(total, force(body.name, "floor")[-1], rtol=1e-10, atol=1e-12)


def test_a_run_after_a_step_writes_its_start_state_as_the_first_frame(tmp_path):
    """Issue 42 (minor): the README's first snippet steps once, then runs with every=5; the run's
    frames began at step 5, so the state the run started from was never seen."""
    from bfemp.io import read_pvd

    scene = bfemp.Scene(dim=2, gravity=(0.0, -9.81))
    mesh = bfemp.shapes.rectangle((0.0, 0.0), (1.0, 0.25), h=0.25)
    scene.add_fem(mesh, material=bfemp.NeoHookean(E=1e6, nu=0.3, density=1000.0), name="b")
    sim = bfemp.Simulation(scene, integrator="backward_euler", dt=1e-2)
    sim.step()
    start = sim.state.t
    sim.run(t_end=start + 0.1, out=tmp_path / "run", every=5)
    times = [t for t, _ in read_pvd(tmp_path / "run" / "b.pvd")]
    assert times[0] == pytest.approx(start)
    assert times[1:] == pytest.approx([start + 0.04, start + 0.09])  # steps 5 and 10
