"""Every example scene runs in its quick form and satisfies its own [check] table."""

from pathlib import Path

import meshio
import numpy as np
import pytest

import bfemp
from bfemp import scenefile
from bfemp.checkpoint import model_fingerprint
from bfemp.io.vtk import read_pvd
from bfemp.scenefile.checks import CheckRecorder, evaluate_checks

EXAMPLES = sorted((Path(__file__).resolve().parents[2] / "examples").glob("*.toml"))


def test_the_promised_examples_ship():
    names = {p.stem for p in EXAMPLES}
    assert {"cantilever", "mpm_block_slip_floor", "fem_mpm_no_contact"} <= names
    # one scene per quick contact benchmark (rings, slope, hertz, sine_boundary)
    assert {"rings", "slope", "hertz", "sine_boundary"} <= names


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_example_runs_quick_and_passes_its_checks(path, tmp_path):
    sf = scenefile.load(path)
    assert set(sf.check) - {"description", "finite"}, "an example must assert something"
    settings = sf.run_settings(quick=True)
    assert settings["t_end"] < sf.run_settings()["t_end"]
    sim = bfemp.Simulation.from_file(sf)
    recorder = CheckRecorder()
    recorder.record(sim)
    sim.run(
        settings["t_end"], out=tmp_path, every=settings["every"], progress=False, callback=recorder
    )
    results = evaluate_checks(sf.check, sim.metrics, recorder)
    assert results and all(r.ok for r in results), [str(r) for r in results]
    assert recorder.steps == sim.state.step > 0
    # one ParaView collection per body, holding the fields of the last state
    names = [b.name for b in (*sim.model.fem_bodies, *sim.model.mpm_bodies)]
    for body in (*sim.model.fem_bodies, *sim.model.mpm_bodies):
        frames = read_pvd(tmp_path / f"{body.name}.pvd")
        assert frames[0][0] == 0.0 and len(frames) >= 2
        last = meshio.read(frames[-1][1])
        x = body.x(sim.state)
        if frames[-1][0] == sim.state.t:
            assert np.allclose(last.points[:, : x.shape[1]], x)
        data = {**last.point_data, **last.cell_data}
        assert {"velocity", "J", "von_mises"} <= set(data), (body.name, set(data))
    assert len(names) == len(set(names))
    # the run's scene.toml rebuilds the same model (the README's promise for every run folder)
    again = scenefile.load(tmp_path / "scene.toml")
    assert model_fingerprint(again.build_model()) == model_fingerprint(sim.model)
    assert again.simulation["dt"] == sim.dt


def test_a_failing_check_is_reported():
    sf = scenefile.load(EXAMPLES[0])
    sim = bfemp.Simulation.from_file(sf)
    recorder = CheckRecorder()
    recorder.record(sim)
    sim.step()
    recorder(sim)
    check = {"bounds": {"lower": [0.5, -1.0], "upper": [1.0, 1.0]}, "max": {"energy_total": -1.0}}
    results = evaluate_checks(check, sim.metrics, recorder)
    assert [r.ok for r in results] == [False, False]
    assert "FAIL" in str(results[0])
