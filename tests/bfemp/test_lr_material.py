"""The bulk/shear hyperelastic law of LR eq. (18): derivatives, closed forms, small-strain limit,
invariance, inverted points, validation, and scenes under the barrier and explicit strategies."""

from __future__ import annotations

import math

import numpy as np
import pytest

import bfemp
from bfemp import scenefile
from bfemp._bulk_shear_kernels import BULK_SHEAR, _pow23_rest, _x_minus_log1p
from bfemp._material_kernels import LINEAR_ELASTIC, NEO_HOOKEAN, MaterialLaw
from bfemp.checkpoint import model_fingerprint
from bfemp.errors import SceneError
from bfemp.materials import BulkShearHyperelastic
from tests.bfemp.conftest import fd_wrt_F
from tests.bfemp.test_materials import _cases, _rotations, assert_frame_indifferent

#: LR §4.1's compression material (K 2450 MPa, G 940 MPa) and the spec's density
LR_BLOCKS = BulkShearHyperelastic(K=2450e6, G=940e6, density=1200.0)


def _reference(F):
    """W, P, sigma of eq. (18) by numpy, from the 3D tensor diag(F, 1) in 2D (plane strain)."""
    n, d = F.shape[0], F.shape[1]
    F3 = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    F3[:, :d, :d] = F
    return F3


def _eq18(F, K, G):
    F3 = _reference(F)
    d = F.shape[1]
    J = np.linalg.det(F3)
    I1 = np.einsum("sij,sij->s", F3, F3)
    W = 0.5 * G * (I1 / J ** (2 / 3) - 3) + 0.5 * K * (0.5 * (J**2 - 1) - np.log(J))
    b = F3 @ np.swapaxes(F3, 1, 2)
    dev_b = b - (I1 / 3)[:, None, None] * np.eye(3)
    sigma = (G * J ** (-5 / 3))[:, None, None] * dev_b + (0.5 * K * (J - 1 / J))[
        :, None, None
    ] * np.eye(3)
    return W, sigma[:, :d, :d]


def _moduli(rng, n):
    """Per-point (mu, lam) of random K, G (nu from about -0.3 to 0.49)."""
    G = rng.uniform(1e5, 1e8, n)
    K = G * rng.uniform(0.5, 50.0, n)
    return G, K - 2 * G / 3, K


@pytest.mark.parametrize("d", [2, 3])
def test_first_piola_matches_energy_finite_differences(d):
    F, _, _ = _cases(d, seed=21)
    mu, lam, _ = _moduli(np.random.default_rng(d), len(F))
    P = BULK_SHEAR.first_piola(F, mu, lam)
    P_fd = fd_wrt_F(lambda G: BULK_SHEAR.energy_density(G, mu, lam), F)
    scale = np.linalg.norm(P, axis=(1, 2)) + 1e-3 * mu
    assert (np.linalg.norm(P - P_fd, axis=(1, 2)) / scale).max() < 1e-6


@pytest.mark.parametrize("d", [2, 3])
def test_piola_derivative_matches_finite_differences_and_is_symmetric(d):
    F, _, _ = _cases(d, seed=23)
    mu, lam, _ = _moduli(np.random.default_rng(10 + d), len(F))
    dP = BULK_SHEAR.first_piola_derivative(F, mu, lam)
    assert dP.shape == (len(F), d, d, d, d)
    dP_fd = fd_wrt_F(lambda G: BULK_SHEAR.first_piola(G, mu, lam), F)
    flat = dP.reshape(len(F), d * d, d * d)
    scale = np.linalg.norm(flat, axis=(1, 2))
    assert (np.linalg.norm((dP - dP_fd).reshape(len(F), -1), axis=1) / scale).max() < 1e-6
    asym = np.abs(flat - flat.transpose(0, 2, 1)).max(axis=(1, 2))
    assert (asym <= 1e-12 * scale).all()


@pytest.mark.parametrize("d", [2, 3])
def test_energy_and_cauchy_stress_match_equation_18_in_plane_strain(d):
    F, _, _ = _cases(d, seed=25)
    mu, lam, K = _moduli(np.random.default_rng(20 + d), len(F))
    W, sigma = _eq18(F, K, mu)
    np.testing.assert_allclose(BULK_SHEAR.energy_density(F, mu, lam), W, rtol=1e-9, atol=1e-6)
    scale = np.abs(sigma).max(axis=(1, 2))[:, None, None]
    closed = BULK_SHEAR.cauchy_stress(F, mu, lam)
    assert (np.abs(closed - sigma) <= 1e-10 * scale).all()
    # sigma = P F^T / J, the generic definition every law inherits
    generic = MaterialLaw.cauchy_stress(BULK_SHEAR, F, mu, lam)
    assert (np.abs(generic - sigma) <= 1e-10 * scale).all()


@pytest.mark.parametrize("d", [2, 3])
def test_rest_state_is_stress_free_and_small_strain_is_linear_elasticity_with_k_and_g(d):
    rng = np.random.default_rng(31)
    mu, lam, K = _moduli(rng, 5)
    identity = np.broadcast_to(np.eye(d), (5, d, d))
    assert np.abs(BULK_SHEAR.energy_density(identity, mu, lam)).max() == 0.0
    assert np.abs(BULK_SHEAR.first_piola(identity, mu, lam)).max() == 0.0
    assert np.abs(BULK_SHEAR.cauchy_stress(identity, mu, lam)).max() == 0.0
    # elasticity tensor at rest: G (d_ik d_jl + d_il d_jk) + (K - 2G/3) d_ij d_kl
    eye = np.eye(d)
    C_ref = mu[:, None, None, None, None] * (
        np.einsum("ik,jl->ijkl", eye, eye) + np.einsum("il,jk->ijkl", eye, eye)
    ) + (K - 2 * mu / 3)[:, None, None, None, None] * np.einsum("ij,kl->ijkl", eye, eye)
    C = BULK_SHEAR.first_piola_derivative(identity, mu, lam)
    np.testing.assert_allclose(C, C_ref, rtol=0, atol=1e-12 * K.max())
    for eps in (1e-3, 1e-5, 1e-7):
        F = identity + eps * rng.standard_normal((5, d, d))
        P = BULK_SHEAR.first_piola(F, mu, lam)
        P_lin = LINEAR_ELASTIC.first_piola(F, mu, lam)
        rel = np.linalg.norm(P - P_lin, axis=(1, 2)) / np.linalg.norm(P_lin, axis=(1, 2))
        assert rel.max() < 100 * eps
        # the energy keeps its relative precision at tiny strains (formed from F - I only)
        psi = BULK_SHEAR.energy_density(F, mu, lam)
        psi_lin = LINEAR_ELASTIC.energy_density(F, mu, lam)
        assert np.abs(psi / psi_lin - 1).max() < 100 * eps


def test_series_helpers_match_their_closed_forms():
    for x in (-0.09, -1e-3, 1e-6, 0.05, 0.0999):
        assert _x_minus_log1p(x) == pytest.approx(x - math.log1p(x), rel=1e-12)
        assert _pow23_rest(x) == pytest.approx((1 + x) ** (2 / 3) - 1 - 2 * x / 3, rel=1e-10)
    # where the closed forms cancel, the series keep the leading term
    assert _x_minus_log1p(1e-9) == pytest.approx(0.5e-18, rel=1e-8)
    assert _pow23_rest(1e-9) == pytest.approx(-1e-18 / 9, rel=1e-8)


@pytest.mark.parametrize("d", [2, 3])
def test_frame_indifference_and_isotropy(d):
    rng = np.random.default_rng(41)
    F, _, _ = _cases(d, seed=43)
    mu, lam, _ = _moduli(rng, len(F))
    R = _rotations(rng, len(F), d)
    assert_frame_indifferent(BULK_SHEAR, F, mu, lam, R)
    sigma = BULK_SHEAR.cauchy_stress(F, mu, lam)
    Rt = np.swapaxes(R, 1, 2)
    rotated = BULK_SHEAR.cauchy_stress(R @ F, mu, lam)
    np.testing.assert_allclose(rotated, R @ sigma @ Rt, atol=1e-10 * np.abs(sigma).max())
    assert np.abs(BULK_SHEAR.energy_density(_rotations(rng, 4, d), 1.0, 1.0)).max() < 1e-12


@pytest.mark.parametrize("d", [2, 3])
def test_inverted_points_are_handled_like_neo_hookean(d):
    F = np.broadcast_to(np.eye(d), (3, d, d)).copy()
    F[1, 0, 0] = -1.0  # reflected: J = -1
    F[2, 0, 0] = 0.0  # collapsed: J = 0
    for law in (BULK_SHEAR, NEO_HOOKEAN):
        psi = law.energy_density(F, 1.0, 1.0)
        assert psi[0] == 0.0 and psi[1] == np.inf and psi[2] == np.inf
        assert np.isfinite(law.first_piola(F, 1.0, 1.0)[0]).all()
        assert np.isnan(law.first_piola(F, 1.0, 1.0)[1:]).all()
        assert np.isnan(law.first_piola_derivative(F, 1.0, 1.0)[1:]).all()
        assert np.isnan(law.cauchy_stress(F, 1.0, 1.0)[1:]).all()
    squeeze = np.broadcast_to(np.eye(d), (4, d, d)).copy()
    squeeze[:, 0, 0] = [1e-1, 1e-3, 1e-6, 1e-9]
    assert (np.diff(BULK_SHEAR.energy_density(squeeze, 1.0, 1.0)) > 0).all()


def test_material_parameters_are_derived_from_k_and_g():
    m = LR_BLOCKS
    K, G = 2450e6, 940e6
    assert m.mu == G and m.lam == pytest.approx(K - 2 * G / 3, rel=1e-15)
    assert m.E == pytest.approx(9 * K * G / (3 * K + G), rel=1e-15)
    assert m.nu == pytest.approx((3 * K - 2 * G) / (2 * (3 * K + G)), rel=1e-15)
    # the same small-strain constants as an isotropic material with these E, nu
    iso = bfemp.LinearElastic(E=m.E, nu=m.nu, density=1200.0)
    assert m.mu == pytest.approx(iso.mu, rel=1e-13) and m.lam == pytest.approx(iso.lam, rel=1e-12)
    assert m.p_wave_speed == pytest.approx(iso.p_wave_speed, rel=1e-13)
    # spec 2.9 lr_compression: E 2500 MPa, nu 0.330, c_K 1428.9 m/s, c_p 1756.7 m/s
    assert m.E == pytest.approx(2500e6, rel=1e-3) and m.nu == pytest.approx(0.330, abs=1e-3)
    assert m.bulk_wave_speed == pytest.approx(1428.9, abs=0.05)
    assert m.p_wave_speed == pytest.approx(1756.7, abs=0.05)
    assert m.law is BULK_SHEAR and m.name == m.law.name == "bulk_shear"
    F = np.eye(2)[None] * 0.98
    np.testing.assert_array_equal(m.cauchy_stress(F), BULK_SHEAR.cauchy_stress(F, m.mu, m.lam))
    assert isinstance(BulkShearHyperelastic(K=np.float32(2), G=1, density=1).K, float)
    with pytest.raises(AttributeError):
        m.K = 1.0  # frozen
    with pytest.raises(TypeError):
        BulkShearHyperelastic(1e9, 1e8, 1000.0)  # keyword-only


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("K", 0.0, r"K must be finite and > 0 \(Pa\)"),
        ("K", -1.0, r"K must be finite and > 0 \(Pa\)"),
        ("G", math.inf, r"G must be finite and > 0 \(Pa\)"),
        ("G", math.nan, r"G must be finite and > 0 \(Pa\)"),
        ("density", 0.0, r"density must be finite and > 0 \(kg/m\^3\)"),
        ("density", "1000", "density must be a real number"),
        ("K", True, "K must be a real number"),
    ],
)
def test_material_validation_names_the_field(field, value, message):
    kwargs = {"K": 1e9, "G": 1e8, "density": 1000.0, field: value}
    with pytest.raises(ValueError, match=f"^BulkShearHyperelastic.{message}"):
        BulkShearHyperelastic(**kwargs)


def test_the_scene_accepts_it_and_refuses_other_objects_by_name():
    scene = bfemp.Scene(dim=2)
    x, vol = bfemp.sample.box((0.0, 0.0), (0.1, 0.1), dx=0.05, ppc=4)
    scene.add_mpm(x, vol, material=LR_BLOCKS, name="block")
    with pytest.raises(ValueError, match="mpm body 'bad': material must be bfemp.NeoHookean"):
        scene.add_mpm(x + 1.0, vol, material="steel", name="bad")


# ---------------------------------------------------------------------------- scenes
SOFT_KG = BulkShearHyperelastic(K=1e7 / 1.2, G=1e7 / 2.6, density=1000.0)  # E 10 MPa, nu 0.3
SOFT_NH = bfemp.NeoHookean(E=SOFT_KG.E, nu=SOFT_KG.nu, density=1000.0)


def _sagging_block(material):
    """A 2 x 1 m FEM block with its bottom fixed and a 1 x 1 m MPM block on a sticky floor,
    both sagging in gravity (strains about rho g h / E = 0.1 %)."""
    scene = bfemp.Scene(dim=2, gravity=(0.0, -9.81))
    mesh = bfemp.shapes.rectangle((0.0, 0.0), (2.0, 1.0), h=0.25)
    scene.add_fem(
        mesh,
        material=material,
        prescribed=bfemp.motion.Fixed(),
        prescribed_nodes=mesh.points[:, 1] < 1e-9,
        name="block",
    )
    x, vol = bfemp.sample.box((3.0, 0.1), (4.0, 1.1), dx=0.1, ppc=4)
    scene.add_mpm(x, vol, material=material, name="cube")
    floor = bfemp.levelset.HalfPlane(point=(0.0, 0.0), normal=(0.0, 1.0))
    scene.add_boundary(floor, kind="sticky")
    scene.set_grid(dx=0.1)
    scene.set_contact(dhat=0.02, kappa=1e5)
    return scene


def test_barrier_newton_runs_it_and_the_small_strain_response_is_neo_hookeans():
    results = {}
    for material in (SOFT_KG, SOFT_NH):
        sim = bfemp.Simulation(_sagging_block(material), dt=0.02, tol=1e-6)
        iterations = [sim.step().newton_iterations for _ in range(5)]
        results[material.name] = (sim.state.fem_x.copy(), sim.state.mpm_x.copy(), iterations)
        assert f"elasticity[{material.name}]" in sim.terms
        assert (np.linalg.det(sim.state.mpm_F) > 0).all()
    x_kg, p_kg, it_kg = results["bulk_shear"]
    x_nh, p_nh, it_nh = results["neo_hookean"]
    model = _sagging_block(SOFT_KG).build()
    u_kg, u_nh = x_kg - model.fem_X, x_nh - model.fem_X
    w_kg, w_nh = p_kg - model.mpm_X, p_nh - model.mpm_X
    assert np.abs(u_nh).max() > 3e-4 and np.abs(w_nh).max() > 3e-4  # both sagged
    # the same small-strain constants: displacements agree to O(strain) (measured: FEM 0.016 %,
    # MPM 0.84 %; 0.2 % and 5.3 % at ten times the strain, E = 1 MPa)
    assert np.abs(u_kg - u_nh).max() < 2e-3 * np.abs(u_nh).max()
    assert np.abs(w_kg - w_nh).max() < 2e-2 * np.abs(w_nh).max()
    # an exact Hessian keeps Newton as quick as with Neo-Hookean
    assert sum(it_kg) <= sum(it_nh) + 2, (it_kg, it_nh)


def test_single_field_compression_stress_follows_the_law():
    """An MPM block squeezed by an initial velocity field v_y = -a y: the mean Cauchy stresses
    after a few explicit steps are compressive and, at small strain, those of Neo-Hookean with
    the same E, nu (measured at the auto dt 1.7e-4 s: within 2.2e-5; a K 5 % larger moves
    sigma_xx by 6 % and sigma_yy by 0.7 %)."""
    stresses = {}
    for material in (SOFT_KG, SOFT_NH):
        scene = bfemp.Scene(dim=2)
        x, vol = bfemp.sample.box((0.0, 0.0), (0.4, 0.4), dx=0.05, ppc=4)
        v = np.zeros_like(x)
        v[:, 1] = -0.02 * x[:, 1]
        scene.add_mpm(x, vol, material=material, velocity=v, name="block")
        scene.set_grid(dx=0.05)
        sim = bfemp.Simulation(scene, strategy="single_field", dt="auto")
        for _ in range(10):
            sim.step()
        F = sim.state.mpm_F
        assert (np.linalg.det(F) > 0).all()
        sigma = material.cauchy_stress(F)
        w = sim.model.mpm_volume * np.linalg.det(F)
        stresses[material.name] = (w @ sigma[:, 0, 0] / w.sum(), w @ sigma[:, 1, 1] / w.sum())
    sxx, syy = stresses["bulk_shear"]
    sxx_nh, syy_nh = stresses["neo_hookean"]
    assert syy < 0.0 and sxx < 0.0
    assert syy == pytest.approx(syy_nh, rel=1e-3) and sxx == pytest.approx(sxx_nh, rel=1e-3)


def test_scene_file_round_trip(tmp_path):
    scene = _sagging_block(LR_BLOCKS)
    text = scenefile.save(scene, tmp_path / "scene.toml")
    assert 'type = "bulk_shear"' in text
    again = scenefile.read_scene(tmp_path / "scene.toml")
    a, b = scene.build(), again.build()
    assert model_fingerprint(a) == model_fingerprint(b)
    assert b.fem_bodies[0].material == LR_BLOCKS and b.mpm_bodies[0].material == LR_BLOCKS


BULK_TOML = """
[scene]
dim = 2

[materials.lr]
type = "bulk_shear"
K = "2450 MPa"
G = "940 MPa"
density = 1200.0

[[mpm]]
name = "block"
material = "lr"
particles = { sample = "box", lower = [0.0, 0.0], upper = [0.1, 0.1], ppc = 4 }

[grid]
dx = 0.05
"""


def test_scene_file_reads_units_and_names_wrong_keys():
    sf = scenefile.loads(BULK_TOML)
    assert sf.scene.build().mpm_bodies[0].material == LR_BLOCKS
    bad = BULK_TOML.replace('G = "940 MPa"', 'E = "940 MPa"')
    with pytest.raises(SceneError, match="unknown key 'E'"):
        scenefile.loads(bad)
    with pytest.raises(SceneError, match="G"):
        scenefile.loads(BULK_TOML.replace('G = "940 MPa"', "G = -1.0"))


def test_von_mises_output_uses_the_law_cauchy_stress():
    from bfemp.io.fields import _von_mises

    F, _, _ = _cases(3, seed=51)
    sigma = LR_BLOCKS.cauchy_stress(F)
    dev = sigma - np.trace(sigma, axis1=1, axis2=2)[:, None, None] * np.eye(3) / 3
    expected = np.sqrt(1.5 * np.einsum("sij,sij->s", dev, dev))
    np.testing.assert_allclose(_von_mises(LR_BLOCKS, F), expected, rtol=1e-12)


def test_the_run_manifest_records_k_and_g():
    from bfemp.manifest import model_summary

    summary = model_summary(_sagging_block(LR_BLOCKS).build())
    recorded = summary["mpm_bodies"][0]["material"]
    assert recorded["type"] == "bulk_shear" and recorded["K"] == 2450e6 and recorded["G"] == 940e6
    assert recorded["E"] == LR_BLOCKS.E and recorded["nu"] == LR_BLOCKS.nu


def test_barrier_3d_block_sags_like_neo_hookean():
    sags = {}
    for material in (SOFT_KG, SOFT_NH):
        scene = bfemp.Scene(dim=3, gravity=(0.0, 0.0, -9.81))
        mesh = bfemp.shapes.box((0.0, 0.0, 0.0), (2.0, 1.0, 1.0), h=0.5)
        bottom = mesh.points[:, 2] < 1e-9
        scene.add_fem(
            mesh, material=material, prescribed=bfemp.motion.Fixed(), prescribed_nodes=bottom
        )
        sim = bfemp.Simulation(scene, dt=0.02, tol=1e-6)
        for _ in range(3):
            assert sim.step().newton_iterations <= 4
        sags[material.name] = sim.state.fem_x - sim.model.fem_X
    ref = np.abs(sags["neo_hookean"]).max()
    assert ref > 1e-4
    assert np.abs(sags["bulk_shear"] - sags["neo_hookean"]).max() < 2e-3 * ref
