"""Sine boundary on an MPM box, quick mode (section 6.2, figure 8): the BFEMP boundary lets no
particle in and never pulls the box while lifting off; the level-set slip boundary, run along the
same path, shows both artefacts (particles inside it, adhesion)."""

import pytest

from benchmarks import sine_boundary
from tests.benchmarks._records import check_written, record_fixture

pytestmark = pytest.mark.slow


result = record_fixture("sine_boundary")


def test_writes_json_and_plot(result):
    data = check_written(
        result,
        "sine_boundary",
        "penetrations max_tensile_force levelset wall_s steps",
        png_bytes=20_000,
    )
    for key in ("penetrations", "max_tensile_force"):
        assert key in data["levelset"], key
    assert data["bfemp"]["error"] is None and data["levelset"]["error"] is None


def test_boundary_presses_drags_and_lifts_off(result):
    """The run is meaningful: the boundary carries a load many times the box's weight in both
    treatments; the BFEMP boundary lets go during the upward phase, the level set holds on
    longer (it drags the box up with it)."""
    _, data, _ = result
    bf, ls = data["bfemp"], data["levelset"]
    geo = sine_boundary.Geometry(scale=data["parameters"]["scale"])
    weight = geo.box**2 * sine_boundary.MATERIAL["density"] * sine_boundary.GRAVITY
    for run in (bf, ls):
        assert run["max_compressive_force"] > 10.0 * weight
    assert 0.0 < bf["min_distance"] < sine_boundary.DHAT
    assert geo.t_up < bf["separation_t"] < bf["t_end"]
    assert ls["separation_t"] > bf["separation_t"] + 0.1 * geo.scale


def test_bfemp_no_penetration_no_adhesion(result):
    _, data, _ = result
    bf = data["bfemp"]
    assert data["penetrations"] == 0
    assert bf["max_penetration_depth"] == 0.0
    # the barrier only pushes: no net pull on the box, nor on any particle, at any step
    scale = bf["max_compressive_force"]
    assert data["max_tensile_force"] <= 1e-9 * scale
    assert bf["max_tensile_force_any_phase"] <= 1e-9 * scale
    assert bf["max_particle_tensile_force"] <= 1e-9 * scale
    # the stiff strip's wavy surface follows its scripted path to well within d-hat
    assert bf["strip_surface_deviation_m"] < sine_boundary.DHAT


def test_levelset_shows_penetration_and_adhesion(result):
    _, data, _ = result
    ls = data["levelset"]
    assert ls["penetrations"] > 0
    assert ls["max_penetration_depth"] > sine_boundary.DHAT
    # slip nodes follow the receding boundary: the box is pulled, by a sizeable force
    assert ls["max_tensile_force"] > 0.05 * ls["max_compressive_force"]
