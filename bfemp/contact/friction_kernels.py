"""Pointwise lagged-friction kernels: the mollifier f1 of BFEMP eq. 36, its antiderivative f0 and
the local friction pseudo-potential ``D = mu lambda f0(|u|)`` of BFEMP eq. 37 with derivatives.

Notation: ``u (k,)`` is the tangential relative displacement of a contact pair over the step in
its lagged tangent frame (m, ``k = d - 1``), ``y = |u|``, ``eps = eps_v dt`` (m) the sliding
displacement below which the pair is treated as static, and ``mu_lambda = mu lambda`` (N) the
lagged Coulomb bound of the pair (its weighted normal force times the friction coefficient).

Mollifier (BFEMP eq. 36) and its antiderivative (the constant is chosen so that f0 is continuous at
``eps``; it is the one of IPC, so ``f0(0) = eps / 3`` rather than 0 - a constant offset of the
pseudo-potential that no force or Hessian sees)::

    f1(y) = -y^2 / eps^2 + 2 y / eps,              f0(y) = -y^3 / (3 eps^2) + y^2 / eps + eps / 3
                                                                                     for y < eps
    f1(y) = 1,                                      f0(y) = y                        for y >= eps

so ``f0' = f1``, ``f1(eps) = 1``, ``f1'(eps) = 0`` (C1) and ``f1 <= 1`` (the Coulomb bound).

Derivatives of ``D(u) = mu_lambda f0(|u|)``::

    grad D = mu_lambda f1(y) / y u
    hess D = mu_lambda [ (f1'(y) y - f1(y)) / y^3  u u^T + f1(y) / y I ]
           = mu_lambda [ f1'(y) uh uh^T + f1(y) / y (I - uh uh^T) ],        uh = u / y

The second form is the spectral decomposition (eigenvalue ``f1'`` along ``u``, ``f1 / y``
across) and is used throughout: it has no ``1 / y^3``. As ``y -> 0`` in the static zone
``f1(y) / y = 2 / eps - y / eps^2 -> 2 / eps = f1'(0)``, so the Hessian tends to
``mu_lambda 2 / eps I`` and ``uh`` is not needed (it is set to 0 at ``y = 0``). With this
mollifier ``f1' >= 0`` everywhere, so the exact Hessian is already PSD for ``mu_lambda >= 0``;
``friction_local(psd=True)`` still clamps the eigenvalue along ``u`` to ``>= 0`` (closed form, no
``eigh``), as IPC does, which guards round-off and keeps the contract explicit.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["f0", "f1", "friction_local"]


def _check_eps(eps: float) -> float:
    if isinstance(eps, bool) or not isinstance(eps, int | float | np.floating | np.integer):
        raise ValueError(f"eps must be a number (eps_v * dt, m), got {eps!r}")
    if not (math.isfinite(eps) and eps > 0.0):
        raise ValueError(f"eps must be positive and finite (eps_v * dt, m), got {eps!r}")
    return float(eps)


def _check_y(y: np.ndarray) -> np.ndarray:
    y = np.asarray(y, dtype=np.float64)
    bad = ~(y >= 0.0)
    if bad.any():
        raise ValueError(
            f"y must be a norm (>= 0, not NaN); bad entries at {np.flatnonzero(bad.ravel())[:10]}"
        )
    return y


def f0(y: np.ndarray, eps: float) -> np.ndarray:
    """Antiderivative f0 (n,) in m of the mollifier, at sliding norms ``y (n,) >= 0`` in m.

    ``-y^3 / (3 eps^2) + y^2 / eps + eps / 3`` for ``y < eps``, ``y`` beyond (continuous, C2).
    """
    eps = _check_eps(eps)
    y = _check_y(y)
    return _f0(y, eps)


def _f0(y: np.ndarray, eps: float) -> np.ndarray:
    return np.where(y < eps, (-y / (3.0 * eps * eps) + 1.0 / eps) * y * y + eps / 3.0, y)


def f1(y: np.ndarray, eps: float) -> np.ndarray:
    """Friction mollifier f1 (n,) in [0, 1] (BFEMP eq. 36) at sliding norms ``y (n,) >= 0`` in m.

    ``-y^2 / eps^2 + 2 y / eps`` for ``y < eps`` (static zone), 1 beyond (sliding).
    """
    eps = _check_eps(eps)
    y = _check_y(y)
    return _f1(y, eps)


def _f1(y: np.ndarray, eps: float) -> np.ndarray:
    return np.where(y < eps, (2.0 - y / eps) * (y / eps), 1.0)


def _f1_over_y(y: np.ndarray, eps: float) -> np.ndarray:
    """f1(y) / y, finite at y = 0 (limit 2 / eps)."""
    return np.where(y < eps, (2.0 - y / eps) / eps, 1.0 / np.where(y < eps, 1.0, y))


def _f1_prime(y: np.ndarray, eps: float) -> np.ndarray:
    return np.where(y < eps, 2.0 * (1.0 - y / eps) / eps, 0.0)


def _check_local(u: np.ndarray, mu_lambda: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    u = np.asarray(u, dtype=np.float64)
    if u.ndim != 2 or u.shape[1] < 1:
        raise ValueError(f"u must have shape (n, k) with k = d - 1 >= 1, got {u.shape}")
    mu_lambda = np.asarray(mu_lambda, dtype=np.float64)
    if mu_lambda.shape != (u.shape[0],):
        raise ValueError(f"mu_lambda must have shape ({u.shape[0]},) like u, got {mu_lambda.shape}")
    bad = ~np.isfinite(u).all(axis=1)
    if bad.any():
        raise ValueError(f"u has non-finite entries in rows {np.flatnonzero(bad)[:10]}")
    bad = ~(np.isfinite(mu_lambda) & (mu_lambda >= 0.0))
    if bad.any():
        raise ValueError(
            f"mu_lambda must be finite and >= 0; bad entries at {np.flatnonzero(bad)[:10]}"
        )
    return u, mu_lambda


def friction_local(
    u: np.ndarray, mu_lambda: np.ndarray, eps: float, psd: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Local friction pseudo-potential ``D = mu_lambda f0(|u|)``, exact derivatives (BFEMP eq. 37).

    Args:
        u: tangential relative displacements (n, k) in m, k = d - 1 (1 in 2D, 2 in 3D).
        mu_lambda: lagged friction bounds ``mu lambda`` (n,) in N, >= 0.
        eps: static-zone width ``eps_v dt`` in m.
        psd: project the Hessian to PSD in closed form: the eigenvalue along ``u``
            (``mu_lambda f1'(|u|)``) clamped to ``>= 0``; the ``k - 1`` across ``u``
            (``mu_lambda f1(|u|) / |u|``) are positive.

    Returns:
        value (n,) in J, gradient (n, k) in N (its norm ``mu_lambda f1(|u|) <= mu_lambda``:
        the friction force obeys the Coulomb bound), Hessian (n, k, k) in N/m (well defined at
        ``u = 0`` where it equals ``mu_lambda 2 / eps I``).
    """
    eps = _check_eps(eps)
    u, mu_lambda = _check_local(u, mu_lambda)
    k = u.shape[1]
    y = np.linalg.norm(u, axis=1)
    f1y = _f1_over_y(y, eps)
    value = mu_lambda * _f0(y, eps)
    grad = (mu_lambda * f1y)[:, None] * u
    # Spectral form of the Hessian: eigenvalue f1' along uh, f1 / y across.
    uh = u / np.where(y > 0.0, y, 1.0)[:, None]
    along = _f1_prime(y, eps)
    if psd:
        along = np.maximum(along, 0.0)
    outer = uh[:, :, None] * uh[:, None, :]
    eye = np.eye(k)[None]
    hess = mu_lambda[:, None, None] * (
        along[:, None, None] * outer + f1y[:, None, None] * (eye - outer)
    )
    return value, grad, hess
