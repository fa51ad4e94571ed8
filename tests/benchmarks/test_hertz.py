"""Brazilian disk, quick mode: plane Hertz contact F = C a^2 for both materials (section 6.3),
plus the measurement helpers on synthetic data."""

import math

import numpy as np
import pytest

from benchmarks import hertz
from tests.benchmarks._records import check_written, record_fixture

#: started first (tests/conftest.py): one of the suite's longest files
pytestmark = pytest.mark.slow

C_HERTZ = math.pi * 1e10 / (4.0 * (1.0 - 0.3**2) * 1.0)


result = record_fixture("hertz")


def test_writes_json_and_plot(result):
    data = check_written(
        result, "hertz", "materials samples wall_s steps newton_iterations parameters"
    )
    assert set(data["materials"]) == {"linear", "neo_hookean"}
    for run in data["materials"].values():
        assert run["error"] is None
        for key in ("C_fit", "C_hertz", "rel_error"):
            assert math.isfinite(run[key]), key
        assert run["C_hertz"] == pytest.approx(C_HERTZ, rel=1e-12)


def test_fit_matches_hertz(result):
    """(T) least-squares F = C a^2 within 15 % of Hertz's C, both materials (quick mode runs
    one grid step finer than the paper's; measured 1.132 and 1.138)."""
    _, data, _ = result
    assert data["target_met"]
    for name, run in data["materials"].items():
        assert run["fit_samples"] >= 3, name
        assert run["rel_error"] < hertz.TARGET_REL_ERROR, (name, run["C_fit_over_C_hertz"])


def test_force_and_width_grow_with_compression(result):
    _, data, _ = result
    for name, s in data["samples"].items():
        force, a = np.asarray(s["F"]), np.asarray(s["a"])
        assert np.all(np.diff(force) > 0.0), name
        # the width creeps and jumps, but never shrinks by more than a fine-ring spacing
        assert np.all(np.diff(a) > -0.5 * data["parameters"]["spacing"]), name
        # far from a flat punch (F ~ a) or a point load: F / a^2 stays within a factor 2
        sel = a >= hertz.FIT_MIN_CELLS * data["parameters"]["dx"]
        ratio = force[sel] / (C_HERTZ * a[sel] ** 2)
        assert np.all((ratio > 0.5) & (ratio < 2.0)), (name, ratio)


def test_quasi_static_and_no_penetration(result):
    _, data, _ = result
    for name, run in data["materials"].items():
        # the plates push equally on the disk (inertia is negligible at rho = 100)
        assert run["force_balance_max"] < 1e-2, name
        assert 0.0 < run["min_distance"] < hertz.DHAT, name


def test_materials_agree_at_small_deformation(result):
    _, data, _ = result
    lin, nh = data["materials"]["linear"], data["materials"]["neo_hookean"]
    assert lin["C_fit"] == pytest.approx(nh["C_fit"], rel=0.1)


def test_hertz_constant():
    assert hertz.hertz_constant() == pytest.approx(C_HERTZ, rel=1e-14)


def test_disk_particles_fill_the_disk_with_a_fine_circular_rim():
    x, volume, outer = hertz._disk_particles(1.0, 0.05, 4)
    assert volume.sum() == pytest.approx(math.pi, rel=1e-12)
    assert np.all(volume > 0.0)
    assert np.all(np.linalg.norm(x, axis=1) < 1.0)
    # the rim: a circle of radius R - s/8, particles s/4 apart, the first one at the bottom
    assert np.linalg.norm(x[outer], axis=1) == pytest.approx(1.0 - 0.05 / 8, abs=1e-12)
    step = np.linalg.norm(np.diff(x[outer], axis=0), axis=1)
    assert step == pytest.approx(0.05 / 4, rel=1e-2)
    assert x[outer[0]] == pytest.approx([0.0, -1.0 + 0.05 / 8], abs=1e-12)
    assert x[outer[1], 0] > 0.0  # counter-clockwise from the bottom


def test_half_widths_of_a_flattened_circle():
    """A circle of radius R cut by the line y = -R + h: within dhat of it where y < dhat - R + h,
    i.e. |x| < sqrt(2 R (h + dhat)) to first order."""
    radius, h, dhat = 1.0, 2e-3, 1e-4
    theta = -0.5 * np.pi + np.arange(4000) * (2 * np.pi / 4000)
    ring = np.stack([radius * np.cos(theta), radius * np.sin(theta)], axis=1)
    ring[:, 1] = np.maximum(ring[:, 1], -radius + h)  # flattened by a plate at y = -R + h
    y_plate = -radius + h - 0.3 * dhat
    exact = math.sqrt(radius**2 - (radius - h - 0.7 * dhat) ** 2)
    spacing = 2 * np.pi / 4000
    a = hertz.contact_half_width(ring, y_plate, dhat)
    assert exact - spacing <= a <= exact
    assert hertz.interpolated_half_width(ring, y_plate, dhat) == pytest.approx(exact, abs=2e-5)
    assert hertz.contact_half_width(ring, y_plate - 2 * h, dhat) == 0.0
    assert hertz.interpolated_half_width(ring, y_plate - 2 * h, dhat) == 0.0


def test_fit_constant_recovers_c_and_respects_the_range():
    a = np.linspace(0.01, 0.3, 30)
    force = 3.0 * a**2
    force[a > 0.2] *= 2.0  # outside the fit range: ignored
    c, n = hertz.fit_constant(a, force, 0.05, 0.2)
    assert c == pytest.approx(3.0, rel=1e-12)
    assert n == np.count_nonzero((a >= 0.05) & (a <= 0.2))
    assert math.isnan(hertz.fit_constant(a, force, 0.5, 0.6)[0])
