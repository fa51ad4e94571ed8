"""The bulk/shear hyperelastic law of LR eq. 18 (private kernels).

The strain energy density of the multimaterial-contact paper (LR eq. 18), in J/m^3:

    W = G/2 (I1 J^{-2/3} - 3) + K/2 (1/2 (J^2 - 1) - ln J),

with ``I1 = tr(F^T F)`` and ``J = det F`` taken in 3D. In 2D (plane strain) the 3D invariants of
``diag(F, 1)`` are used: ``I1 = tr(F^T F) + 1`` and ``J = det F`` of the 2 x 2 block. The kernels
take the same per-point Lame parameters as every other law, ``mu = G`` and
``lam = K - 2 G / 3`` (3D meaning, also in plane strain), so ``K = lam + 2 mu / 3``.

With ``Q = F^{-T}``, ``a = G J^{-2/3}`` and ``c = K/2 (J^2 - 1)``:

- first Piola stress ``P = a (F - I1/3 Q) + c Q``;
- its derivative, ``dP_ij/dF_kl = a d_ik d_jl - 2/3 a (F_ij Q_kl + Q_ij F_kl)
  + 2/9 a I1 Q_ij Q_kl + (a I1/3 - c) Q_il Q_kj + K J^2 Q_ij Q_kl`` (symmetric in (ij) <-> (kl));
- Cauchy stress ``sigma = P F^T / J = G J^{-5/3} dev(b) + K/2 (J - 1/J) I``, ``b = F F^T``,
  ``dev(b) = b - I1/3 I`` (in 2D the in-plane block of the 3D tensor).

At ``F = I`` the law linearises to isotropic elasticity with shear modulus G and bulk modulus K.
Near ``F = I`` the energy and both stresses are formed from ``H = F - I`` and the small invariants
of ``_h_invariants`` (no cancellation of O(1) terms), as the Neo-Hookean kernels are, so stiff
materials at tiny strains keep their energy and stress to relative precision.

Like the Neo-Hookean law it is defined for ``J > 0`` only: for ``J <= 0`` the energy is ``+inf``
and the stresses and the derivative are NaN; the kernels never raise.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from bfemp._material_kernels import MaterialLaw, _adj_t, _det_inv_t, _h_invariants, _prepare

__all__ = ["BULK_SHEAR", "BulkShearLaw"]

#: below this |x| the series of ``_x_minus_log1p`` and ``_pow23_rest`` are used (24 terms:
#: the first neglected term is below 1e-24 x^2).
_SERIES_BELOW = 0.1
_SERIES_TERMS = 24


@njit(cache=True)
def _x_minus_log1p(x: float) -> float:
    """x - log(1 + x) = sum_{n >= 2} (-1)^n x^n / n, without cancellation for small |x|."""
    if abs(x) >= _SERIES_BELOW:
        return x - math.log1p(x)
    total = 0.0
    power = x
    for n in range(2, _SERIES_TERMS + 2):
        power *= -x
        total += power / n
    return -total


@njit(cache=True)
def _pow23_rest(x: float) -> float:
    """(1 + x)^{2/3} - 1 - 2x/3 = sum_{n >= 2} binom(2/3, n) x^n, accurate for small |x|."""
    if abs(x) >= _SERIES_BELOW:
        return math.expm1(2.0 / 3.0 * math.log1p(x)) - 2.0 * x / 3.0
    total = 0.0
    coef = 2.0 / 3.0  # binom(2/3, 1)
    power = x
    for n in range(2, _SERIES_TERMS + 2):
        coef *= (2.0 / 3.0 - (n - 1)) / n
        power *= x
        total += coef * power
    return total


@njit(cache=True)
def _small_invariants(F: np.ndarray, s: int, H: np.ndarray) -> tuple[float, float, float, float]:
    """H <- F[s] - I; returns (tr H, J - 1, J - 1 - tr H, |H|^2) from small quantities only."""
    tr, jm1, rest = _h_invariants(F, s, H)
    d = F.shape[1]
    sq = 0.0
    for i in range(d):
        for j in range(d):
            sq += H[i, j] * H[i, j]
    return tr, jm1, rest, sq


@njit(cache=True)
def _bs_energy(F: np.ndarray, mu: np.ndarray, lam: np.ndarray, out: np.ndarray) -> None:
    d = F.shape[1]
    H = np.empty((d, d))
    for s in range(F.shape[0]):
        _, jm1, rest, sq = _small_invariants(F, s, H)
        if not jm1 > -1.0:
            out[s] = np.inf
            continue
        K = lam[s] + 2.0 * mu[s] / 3.0
        # I1 J^{-2/3} - 3 = (I1 - 3 J^{2/3}) J^{-2/3}; with I1 - 3 = 2 tr H + |H|^2 (2D too, by
        # the plane-strain I1 = tr(F^T F) + 1) and 3 J^{2/3} - 3 = 2 (J - 1) + 3 g(J - 1):
        # I1 - 3 J^{2/3} = |H|^2 - 2 rest - 3 g(J - 1), every term of second order.
        logj = math.log1p(jm1)
        shear = (sq - 2.0 * rest - 3.0 * _pow23_rest(jm1)) * math.exp(-2.0 / 3.0 * logj)
        # 1/2 (J^2 - 1) - ln J = (J - 1)^2 / 2 + (J - 1) - ln J.
        bulk = 0.5 * jm1 * jm1 + _x_minus_log1p(jm1)
        out[s] = 0.5 * mu[s] * shear + 0.5 * K * bulk


@njit(cache=True)
def _bs_piola(F: np.ndarray, mu: np.ndarray, lam: np.ndarray, out: np.ndarray) -> None:
    d = F.shape[1]
    H = np.empty((d, d))
    for s in range(F.shape[0]):
        tr, jm1, rest, sq = _small_invariants(F, s, H)
        if not jm1 > -1.0:
            out[s] = np.nan
            continue
        J = 1.0 + jm1
        K = lam[s] + 2.0 * mu[s] / 3.0
        a = mu[s] * math.exp(-2.0 / 3.0 * math.log1p(jm1))  # G J^{-2/3}
        third_q = (2.0 * tr + sq) / 3.0  # I1/3 - 1
        c = 0.5 * K * jm1 * (2.0 + jm1)  # K/2 (J^2 - 1)
        # P = [a (J F - I1/3 cof F) + c cof F] / J with cof F = (1 + tr H) I - H^T + adj(H)^T;
        # J F - I1/3 cof F = rest I + H + H^T + (J - 1) H - adj(H)^T - (I1/3 - 1) cof F.
        for i in range(d):
            for j in range(d):
                adj = _adj_t(H, i, j) if d == 3 else 0.0
                eye = 1.0 if i == j else 0.0
                cof = (1.0 + tr) * eye - H[j, i] + adj
                dev = rest * eye + H[i, j] + H[j, i] + jm1 * H[i, j] - adj - third_q * cof
                out[s, i, j] = (a * dev + c * cof) / J


@njit(cache=True)
def _bs_piola_derivative(F: np.ndarray, mu: np.ndarray, lam: np.ndarray, out: np.ndarray) -> None:
    d = F.shape[1]
    Q = np.empty((d, d))
    for s in range(F.shape[0]):
        J = _det_inv_t(F, s, Q)
        if not J > 0.0:
            out[s] = np.nan
            continue
        K = lam[s] + 2.0 * mu[s] / 3.0
        i1 = 1.0 if d == 2 else 0.0  # plane strain: F33 = 1 adds 1 to I1
        for i in range(d):
            for j in range(d):
                i1 += F[s, i, j] * F[s, i, j]
        a = mu[s] * math.exp(-2.0 / 3.0 * math.log(J))
        c = 0.5 * K * (J * J - 1.0)
        twist = a * i1 / 3.0 - c  # coefficient of Q_il Q_kj
        qq = 2.0 / 9.0 * a * i1 + K * J * J  # coefficient of Q_ij Q_kl
        fq = 2.0 / 3.0 * a  # coefficient of -(F_ij Q_kl + Q_ij F_kl)
        o = out[s]
        for i in range(d):
            for j in range(d):
                for k in range(d):
                    for l in range(d):
                        o[i, j, k, l] = (
                            twist * Q[i, l] * Q[k, j]
                            + qq * Q[i, j] * Q[k, l]
                            - fq * (F[s, i, j] * Q[k, l] + Q[i, j] * F[s, k, l])
                        )
                o[i, j, i, j] += a


@njit(cache=True)
def _bs_cauchy(F: np.ndarray, mu: np.ndarray, lam: np.ndarray, out: np.ndarray) -> None:
    d = F.shape[1]
    H = np.empty((d, d))
    for s in range(F.shape[0]):
        tr, jm1, _, sq = _small_invariants(F, s, H)
        if not jm1 > -1.0:
            out[s] = np.nan
            continue
        J = 1.0 + jm1
        K = lam[s] + 2.0 * mu[s] / 3.0
        g = mu[s] * math.exp(-5.0 / 3.0 * math.log1p(jm1))  # G J^{-5/3}
        third_q = (2.0 * tr + sq) / 3.0  # I1/3 - 1
        p = 0.5 * K * jm1 * (2.0 + jm1) / J  # K/2 (J - 1/J)
        # dev(b) = b - I1/3 I = H + H^T + H H^T - (I1/3 - 1) I.
        for i in range(d):
            for j in range(d):
                hh = 0.0
                for k in range(d):
                    hh += H[i, k] * H[j, k]
                eye = 1.0 if i == j else 0.0
                out[s, i, j] = g * (H[i, j] + H[j, i] + hh - third_q * eye) + p * eye


class BulkShearLaw(MaterialLaw):
    """LR eq. 18: W = G/2 (I1 J^{-2/3} - 3) + K/2 (1/2 (J^2 - 1) - ln J), G = mu,
    K = lam + 2 mu / 3; plane strain in 2D; psi = +inf (stresses NaN) where J <= 0."""

    __slots__ = ()

    def cauchy_stress(
        self, F: np.ndarray, mu: np.ndarray | float, lam: np.ndarray | float
    ) -> np.ndarray:
        """Cauchy stress (S, d, d) in Pa by the closed form G J^{-5/3} dev(b) + K/2 (J - 1/J) I
        (2D: the in-plane block); NaN where J <= 0."""
        F, mu, lam = _prepare(F, mu, lam)
        out = np.empty_like(F)
        _bs_cauchy(F, mu, lam, out)
        return out


BULK_SHEAR = BulkShearLaw("bulk_shear", _bs_energy, _bs_piola, _bs_piola_derivative)
