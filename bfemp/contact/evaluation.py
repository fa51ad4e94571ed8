"""Stateless evaluation of the barrier potential on (pairs, positions, parameters).

B = sum over active pairs of omega_q c b(d) (BFEMP eqs. 28-32): b the clamped log barrier of
BFEMP eq. 27 with ``dhat`` and ``kappa``, c the pair's duplicate-removal coefficient, omega_q the
integration weight of its point (section 4.2); edge-edge terms (3D) carry IPC's mollifier. These
functions know nothing of unknowns, layouts or steps: they take the collision-point positions
``(C, d)``, the active pairs (``bfemp.contact.pairs.find_pairs``) and the point weights, and return
the energy or per-pair derivatives with respect to each pair's own points. ``BarrierTerm`` (the
implicit strategies' energy term) chains them to nodes; any other strategy that needs the barrier
(``two_stage``) calls the same code. Pairs of a kind without a fused kernel (edge-edge) go through
the batched distance functions of :mod:`geometry.distance`.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from bfemp.contact._barrier_kernels import _barrier_gradients, _barrier_hessians
from bfemp.contact.barrier import barrier, barrier_derivative, barrier_second_derivative
from bfemp.contact.pairs import ContactPairs
from geometry import distance as dist
from geometry._distance_kernels import KIND_PE, KIND_PP, KIND_PT
from geometry.mollifier import (
    edge_edge_mollifier,
    edge_edge_mollifier_gradient,
    edge_edge_mollifier_hessian,
)
from solvers.psd import project_psd

__all__ = ["barrier_energy", "barrier_pair_gradients", "barrier_pair_hessians"]

#: Pair kinds with fused numba kernels (distance, barrier and PSD projection per pair); the
#: mollified edge-edge terms go through the batched distance functions.
KERNEL_KIND = {"pp": KIND_PP, "pe": KIND_PE, "pt": KIND_PT}


def _corners(pairs: ContactPairs, positions: np.ndarray, kind: str) -> list[np.ndarray]:
    """The positions ``(n, d)`` of each of the pair's points, in pair order."""
    pts = pairs.points[kind]
    return [positions[pts[:, a]] for a in range(pts.shape[1])]


def _active_kinds(pairs: ContactPairs, omega: np.ndarray) -> Iterator[tuple]:
    """``(kind, distances (n,), points (n, m), scale (n,))`` of every kind with active pairs, the
    scale omega_q c of each pair."""
    for kind, d in pairs.distance.items():
        if d.size:
            pts = pairs.points[kind]
            yield kind, d, pts, omega[pts[:, 0]] * pairs.coef[kind]


def barrier_energy(
    pairs: ContactPairs, positions: np.ndarray, omega: np.ndarray, dhat: float, kappa: float
) -> float:
    """B in J (J/m in 2D); +inf if a distance is <= 0.

    Args:
        pairs: active pairs at ``positions``.
        positions: collision-point positions ``(C, d)`` in m.
        omega: point weights ``(C,)`` (m in 2D, m^2 in 3D).
        dhat: activation distance in m.
        kappa: barrier stiffness in Pa.
    """
    total = 0.0
    for kind, d, _, scale in _active_kinds(pairs, omega):
        b = barrier(d, dhat, kappa)
        if kind == "ee":  # mollified where the edges turn parallel (IPC)
            b = b * edge_edge_mollifier(*_corners(pairs, positions, kind), pairs.eps_x)
        total += float(np.dot(scale, b))
    return total


def barrier_pair_gradients(
    pairs: ContactPairs, positions: np.ndarray, omega: np.ndarray, dhat: float, kappa: float
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per-pair gradients: kind -> ``(points (n, m), grad (n, m d))`` in N, the derivative of
    omega c [m] b(d) with respect to the pair's ``m`` points (arguments as ``barrier_energy``)."""
    out = {}
    for kind, d, pts, scale in _active_kinds(pairs, omega):
        b1 = barrier_derivative(d, dhat, kappa)
        if kind in KERNEL_KIND:
            out[kind] = (pts, _barrier_gradients(positions, pts, KERNEL_KIND[kind], scale * b1))
            continue
        # mollified edge-edge: (m b)' = m' b + m b'
        args = _corners(pairs, positions, kind)
        grad = scale[:, None] * b1[:, None] * dist.edge_edge_distance_gradient(*args)
        mol = edge_edge_mollifier(*args, pairs.eps_x)
        b0 = barrier(d, dhat, kappa)
        local = mol[:, None] * grad + (scale * b0)[:, None] * (
            edge_edge_mollifier_gradient(*args, pairs.eps_x)
        )
        out[kind] = (pts, local)
    return out


def barrier_pair_hessians(
    pairs: ContactPairs,
    positions: np.ndarray,
    omega: np.ndarray,
    dhat: float,
    kappa: float,
    psd: bool,
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per-pair Hessians: kind -> ``(points (n, m), hess (n, m d, m d))`` in N/m, projected to
    PSD per pair when ``psd`` (in the closest feature's difference coordinates for the fused
    kinds; arguments as ``barrier_energy``)."""
    out = {}
    for kind, d, pts, scale in _active_kinds(pairs, omega):
        b1 = barrier_derivative(d, dhat, kappa)
        b2 = barrier_second_derivative(d, dhat, kappa)
        if kind in KERNEL_KIND:
            local = _barrier_hessians(
                positions, pts, KERNEL_KIND[kind], scale * b1, scale * b2, psd
            )
        else:  # mollified edge-edge m(x) c b(d(x)): (m b)'' = m'' b + m' b'^T + b' m'^T + m b''
            args, eps_x = _corners(pairs, positions, kind), pairs.eps_x
            grad = dist.edge_edge_distance_gradient(*args)
            local = (scale * b2)[:, None, None] * grad[:, :, None] * grad[:, None, :]
            local += (scale * b1)[:, None, None] * dist.edge_edge_distance_hessian(*args)
            mol = edge_edge_mollifier(*args, eps_x)
            g_m = edge_edge_mollifier_gradient(*args, eps_x)
            b0 = barrier(d, dhat, kappa)
            cross = (scale * b1)[:, None, None] * g_m[:, :, None] * grad[:, None, :]
            local = mol[:, None, None] * local + cross + np.swapaxes(cross, 1, 2)
            local += (scale * b0)[:, None, None] * edge_edge_mollifier_hessian(*args, eps_x)
            local = project_psd(local) if psd else local
        out[kind] = (pts, local)
    return out
