"""Physics of the implicit FEM core: free fall, static bars, energy behaviour, momentum, det F."""

import numpy as np
import pytest

import bfemp
from bfemp.scene import Scene

NH = bfemp.NeoHookean(E=1e6, nu=0.3, density=1000.0)


def _com(model, x):
    return model.fem_mass @ x / model.fem_mass.sum()


@pytest.mark.parametrize("dim", [2, 3])
def test_free_fall_centre_of_mass_follows_backward_euler_exactly(dim):
    g = np.zeros(dim)
    g[-1] = -9.81
    scene = Scene(dim=dim, gravity=tuple(g))
    mesh = (
        bfemp.shapes.rectangle((0, 0), (1.0, 0.5), h=0.25)
        if dim == 2
        else bfemp.shapes.box((0, 0, 0), (1.0, 0.5, 0.5), h=0.5)
    )
    v0 = np.zeros((mesh.points.shape[0], dim))
    v0[:, 0] = 1.0 + 0.3 * mesh.points[:, 1]  # shear: elastic forces act, but are internal
    scene.add_fem(mesh, material=NH, velocity=v0)
    dt = 0.01
    sim = bfemp.Simulation(scene, integrator="backward_euler", dt=dt, tol=1e-10)
    com, vcom = _com(sim.model, sim.state.fem_x), _com(sim.model, sim.state.fem_v)
    for _ in range(20):
        sim.step()
        vcom = vcom + dt * g  # BE: v^{n+1} = v^n + dt g, x^{n+1} = x^n + dt v^{n+1}
        com = com + dt * vcom
    assert np.allclose(_com(sim.model, sim.state.fem_v), vcom, rtol=0, atol=1e-12)
    assert np.allclose(_com(sim.model, sim.state.fem_x), com, rtol=0, atol=1e-10)


def _consistent_end_load(mesh, dim, length, traction):
    """Nodal forces (n, d) of a uniform traction on the face x = length (consistent lumping)."""
    force = np.zeros((mesh.points.shape[0], dim))
    facets = mesh.boundary_edges if dim == 2 else mesh.boundary_faces
    on_end = np.all(np.abs(mesh.points[facets, 0] - length) < 1e-9, axis=1)
    facets = facets[on_end]
    p = mesh.points[facets]
    if dim == 2:
        size = np.linalg.norm(p[:, 1] - p[:, 0], axis=1)
    else:
        size = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    np.add.at(force, facets.ravel(), np.repeat(size / dim, dim)[:, None] * traction)
    return force


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("material_cls", [bfemp.LinearElastic, bfemp.NeoHookean])
def test_bar_under_end_load_matches_linear_elastic_static_solution(dim, material_cls):
    length, width, E, sigma = 2.0, 0.25, 1e7, 1e3  # strain 1e-4: the linear regime
    if dim == 2:
        mesh = bfemp.shapes.rectangle((0, 0), (length, width), h=0.125)
        area = width
    else:
        mesh = bfemp.shapes.box((0, 0, 0), (length, width, width), h=0.125)
        area = width * width
    scene = Scene(dim=dim)
    traction = np.zeros(dim)
    traction[0] = sigma
    body = scene.add_fem(
        mesh,
        material=material_cls(E=E, nu=0.0, density=1000.0),
        prescribed=bfemp.motion.Fixed(),
        prescribed_nodes=mesh.points[:, 0] < 1e-9,
    )
    load = _consistent_end_load(mesh, dim, length, traction)
    scene.add_load(body, load)
    assert np.isclose(load[:, 0].sum(), sigma * area)
    # One backward-Euler step with a huge dt is the static solve (inertia ~ rho/dt^2 -> 0).
    sim = bfemp.Simulation(scene, integrator="backward_euler", dt=1e3, tol=1e-14)
    sim.step()
    end = np.abs(mesh.points[:, 0] - length) < 1e-9
    tip = (sim.state.fem_x - mesh.points)[end, 0].mean()
    expected = sigma * length / E  # u = P L / (E A)
    assert abs(tip - expected) < 0.01 * expected


def _vibrating_cantilever(integrator, periods=10):
    length, height = 2.0, 0.2
    mesh = bfemp.shapes.rectangle((0, 0), (length, height), h=0.1)
    scene = Scene(dim=2)
    v0 = np.zeros_like(mesh.points)
    v0[:, 1] = 0.3 * (mesh.points[:, 0] / length) ** 2
    mat = bfemp.NeoHookean(E=1e6, nu=0.3, density=1000.0)
    scene.add_fem(
        mesh,
        material=mat,
        velocity=v0,
        prescribed=bfemp.motion.Fixed(),
        prescribed_nodes=mesh.points[:, 0] < 1e-9,
    )
    # Euler-Bernoulli first mode (plane strain modulus); linear triangles are a bit stiffer.
    e_plane = mat.E / (1 - mat.nu**2)
    omega = 1.875**2 * np.sqrt(e_plane * height**3 / 12 / (mat.density * height * length**4))
    period = 2 * np.pi / omega
    dt = period / 40
    sim = bfemp.Simulation(scene, integrator=integrator, dt=dt, tol=1e-9)
    sim.run(periods * period, progress=False)
    return sim.metrics.column("energy_total"), sim


def test_newmark_keeps_energy_within_one_percent_over_ten_periods():
    energy, sim = _vibrating_cantilever("newmark")
    assert np.all(np.isfinite(energy))
    drift = np.max(np.abs(energy - energy[0])) / energy[0]
    assert drift < 0.01, drift
    # it really vibrated: elastic energy took most of the energy at some point
    assert np.nanmax(sim.metrics.column("energy_elastic")) > 0.5 * energy[0]


def test_backward_euler_dissipates_the_same_vibration():
    energy, _ = _vibrating_cantilever("backward_euler")
    assert energy[-1] < 0.7 * energy[0]
    assert np.all(np.diff(energy) < 1e-9 * energy[0])  # monotone decay, never gains


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("integrator", ["newmark", "backward_euler"])
def test_free_body_conserves_linear_momentum_to_round_off(dim, integrator, rng):
    mesh = (
        bfemp.shapes.rectangle((0, 0), (1.0, 0.5), h=0.25)
        if dim == 2
        else bfemp.shapes.box((0, 0, 0), (1.0, 0.5, 0.5), h=0.5)
    )
    scene = Scene(dim=dim)
    scene.add_fem(mesh, material=NH, velocity=5.0 * rng.standard_normal(mesh.points.shape))
    sim = bfemp.Simulation(scene, integrator=integrator, dt=5e-3, tol=1e-6)
    p0 = sim.model.fem_mass @ sim.state.fem_v
    scale = sim.model.fem_mass @ np.linalg.norm(sim.state.fem_v, axis=1)
    for _ in range(15):
        sim.step()
    p = sim.model.fem_mass @ sim.state.fem_v
    assert np.max(np.abs(p - p0)) < 1e-13 * scale


def _spin_drift(dt, t_end=0.2):
    mesh = bfemp.shapes.rectangle((-0.5, -0.25), (0.5, 0.25), h=0.125)
    scene = Scene(dim=2)
    spin = 20.0 * np.column_stack([-mesh.points[:, 1], mesh.points[:, 0]])
    scene.add_fem(mesh, material=bfemp.NeoHookean(E=1e5, nu=0.3, density=100.0), velocity=spin)
    sim = bfemp.Simulation(scene, integrator="newmark", dt=dt, tol=1e-10)
    sim.run(t_end, progress=False)
    lz = sim.metrics.column("angular_momentum_z")
    return np.max(np.abs(lz - lz[0])) / abs(lz[0])


def test_newmark_angular_momentum_error_is_second_order_in_dt():
    """Newmark is not exactly angular-momentum conserving; its error is O(dt^2)."""
    coarse, fine = _spin_drift(4e-3), _spin_drift(2e-3)
    assert fine < 2e-3
    assert coarse / fine > 3.0, (coarse, fine)


def test_det_f_guard_keeps_j_positive_through_violent_compression():
    mesh = bfemp.shapes.rectangle((0, 0), (1.0, 1.0), h=0.25)
    scene = Scene(dim=2)
    v0 = np.zeros_like(mesh.points)
    v0[:, 1] = -100.0 * mesh.points[:, 1]
    scene.add_fem(
        mesh,
        material=bfemp.NeoHookean(E=1e5, nu=0.3, density=1000.0),
        velocity=v0,
        prescribed=bfemp.motion.Fixed(),
        prescribed_nodes=mesh.points[:, 1] < 1e-9,
    )
    sim = bfemp.Simulation(scene, integrator="backward_euler", dt=0.1, tol=1e-6)
    min_j = []
    for _ in range(5):
        report = sim.step()
        assert report.success
        x = sim.state.fem_x[sim.model.fem_cells]
        F = np.einsum("mai,maj->mij", x, sim.model.fem_cell_grad)
        min_j.append(np.linalg.det(F).min())
    assert min(min_j) > 0.0
    assert min_j[0] < 0.2  # the first step really crushed the block (an undefended step inverts)


def test_newmark_with_implicit_contact_is_newmark_without_contact():
    """Implicit contact changes only how contact forces enter: a contact-free vibration follows
    mid-point Newmark to the last bit."""
    plain, _ = _vibrating_cantilever("newmark", periods=2)
    implicit, _ = _vibrating_cantilever("newmark_implicit_contact", periods=2)
    assert np.array_equal(plain, implicit)


def test_implicit_contact_needs_gamma_twice_beta():
    from bfemp.integrators import Integrator

    with pytest.raises(ValueError, match="gamma = 2 beta"):
        Integrator(name="x", alpha=0.5, beta=0.3025, gamma=0.55, implicit_contact=True)
    with pytest.raises(ValueError, match="newmark_implicit_contact"):  # the names are listed
        bfemp.integrators.integrator_from_name("implicit_contact")
