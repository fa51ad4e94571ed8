"""Pointwise hyperelastic laws on batches of deformation gradients (private kernels).

Each law maps S deformation gradients ``F (S, d, d)`` (d = 2 or 3, dimensionless) and per-point
Lame parameters ``mu (S,)``, ``lam (S,)`` (Pa) to

- the strain energy density ``psi (S,)`` in J/m^3 (= Pa),
- the first Piola-Kirchhoff stress ``P = dpsi/dF (S, d, d)`` in Pa,
- its derivative ``dP (S, d, d, d, d)`` in Pa with ``dP[s, i, j, k, l] = dP_ij / dF_kl``.

Laws:

- Compressible Neo-Hookean, BFEMP eq. 7:
  ``psi = mu/2 (tr(F^T F) - d) - mu log J + lam/2 (log J)^2`` with ``J = det F``,
  ``P = mu (F - F^{-T}) + lam log J F^{-T}``.
  It is defined for ``J > 0`` only: for ``J <= 0`` the energy is ``+inf`` and the stress and its
  derivative are NaN. The kernels never raise; the caller handles infeasibility (the line search
  never proposes such F, see ``_detf_bound``).
- Small-strain linear elasticity: ``eps = (F + F^T)/2 - I``,
  ``psi = mu eps:eps + lam/2 tr(eps)^2``, ``P = 2 mu eps + lam tr(eps) I``.

In 2D everything is plane strain per unit thickness, so the 3D formulas hold unchanged with d = 2.

The laws are exposed as module-level singletons ``NEO_HOOKEAN`` and ``LINEAR_ELASTIC``; their
methods validate shapes and broadcast scalar Lame parameters, then call numba kernels.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numba import njit, prange

__all__ = ["LINEAR_ELASTIC", "NEO_HOOKEAN", "MaterialLaw", "NeoHookeanLaw"]


# --------------------------------------------------------------------------------------------
# numba kernels
# --------------------------------------------------------------------------------------------

# The Neo-Hookean kernels run over point ranges in parallel (each range with its own scratch
# matrix); every point is independent, so the results do not depend on the thread count.


@njit(cache=True)
def _n_ranges(n: int) -> int:
    """Point ranges for a parallel loop over ``n`` points: up to 64 (the threads share them
    out), >= 512 points each, so a range's scratch allocation is negligible."""
    return max(1, min(64, n // 512))


@njit(cache=True)
def _det_inv_t(F: np.ndarray, s: int, G: np.ndarray) -> float:
    """J = det F[s]; G (d, d) <- F[s]^{-T} = cof(F) / J when J != 0 (else G is untouched)."""
    d = F.shape[1]
    if d == 2:
        a, b = F[s, 0, 0], F[s, 0, 1]
        c, e = F[s, 1, 0], F[s, 1, 1]
        J = a * e - b * c
        if J != 0.0:
            inv = 1.0 / J
            # The cofactor matrix of [[a, b], [c, e]] is [[e, -c], [-b, a]].
            G[0, 0] = e * inv
            G[0, 1] = -c * inv
            G[1, 0] = -b * inv
            G[1, 1] = a * inv
        return J
    # 3D: cofactors C_ij = (-1)^(i+j) minor_ij, J = sum_j F_0j C_0j.
    c00 = F[s, 1, 1] * F[s, 2, 2] - F[s, 1, 2] * F[s, 2, 1]
    c01 = F[s, 1, 2] * F[s, 2, 0] - F[s, 1, 0] * F[s, 2, 2]
    c02 = F[s, 1, 0] * F[s, 2, 1] - F[s, 1, 1] * F[s, 2, 0]
    J = F[s, 0, 0] * c00 + F[s, 0, 1] * c01 + F[s, 0, 2] * c02
    if J != 0.0:
        inv = 1.0 / J
        G[0, 0] = c00 * inv
        G[0, 1] = c01 * inv
        G[0, 2] = c02 * inv
        G[1, 0] = (F[s, 0, 2] * F[s, 2, 1] - F[s, 0, 1] * F[s, 2, 2]) * inv
        G[1, 1] = (F[s, 0, 0] * F[s, 2, 2] - F[s, 0, 2] * F[s, 2, 0]) * inv
        G[1, 2] = (F[s, 0, 1] * F[s, 2, 0] - F[s, 0, 0] * F[s, 2, 1]) * inv
        G[2, 0] = (F[s, 0, 1] * F[s, 1, 2] - F[s, 0, 2] * F[s, 1, 1]) * inv
        G[2, 1] = (F[s, 0, 2] * F[s, 1, 0] - F[s, 0, 0] * F[s, 1, 2]) * inv
        G[2, 2] = (F[s, 0, 0] * F[s, 1, 1] - F[s, 0, 1] * F[s, 1, 0]) * inv
    return J


@njit(cache=True)
def _h_invariants(F: np.ndarray, s: int, H: np.ndarray) -> tuple[float, float, float]:
    """H <- F[s] - I; returns (tr H, J - 1, J - 1 - tr H), all without cancellation near F = I.

    det(I + H) - 1 = tr H + m2(H) + det H (3D; m2 = sum of principal 2x2 minors), tr H + det H
    (2D): formed from the small H, not as det(F) - 1, so stiff materials at tiny strains keep
    their energy and stress to relative precision (the line search then resolves small steps).
    """
    d = F.shape[1]
    for i in range(d):
        for j in range(d):
            H[i, j] = F[s, i, j] - (1.0 if i == j else 0.0)
    if d == 2:
        tr = H[0, 0] + H[1, 1]
        rest = H[0, 0] * H[1, 1] - H[0, 1] * H[1, 0]
        return tr, tr + rest, rest
    tr = H[0, 0] + H[1, 1] + H[2, 2]
    m2 = (
        H[0, 0] * H[1, 1]
        - H[0, 1] * H[1, 0]
        + H[0, 0] * H[2, 2]
        - H[0, 2] * H[2, 0]
        + H[1, 1] * H[2, 2]
        - H[1, 2] * H[2, 1]
    )
    det_h = (
        H[0, 0] * (H[1, 1] * H[2, 2] - H[1, 2] * H[2, 1])
        + H[0, 1] * (H[1, 2] * H[2, 0] - H[1, 0] * H[2, 2])
        + H[0, 2] * (H[1, 0] * H[2, 1] - H[1, 1] * H[2, 0])
    )
    return tr, tr + m2 + det_h, m2 + det_h


@njit(cache=True)
def _adj_t(H: np.ndarray, i: int, j: int) -> float:
    """adj(H)^T_ij = the cofactor of H at (i, j) (3 x 3 only)."""
    i1, i2 = (i + 1) % 3, (i + 2) % 3
    j1, j2 = (j + 1) % 3, (j + 2) % 3
    return H[i1, j1] * H[i2, j2] - H[i1, j2] * H[i2, j1]


@njit(cache=True, parallel=True)
def _nh_energy(F: np.ndarray, mu: np.ndarray, lam: np.ndarray, out: np.ndarray) -> None:
    d = F.shape[1]
    n = F.shape[0]
    n_ranges = _n_ranges(n)
    for c in prange(n_ranges):
        _nh_energy_range(F, mu, lam, out, c * n // n_ranges, (c + 1) * n // n_ranges, d)


@njit(cache=True, inline="always")
def _nh_energy_range(F, mu, lam, out, start, stop, d):  # noqa: ANN001, ANN202
    if d == 2:  # unrolled, the loop below's operations in its order (as ``_nh_piola_2d``)
        for s in range(start, stop):
            h00, h01, h10, h11 = F[s, 0, 0] - 1.0, F[s, 0, 1], F[s, 1, 0], F[s, 1, 1] - 1.0
            tr = h00 + h11
            jm1 = tr + (h00 * h11 - h01 * h10)
            if not jm1 > -1.0:
                out[s] = np.inf
                continue
            sq = h00 * h00 + h01 * h01 + h10 * h10 + h11 * h11
            logj = math.log1p(jm1)
            out[s] = mu[s] * (0.5 * sq + (tr - logj)) + 0.5 * lam[s] * logj * logj
        return
    H = np.empty((d, d))
    for s in range(start, stop):
        tr, jm1, _ = _h_invariants(F, s, H)
        if not jm1 > -1.0:
            out[s] = np.inf
            continue
        # tr(F^T F) - d = |H|^2 + 2 tr H and log J = log1p(J - 1): no cancellation near F = I.
        sq = 0.0
        for i in range(d):
            for j in range(d):
                sq += H[i, j] * H[i, j]
        logj = math.log1p(jm1)
        out[s] = mu[s] * (0.5 * sq + (tr - logj)) + 0.5 * lam[s] * logj * logj


@njit(cache=True, parallel=True)
def _nh_piola(F: np.ndarray, mu: np.ndarray, lam: np.ndarray, out: np.ndarray) -> None:
    d = F.shape[1]
    n = F.shape[0]
    n_ranges = _n_ranges(n)
    for c in prange(n_ranges):
        _nh_piola_range(F, mu, lam, out, c * n // n_ranges, (c + 1) * n // n_ranges, d)


@njit(cache=True, inline="always")
def _nh_piola_range(F, mu, lam, out, start, stop, d):  # noqa: ANN001, ANN202
    if d == 2:
        for s in range(start, stop):
            p00, p01, p10, p11 = _nh_piola_2d(F, s, mu[s], lam[s])
            out[s, 0, 0] = p00
            out[s, 0, 1] = p01
            out[s, 1, 0] = p10
            out[s, 1, 1] = p11
        return
    H = np.empty((d, d))
    for s in range(start, stop):
        tr, jm1, rest = _h_invariants(F, s, H)
        if not jm1 > -1.0:
            out[s] = np.nan
            continue
        J = 1.0 + jm1
        logj = math.log1p(jm1)
        # P = [mu (J F - cof F) + lam log J cof F] / J, with cof F = (1 + tr H) I - H^T (2D) or
        # (1 + tr H) I - H^T + adj(H)^T (3D), so that J F - cof F = rest I + H + H^T + jm1 H
        # (- adj(H)^T in 3D) is formed from small quantities only.
        for i in range(d):
            for j in range(d):
                adj_t = _adj_t(H, i, j) if d == 3 else 0.0
                eye = 1.0 if i == j else 0.0
                cof = (1.0 + tr) * eye - H[j, i] + adj_t
                diff = rest * eye + H[i, j] + H[j, i] + jm1 * H[i, j] - adj_t
                out[s, i, j] = (mu[s] * diff + lam[s] * logj * cof) / J


@njit(cache=True, inline="always")
def _nh_piola_2d(F, s, mu, lam):  # noqa: ANN001, ANN202
    """The Neo-Hookean P of F[s] in 2D, in registers: ``(P00, P01, P10, P11)`` in Pa.

    The operations of the general loop of ``_nh_piola_range`` with d = 2 in the same order
    (its terms in ``eye = 0`` and ``adj_t = 0`` only add zeros), so the two agree bit for bit
    up to the sign of a zero entry; without the loops and the scratch array it takes a third
    of the time (0.30 against 0.88 ms for 33k particles, one thread).
    """
    h00 = F[s, 0, 0] - 1.0
    h01 = F[s, 0, 1]
    h10 = F[s, 1, 0]
    h11 = F[s, 1, 1] - 1.0
    tr = h00 + h11
    rest = h00 * h11 - h01 * h10
    jm1 = tr + rest
    if not jm1 > -1.0:
        return np.nan, np.nan, np.nan, np.nan
    J = 1.0 + jm1
    lj = lam * math.log1p(jm1)
    p00 = (mu * (rest + h00 + h00 + jm1 * h00) + lj * ((1.0 + tr) - h00)) / J
    p01 = (mu * (h01 + h10 + jm1 * h01) + lj * -h10) / J
    p10 = (mu * (h10 + h01 + jm1 * h10) + lj * -h01) / J
    p11 = (mu * (rest + h11 + h11 + jm1 * h11) + lj * ((1.0 + tr) - h11)) / J
    return p00, p01, p10, p11


@njit(cache=True, parallel=True)
def _nh_piola_derivative(F: np.ndarray, mu: np.ndarray, lam: np.ndarray, out: np.ndarray) -> None:
    d = F.shape[1]
    n = F.shape[0]
    n_ranges = _n_ranges(n)
    for c in prange(n_ranges):
        _nh_piola_derivative_range(F, mu, lam, out, c * n // n_ranges, (c + 1) * n // n_ranges, d)


@njit(cache=True, inline="always")
def _nh_piola_derivative_range(F, mu, lam, out, start, stop, d):  # noqa: ANN001, ANN202
    G = np.empty((d, d))
    for s in range(start, stop):
        J = _det_inv_t(F, s, G)
        if not J > 0.0:
            out[s] = np.nan
            continue
        # With G = F^{-T}: dG_ij/dF_kl = -G_il G_kj and d(log J)/dF_kl = G_kl, so
        # dP_ij/dF_kl = mu d_ik d_jl + (mu - lam log J) G_il G_kj + lam G_ij G_kl.
        a = mu[s] - lam[s] * math.log(J)
        b = lam[s]
        o = out[s]
        for i in range(d):
            for j in range(d):
                bg = b * G[i, j]
                for k in range(d):
                    agk = a * G[k, j]
                    for l in range(d):
                        o[i, j, k, l] = agk * G[i, l] + bg * G[k, l]
                o[i, j, i, j] += mu[s]


@njit(cache=True)
def _lin_energy(F: np.ndarray, mu: np.ndarray, lam: np.ndarray, out: np.ndarray) -> None:
    d = F.shape[1]
    for s in range(F.shape[0]):
        sq = 0.0
        tr = 0.0
        for i in range(d):
            for j in range(d):
                e = 0.5 * (F[s, i, j] + F[s, j, i]) - (1.0 if i == j else 0.0)
                sq += e * e
            tr += F[s, i, i] - 1.0
        out[s] = mu[s] * sq + 0.5 * lam[s] * tr * tr


@njit(cache=True)
def _lin_piola(F: np.ndarray, mu: np.ndarray, lam: np.ndarray, out: np.ndarray) -> None:
    d = F.shape[1]
    for s in range(F.shape[0]):
        tr = 0.0
        for i in range(d):
            tr += F[s, i, i] - 1.0
        for i in range(d):
            for j in range(d):
                e = 0.5 * (F[s, i, j] + F[s, j, i]) - (1.0 if i == j else 0.0)
                out[s, i, j] = 2.0 * mu[s] * e
            out[s, i, i] += lam[s] * tr


@njit(cache=True)
def _lin_piola_derivative(F: np.ndarray, mu: np.ndarray, lam: np.ndarray, out: np.ndarray) -> None:
    # dP_ij/dF_kl = mu (d_ik d_jl + d_il d_jk) + lam d_ij d_kl, independent of F.
    d = F.shape[1]
    for s in range(F.shape[0]):
        for i in range(d):
            for j in range(d):
                for k in range(d):
                    for l in range(d):
                        v = 0.0
                        if i == k and j == l:
                            v += mu[s]
                        if i == l and j == k:
                            v += mu[s]
                        if i == j and k == l:
                            v += lam[s]
                        out[s, i, j, k, l] = v


# --------------------------------------------------------------------------------------------
# law objects
# --------------------------------------------------------------------------------------------


def _prepare(
    F: np.ndarray, mu: np.ndarray | float, lam: np.ndarray | float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Validate and convert inputs: F (S, d, d) with d in {2, 3}; mu, lam (S,) or scalars."""
    F = np.ascontiguousarray(F, dtype=np.float64)
    if F.ndim != 3 or F.shape[1] != F.shape[2] or F.shape[1] not in (2, 3):
        raise ValueError(f"F must have shape (S, d, d) with d in (2, 3), got {F.shape}")
    n = F.shape[0]
    out = []
    for name, value in (("mu", mu), ("lam", lam)):
        arr = np.asarray(value, dtype=np.float64)
        if arr.ndim == 0:
            arr = np.full(n, float(arr))
        elif arr.shape != (n,):
            raise ValueError(f"{name} must be a scalar or have shape ({n},), got {arr.shape}")
        out.append(np.ascontiguousarray(arr))
    return F, out[0], out[1]


class MaterialLaw:
    """A pointwise hyperelastic law psi(F) evaluated on batches of S points.

    Made of its ``name`` and its three numba kernels ``kernel(F, mu, lam, out)`` (the energy
    density, P and dP/dF). All methods take ``F (S, d, d)`` (dimensionless, d = 2 or 3) and Lame
    parameters ``mu``, ``lam`` in Pa, each either an array ``(S,)`` or a scalar shared by all
    points.
    """

    __slots__ = ("_derivative_kernel", "_energy_kernel", "_piola_kernel", "name")

    def __init__(self, name: str, energy: Callable, piola: Callable, derivative: Callable) -> None:
        self.name = name
        self._energy_kernel = energy
        self._piola_kernel = piola
        self._derivative_kernel = derivative

    def energy_density(
        self, F: np.ndarray, mu: np.ndarray | float, lam: np.ndarray | float
    ) -> np.ndarray:
        """Strain energy density psi (S,) in J/m^3 of deformation gradients F (S, d, d)."""
        F, mu, lam = _prepare(F, mu, lam)
        out = np.empty(F.shape[0])
        self._energy_kernel(F, mu, lam, out)
        return out

    def first_piola(
        self,
        F: np.ndarray,
        mu: np.ndarray | float,
        lam: np.ndarray | float,
        out: np.ndarray | None = None,
    ) -> np.ndarray:
        """First Piola-Kirchhoff stress P = dpsi/dF (S, d, d) in Pa for F (S, d, d), written into
        ``out`` (float64, C-contiguous, the shape of F) when given."""
        F, mu, lam = _prepare(F, mu, lam)
        if out is None:
            out = np.empty_like(F)
        elif out.shape != F.shape or out.dtype != np.float64 or not out.flags.c_contiguous:
            raise ValueError(f"out must be C-contiguous float64 of shape {F.shape}")
        self._piola_kernel(F, mu, lam, out)
        return out

    def first_piola_derivative(
        self, F: np.ndarray, mu: np.ndarray | float, lam: np.ndarray | float
    ) -> np.ndarray:
        """dP/dF (S, d, d, d, d) in Pa with out[s, i, j, k, l] = dP_ij/dF_kl at F[s].

        Reshaped to (S, d*d, d*d) each block is symmetric (it is the Hessian of psi).
        """
        F, mu, lam = _prepare(F, mu, lam)
        d = F.shape[1]
        out = np.empty((F.shape[0], d, d, d, d))
        self._derivative_kernel(F, mu, lam, out)
        return out

    def cauchy_stress(
        self, F: np.ndarray, mu: np.ndarray | float, lam: np.ndarray | float
    ) -> np.ndarray:
        """Cauchy stress sigma = P F^T / J (S, d, d) in Pa for F (S, d, d); NaN where J <= 0.

        In 2D (plane strain) this is the in-plane block of the 3D tensor. Laws with a closed
        form override it.
        """
        F, mu, lam = _prepare(F, mu, lam)
        J = np.linalg.det(F)
        with np.errstate(all="ignore"):
            sigma = self.first_piola(F, mu, lam) @ np.swapaxes(F, 1, 2) / J[:, None, None]
        sigma[~(J > 0.0)] = np.nan
        return sigma

    def project_derivative(
        self, blocks: np.ndarray, F: np.ndarray, mu: np.ndarray, lam: np.ndarray
    ) -> np.ndarray:
        """dP/dF blocks ``(S, d*d, d*d)`` (in Pa, at ``F (S, d, d)``) projected to PSD: the
        generic eigenvalue clamp of ``solvers.psd``; a law with an analytic eigensystem
        overrides it (the result is the same matrix)."""
        from solvers.psd import project_psd

        return project_psd(blocks)

    def __repr__(self) -> str:
        return f"<material law {self.name!r}>"


class NeoHookeanLaw(MaterialLaw):
    """Compressible Neo-Hookean law of BFEMP eq. 7; psi = +inf (P, dP/dF NaN) where J <= 0."""

    __slots__ = ()

    def project_derivative(
        self, blocks: np.ndarray, F: np.ndarray, mu: np.ndarray, lam: np.ndarray
    ) -> np.ndarray:
        """The projection by the analytic eigensystem (``bfemp._nh_projection``): a d x d
        eigenproblem per block instead of a d^2 x d^2 one (3D: 2.7x faster, measured)."""
        from bfemp._nh_projection import project_nh_derivative

        F, mu, lam = _prepare(F, mu, lam)
        return project_nh_derivative(blocks, F, mu, lam)


NEO_HOOKEAN = NeoHookeanLaw("neo_hookean", _nh_energy, _nh_piola, _nh_piola_derivative)
#: small-strain linear elasticity psi = mu eps:eps + lam/2 tr(eps)^2, eps = sym(F) - I
LINEAR_ELASTIC = MaterialLaw("linear", _lin_energy, _lin_piola, _lin_piola_derivative)
