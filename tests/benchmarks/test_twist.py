"""3D twist with friction, quick mode (paper section 6.7): a FEM shell pressed into an MPM cube
and twisted; the cube's top follows the shell until it slips, later the larger mu. Also the
pieces: the shell meshes of the modes, the press-then-twist motion, the twist measure and the
slip criterion."""

import json
import math

import numpy as np
import pytest

from benchmarks import twist
from tests.benchmarks._records import check_written, record_fixture

QUICK_MUS = (0.0, 0.2)  # mu = 0.5 and 1 (the longest cases: 102 and 177 s) are in the record only


@pytest.mark.parametrize("mode", list(twist.MODES))
def test_shell_mesh_is_positive_closed_and_sized_like_the_paper(mode):
    mesh, center = twist.shell_mesh(twist.MODES[mode]["shell_h"])
    assert np.all(mesh.signed_volumes() > 0)
    r = np.linalg.norm(mesh.points - center, axis=1)
    assert r.min() == pytest.approx(0.45, abs=1e-12) and r.max() == pytest.approx(0.5, abs=1e-12)
    # closed boundary: every edge of a boundary triangle is shared by exactly two of them
    tri = mesh.boundary_facets
    edges = np.sort(tri[:, [[0, 1], [1, 2], [2, 0]]].reshape(-1, 2), axis=1)
    _, use = np.unique(edges, axis=0, return_counts=True)
    assert np.all(use == 2)
    # the shell's lowest node is d-hat above the cube's top face: its south pole
    assert np.hypot(*mesh.points[np.argmin(mesh.points[:, 2]), :2]) < 1e-12
    assert mesh.points[:, 2].min() - twist.CUBE_EDGE == pytest.approx(twist.DHAT, rel=1e-9)
    if mode == "full":
        paper_v, paper_t = twist.PAPER["shell_vertices"], twist.PAPER["shell_tetrahedra"]
        assert abs(mesh.n_points / paper_v - 1.0) < 0.15
        assert abs(mesh.n_cells / paper_t - 1.0) < 0.15


def test_shell_motion_presses_then_turns_about_z():
    omega = math.pi / 5.0
    motion = twist.shell_motion(omega)
    x0 = np.array([[0.3, 0.1, 1.6], [-0.2, 0.4, 1.9], [0.0, 0.0, 2.0]])
    down = x0 - [0.0, 0.0, twist.PRESS_SPEED * twist.PRESS_TIME]
    np.testing.assert_allclose(motion.positions(x0, twist.PRESS_TIME), down, atol=1e-14)
    v = motion.velocities(x0, 0.5 * twist.PRESS_TIME)
    np.testing.assert_allclose(v, np.tile([0.0, 0.0, -twist.PRESS_SPEED], (3, 1)), atol=1e-14)
    tau = 1.7
    x = motion.positions(x0, twist.PRESS_TIME + tau)
    # rigid rotation about the z axis by omega tau: heights and axis distances kept
    np.testing.assert_allclose(x[:, 2], down[:, 2], atol=1e-14)
    np.testing.assert_allclose(np.hypot(x[:, 0], x[:, 1]), np.hypot(down[:, 0], down[:, 1]))
    turned = np.arctan2(x[:2, 1], x[:2, 0]) - np.arctan2(down[:2, 1], down[:2, 0])
    np.testing.assert_allclose(np.mod(turned, 2 * math.pi), omega * tau, atol=1e-12)
    v = motion.velocities(x0, twist.PRESS_TIME + tau)
    np.testing.assert_allclose(v, omega * np.cross([0.0, 0.0, 1.0], x), atol=1e-12)


def test_top_twist_measures_a_rigid_turn_and_ignores_the_rest():
    rng = np.random.default_rng(3)
    x0 = np.column_stack([rng.uniform(-0.5, 0.5, (400, 2)), rng.uniform(0.0, 1.0, 400)])
    x0[:50, 2] = 1.0  # the top layer
    measure = twist.TopTwist(x0, spacing=0.05)
    assert 0 < measure.region.size < 50
    a = 0.7 * math.pi
    rot = np.array([[math.cos(a), -math.sin(a), 0.0], [math.sin(a), math.cos(a), 0.0], [0, 0, 1]])
    x = x0.copy()
    x[measure.region] = x0[measure.region] @ rot.T
    x[~np.isin(np.arange(400), measure.region)] += 0.3  # particles outside the region move freely
    assert measure(x) == pytest.approx(a, abs=1e-12)


def test_slip_onset_finds_the_stall_and_none_without_it():
    dt, omega, t_press = 0.01, 1.0, 0.5
    t = np.arange(0.0, 3.0 + 0.5 * dt, dt)
    shell = omega * np.maximum(t - t_press, 0.0)
    stall = np.minimum(shell, 1.2)  # follows to 1.2 rad at t = 1.7 s, then stays
    t_s, angle = twist.slip_onset(t, stall, omega, t_press, dt)
    assert angle == pytest.approx(1.2 - 0.5 * omega * twist.SLIP_WINDOW_S, abs=2 * dt)
    assert t_s == pytest.approx(1.7 - 0.5 * twist.SLIP_WINDOW_S, abs=2 * dt)
    assert twist.slip_onset(t, 0.97 * shell, omega, t_press, dt) == (None, None)
    assert twist.slip_onset(t, 0.0 * shell, omega, t_press, dt)[1] == 0.0
    assert twist.slip_ordered([0.0, 0.3, None]) and not twist.slip_ordered([0.3, 0.3, 0.5])
    assert not twist.slip_ordered([None, None])


result = record_fixture("twist", mus=QUICK_MUS)


def test_writes_json_and_plot(result):
    data = check_written(
        result, "twist_quick", "slip_angle_pi wall_s peak_memory_mb parameters paper"
    )
    assert [case["mu"] for case in data["cases"]] == list(QUICK_MUS)


def test_every_case_presses_and_twists_without_touching(result):
    _, data, _ = result
    assert data["failed_cases"] == []
    for case in data["cases"]:
        assert case["error"] is None, case["error"]
        assert case["t_end_s"] > twist.PRESS_TIME  # reached the twist
        assert 0.0 < case["min_distance_m"] < twist.DHAT, case["mu"]


def test_the_cube_follows_the_shell_until_it_slips(result):
    _, data, _ = result
    for case in data["cases"]:
        s = case["series"]
        t, cube, shell = (np.array(s[k]) for k in ("t_s", "cube_angle_rad", "shell_angle_rad"))
        assert case["slip_time_s"] is not None, case["mu"]  # every quick case slips
        t_s = case["slip_time_s"]
        k = int(np.argmin(np.abs(t - t_s)))
        assert cube[k] == pytest.approx(case["slip_angle_rad"], abs=1e-12)
        if case["mu"] > 0:
            # sticking: the top turns with the shell, within the cube's elastic lag early on
            # and the partial slip (from the rim of the contact patch in) near the onset
            early = shell <= 0.5 * case["slip_angle_rad"]
            assert np.all(cube[early] >= 0.9 * shell[early] - 1e-3), case["mu"]
            assert np.all(cube[: k + 1] >= 0.75 * shell[: k + 1] - 1e-3), case["mu"]
            assert case["slip_angle_rad"] > 0.05 * math.pi, case["mu"]
        else:
            # no friction: the shell turns over the cube's top
            assert abs(case["max_cube_angle_pi"]) < 0.02
        # slipping: the shell runs ahead of the cube
        lag = shell - cube
        omega = data["parameters"]["omega"]
        assert lag[-1] - lag[k] > 0.25 * omega * (t[-1] - t_s), case["mu"]


def test_slip_angle_increases_with_friction(result):
    _, data, _ = result
    angles = [data["slip_angle_pi"][str(mu)] for mu in QUICK_MUS]
    assert twist.slip_ordered(angles), angles
    assert data["slip_increases_with_mu"]


def test_records_of_cases_run_apart_merge_into_the_record_of_one_run(result, tmp_path):
    _, data, _ = result
    # one record per mu, in reverse order, as processes run side by side would write them
    paths = []
    for k, case in enumerate(reversed(data["cases"])):
        part = {**data, "cases": [case], "wall_s": case["wall_s"]}
        paths.append(tmp_path / f"part{k}.json")
        paths[-1].write_text(json.dumps(part))
    merged = twist.merge(paths, tmp_path / "merged")
    assert [c["mu"] for c in merged["cases"]] == sorted(QUICK_MUS)
    assert merged["slip_angle_pi"] == data["slip_angle_pi"]
    assert merged["slip_increases_with_mu"] == data["slip_increases_with_mu"]
    assert merged["wall_s"] == pytest.approx(sum(c["wall_s"] for c in data["cases"]))
    assert (tmp_path / "merged" / "twist_quick.png").stat().st_size > 0
    with pytest.raises(ValueError, match="one mode"):
        twist.merge([paths[0], _with_mode(tmp_path, data, "partial")], tmp_path / "bad")


def _with_mode(tmp_path, data, mode):
    path = tmp_path / f"mode_{mode}.json"
    path.write_text(json.dumps({**data, "mode": mode}))
    return path


def test_probe_rates_are_per_newton_iteration_of_the_chosen_steps():
    """The probe's per-iteration phases: summed over the chosen steps (in contact, the first
    step left out) and divided by their Newton iterations, not averaged per step."""
    series = {
        "step_newton_iterations": [3, 2, 8],
        "step_phase_s": {"hessian": [30.0, 1.0, 4.0], "factorize": [9.0, 2.0, 8.0]},
        "step_hessian_phases_s": [{"a": 20.0}, {"a": 0.5, "stack": 0.1}, {"a": 3.5}],
    }
    steps = np.array([False, True, True])
    phases, split = twist.per_newton_iteration(series, steps)
    assert phases == {"hessian": pytest.approx(0.5), "factorize": pytest.approx(1.0)}
    assert split == {"a": pytest.approx(0.4), "stack": pytest.approx(0.01)}
    none, _ = twist.per_newton_iteration(series, np.zeros(3, dtype=bool))
    assert none == {"hessian": None, "factorize": None}
