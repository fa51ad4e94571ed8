"""Material parameters and pointwise laws: derivatives, rest state, invariance, validation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bfemp._material_kernels import LINEAR_ELASTIC, NEO_HOOKEAN
from bfemp.materials import LinearElastic, NeoHookean
from tests.bfemp.conftest import fd_wrt_F

LAWS = [NEO_HOOKEAN, LINEAR_ELASTIC]
MATERIALS = [NeoHookean, LinearElastic]


def _rotations(rng, n, d):
    """Random proper rotations (n, d, d) from QR of Gaussian matrices."""
    q, r = np.linalg.qr(rng.standard_normal((n, d, d)))
    q = q * np.sign(np.diagonal(r, axis1=1, axis2=2))[:, None, :]
    flip = np.linalg.det(q) < 0
    q[flip, :, 0] *= -1.0
    return q


def _near_identity(rng, n, d):
    return np.eye(d) + 0.05 * rng.standard_normal((n, d, d))


def _strongly_deformed(rng, n, d):
    """F = R1 diag(s) R2 (I + shear) with J in [0.2, 3], large rotations and shear up to 1.5."""
    log_s = rng.uniform(-0.8, 0.8, (n, d))
    log_j = rng.uniform(math.log(0.2), math.log(3.0), n)
    log_s += ((log_j - log_s.sum(axis=1)) / d)[:, None]
    stretch = np.zeros((n, d, d))
    idx = np.arange(d)
    stretch[:, idx, idx] = np.exp(log_s)
    shear = np.broadcast_to(np.eye(d), (n, d, d)).copy()
    shear[:, 0, 1] = rng.uniform(-1.5, 1.5, n)
    F = _rotations(rng, n, d) @ stretch @ _rotations(rng, n, d) @ shear
    J = np.linalg.det(F)
    assert J.min() > 0.19 and J.max() < 3.01
    return F


def _lame(rng, n):
    E = rng.uniform(1e5, 1e8, n)
    nu = rng.uniform(0.0, 0.45, n)
    return E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))


def _cases(d, n=40, seed=0):
    rng = np.random.default_rng(seed + d)
    F = np.concatenate([_near_identity(rng, n, d), _strongly_deformed(rng, n, d)])
    mu, lam = _lame(rng, 2 * n)
    return F, mu, lam


@pytest.mark.parametrize("law", LAWS, ids=lambda law: law.name)
@pytest.mark.parametrize("d", [2, 3])
def test_first_piola_matches_energy_finite_differences(law, d):
    F, mu, lam = _cases(d)
    P = law.first_piola(F, mu, lam)
    P_fd = fd_wrt_F(lambda G: law.energy_density(G, mu, lam), F)
    scale = np.linalg.norm(P, axis=(1, 2)) + 1e-3 * mu
    err = np.linalg.norm(P - P_fd, axis=(1, 2)) / scale
    assert err.max() < 1e-6


@pytest.mark.parametrize("law", LAWS, ids=lambda law: law.name)
@pytest.mark.parametrize("d", [2, 3])
def test_piola_derivative_matches_finite_differences_and_is_symmetric(law, d):
    F, mu, lam = _cases(d, seed=7)
    dP = law.first_piola_derivative(F, mu, lam)
    assert dP.shape == (len(F), d, d, d, d)
    dP_fd = fd_wrt_F(lambda G: law.first_piola(G, mu, lam), F)
    flat = dP.reshape(len(F), d * d, d * d)
    scale = np.linalg.norm(flat, axis=(1, 2))
    err = np.linalg.norm((dP - dP_fd).reshape(len(F), -1), axis=1) / scale
    assert err.max() < 1e-6
    # Hessian of psi: symmetric as a (d^2 x d^2) matrix, to round-off.
    asym = np.abs(flat - flat.transpose(0, 2, 1)).max(axis=(1, 2))
    assert (asym <= 1e-12 * scale).all()


@pytest.mark.parametrize("law", LAWS, ids=lambda law: law.name)
@pytest.mark.parametrize("d", [2, 3])
def test_rest_state_is_stress_free_with_zero_energy(law, d):
    F = np.broadcast_to(np.eye(d), (3, d, d))
    mu = np.array([1.0, 3e6, 4e7])
    lam = np.array([2.0, 1e6, 9e8])
    assert np.abs(law.energy_density(F, mu, lam)).max() == 0.0
    assert np.abs(law.first_piola(F, mu, lam)).max() <= 1e-12 * lam.max()


@pytest.mark.parametrize("d", [2, 3])
def test_linear_elasticity_is_the_linearisation_of_neo_hookean(d):
    rng = np.random.default_rng(3)
    mu, lam = _lame(rng, 5)
    identity = np.broadcast_to(np.eye(d), (5, d, d))
    C_nh = NEO_HOOKEAN.first_piola_derivative(identity, mu, lam)
    C_lin = LINEAR_ELASTIC.first_piola_derivative(identity, mu, lam)
    np.testing.assert_allclose(C_nh, C_lin, rtol=0, atol=1e-9 * lam.max())
    # Elasticity tensor at rest: C_ijkl = mu (d_ik d_jl + d_il d_jk) + lam d_ij d_kl.
    eye = np.eye(d)
    C_ref = mu[:, None, None, None, None] * (
        np.einsum("ik,jl->ijkl", eye, eye) + np.einsum("il,jk->ijkl", eye, eye)
    ) + lam[:, None, None, None, None] * np.einsum("ij,kl->ijkl", eye, eye)
    np.testing.assert_allclose(C_nh, C_ref, rtol=1e-12, atol=1e-9 * lam.max())
    # Small displacement gradients: stresses agree to first order (error O(|H|^2)).
    for eps in (1e-4, 1e-5):
        F = identity + eps * rng.standard_normal((5, d, d))
        P_nh = NEO_HOOKEAN.first_piola(F, mu, lam)
        P_lin = LINEAR_ELASTIC.first_piola(F, mu, lam)
        rel = np.linalg.norm(P_nh - P_lin, axis=(1, 2)) / np.linalg.norm(P_lin, axis=(1, 2))
        assert rel.max() < 100 * eps


@pytest.mark.parametrize("d", [2, 3])
def test_neo_hookean_matches_equation_7(d):
    F, mu, lam = _cases(d, seed=11)
    J = np.linalg.det(F)
    psi = (
        0.5 * mu * (np.einsum("sij,sij->s", F, F) - d) - mu * np.log(J) + 0.5 * lam * np.log(J) ** 2
    )
    np.testing.assert_allclose(NEO_HOOKEAN.energy_density(F, mu, lam), psi, rtol=1e-10, atol=1e-6)
    Finv_T = np.linalg.inv(F).transpose(0, 2, 1)
    P = mu[:, None, None] * (F - Finv_T) + (lam * np.log(J))[:, None, None] * Finv_T
    np.testing.assert_allclose(NEO_HOOKEAN.first_piola(F, mu, lam), P, rtol=1e-10, atol=1e-6)


def assert_frame_indifferent(law, F, mu, lam, R):
    """psi(RF) = psi(FR) = psi(F) (frame indifference, isotropy) and P(RF) = R P(F) (the stress
    rotates with the body) for deformation gradients F and rotations R (n, d, d)."""
    psi = law.energy_density(F, mu, lam)
    np.testing.assert_allclose(law.energy_density(R @ F, mu, lam), psi, rtol=1e-9)
    np.testing.assert_allclose(law.energy_density(F @ R, mu, lam), psi, rtol=1e-9)
    P = law.first_piola(F, mu, lam)
    np.testing.assert_allclose(law.first_piola(R @ F, mu, lam), R @ P, atol=1e-10 * np.abs(P).max())


def test_neo_hookean_2d_kernels_are_the_plane_strain_3d_route_bit_for_bit():
    """The 2D stress and energy kernels (unrolled, in registers) do the general loop's
    operations in its order: on F embedded as diag(F, 1) the 3D loop adds only exact zeros, so
    the in-plane stress block and the energy agree bit for bit, also for inverted points (NaN,
    inf) and tiny strains."""
    F, mu, lam = _cases(2, n=200)
    rng = np.random.default_rng(7)
    tiny = np.eye(2) + 1e-9 * rng.standard_normal((50, 2, 2))
    inverted = np.array([[[-1.0, 0.0], [0.0, 1.0]], [[0.5, 2.0], [1.0, 1.0]]])
    F = np.concatenate([F, tiny, inverted])
    mu, lam = np.resize(mu, F.shape[0]), np.resize(lam, F.shape[0])
    F3 = np.zeros((F.shape[0], 3, 3))
    F3[:, :2, :2] = F
    F3[:, 2, 2] = 1.0
    P2 = NEO_HOOKEAN.first_piola(F, mu, lam)
    P3 = NEO_HOOKEAN.first_piola(F3, mu, lam)[:, :2, :2]
    assert np.isnan(P2[-2:]).all() and np.isnan(P3[-2:]).all()
    np.testing.assert_array_equal(P2, P3)
    psi2 = NEO_HOOKEAN.energy_density(F, mu, lam)  # the energy kernel likewise
    psi3 = NEO_HOOKEAN.energy_density(F3, mu, lam)
    assert np.isinf(psi2[-2:]).all()
    np.testing.assert_array_equal(psi2, psi3)


@pytest.mark.parametrize("d", [2, 3])
def test_neo_hookean_is_frame_indifferent_and_isotropic(d):
    rng = np.random.default_rng(5)
    F, mu, lam = _cases(d, seed=13)
    R = _rotations(rng, len(F), d)
    assert_frame_indifferent(NEO_HOOKEAN, F, mu, lam, R)
    # Small-strain elasticity is not: a pure rotation of 1 rad stores energy.
    R_only = _rotations(rng, 4, d)
    assert (LINEAR_ELASTIC.energy_density(R_only, 1.0, 1.0) > 1e-3).all()
    assert np.abs(NEO_HOOKEAN.energy_density(R_only, 1.0, 1.0)).max() < 1e-12


@pytest.mark.parametrize("d", [2, 3])
def test_neo_hookean_inverted_points_have_infinite_energy(d):
    F = np.broadcast_to(np.eye(d), (3, d, d)).copy()
    F[1, 0, 0] = -1.0  # reflected: J = -1
    F[2, 0, 0] = 0.0  # collapsed: J = 0
    psi = NEO_HOOKEAN.energy_density(F, 1.0, 1.0)
    assert psi[0] == 0.0 and psi[1] == np.inf and psi[2] == np.inf
    P = NEO_HOOKEAN.first_piola(F, 1.0, 1.0)
    assert np.isfinite(P[0]).all() and np.isnan(P[1:]).all()
    assert np.isnan(NEO_HOOKEAN.first_piola_derivative(F, 1.0, 1.0)[1:]).all()
    # Compression costs energy without bound as J -> 0+.
    squeeze = np.broadcast_to(np.eye(d), (4, d, d)).copy()
    squeeze[:, 0, 0] = [1e-1, 1e-3, 1e-6, 1e-9]
    assert (np.diff(NEO_HOOKEAN.energy_density(squeeze, 1.0, 1.0)) > 0).all()


def test_law_input_validation_and_broadcasting():
    F = np.broadcast_to(np.eye(3), (4, 3, 3)) * 1.1
    per_point = NEO_HOOKEAN.energy_density(F, np.full(4, 2.0), np.full(4, 3.0))
    np.testing.assert_array_equal(NEO_HOOKEAN.energy_density(F, 2.0, 3.0), per_point)
    with pytest.raises(ValueError, match="F must have shape"):
        NEO_HOOKEAN.energy_density(np.ones((4, 3, 2)), 1.0, 1.0)
    with pytest.raises(ValueError, match="F must have shape"):
        LINEAR_ELASTIC.first_piola(np.ones((4, 4, 4)), 1.0, 1.0)
    with pytest.raises(ValueError, match="mu must be"):
        NEO_HOOKEAN.first_piola(F, np.ones(3), 1.0)
    with pytest.raises(ValueError, match="lam must be"):
        LINEAR_ELASTIC.first_piola_derivative(F, 1.0, np.ones((4, 1)))


@pytest.mark.parametrize("cls", MATERIALS)
def test_material_parameters(cls):
    m = cls(E=1e8, nu=0.2, density=1000.0)
    assert m.mu == pytest.approx(1e8 / 2.4, rel=1e-14)
    assert m.lam == pytest.approx(1e8 * 0.2 / (1.2 * 0.6), rel=1e-14)
    assert m.p_wave_speed == pytest.approx(math.sqrt((m.lam + 2 * m.mu) / 1000.0), rel=1e-14)
    assert m.law is (NEO_HOOKEAN if cls is NeoHookean else LINEAR_ELASTIC)
    assert m.name == m.law.name == ("neo_hookean" if cls is NeoHookean else "linear")
    assert cls(E=np.float32(2.0), nu=0, density=1) == cls(E=2.0, nu=0.0, density=1.0)
    assert isinstance(cls(E=np.float32(2.0), nu=0, density=1).E, float)
    with pytest.raises(AttributeError):
        m.E = 2.0  # frozen
    with pytest.raises(TypeError):
        cls(1e8, 0.2, 1000.0)  # keyword-only


@pytest.mark.parametrize("cls", MATERIALS)
@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("E", 0.0, "E must be finite and > 0"),
        ("E", -1.0, "E must be finite and > 0"),
        ("E", math.inf, "E must be finite and > 0"),
        ("E", math.nan, "E must be finite and > 0"),
        ("nu", 0.5, r"nu must be in \(-1, 0.5\), got 0.5"),
        ("nu", -1.0, r"nu must be in \(-1, 0.5\)"),
        ("nu", math.nan, r"nu must be in \(-1, 0.5\)"),
        ("density", 0.0, "density must be finite and > 0"),
        ("density", -5.0, "density must be finite and > 0"),
        ("density", math.nan, "density must be finite and > 0"),
        ("density", "1000", "density must be a real number"),
        ("E", True, "E must be a real number"),
    ],
)
def test_material_validation_names_class_and_field(cls, field, value, message):
    kwargs = {"E": 1e8, "nu": 0.2, "density": 1000.0, field: value}
    with pytest.raises(ValueError, match=f"^{cls.__name__}.{message}"):
        cls(**kwargs)
