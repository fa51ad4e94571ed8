"""numba kernels of multimaterial MPM: one grid velocity field per material (LR eq. 5).

Every particle p belongs to one material ``material[p]`` in [0, M); the shared grid holds M
fields over its G active nodes. P2G of material alpha sums over alpha's particles only:

    m_i^a   = sum_{p in a} w_ip m_p                     (kg, kg/m in 2D)
    p_i^a0  = sum_{p in a} w_ip m_p v_p                 (kg m/s)
    f_i^a0  = -sum_{p in a} V_p^0 P(F_p) F_p^T grad w_ip (N; LR eq. 29 without gravity)

The transfers of XPIC (LR section 3.3) are the two maps between a field (M, G, d) and the
particles: ``g2p_field`` (S: v_p = sum_i w_ip u_i^{a(p)}) and ``p2g_field`` (S+^a: u_i^a =
sum_{p in a} w_ip m_p u_p / m_i^a). The scatters are serial (each writes into the shared (M, G)
arrays); they are a few per cent of a step at the sizes of the LR benchmarks (thousands of
particles), measured in ``benchmarks/lr_compression``. The gathers have a serial and a parallel
build: below ``PARALLEL_MIN_POINTS`` points the thread start-up of a parallel loop costs more
than the loop (measured: 0.09 ms per gather of 640 particles on 2 threads).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from bfemp._njit import serial_or_parallel
from bfemp.mpm._transfer_kernels import _kirchhoff_volume

__all__ = [
    "g2p_field",
    "g2p_update",
    "mass_moments",
    "p2g_field",
    "p2g_materials",
    "p2g_nodal",
]

#: points from which the gathers run in parallel
PARALLEL_MIN_POINTS = 20_000


@njit(cache=True)
def p2g_materials(
    nodes: np.ndarray,
    weights: np.ndarray,
    grads: np.ndarray,
    material: np.ndarray,
    mass: np.ndarray,
    velocity: np.ndarray,
    piola: np.ndarray,
    F: np.ndarray,
    volume: np.ndarray,
    n_materials: int,
    n_nodes: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-material grid mass ``(M, G)``, momentum ``(M, G, d)`` and internal force ``(M, G, d)``.

    Args:
        nodes, weights, grads: stencils ``(P, K)``, ``(P, K)``, ``(P, K, d)`` (1/m) at x_p^n.
        material: material of each particle ``(P,)`` in [0, M).
        mass, velocity: particle masses ``(P,)`` kg and velocities ``(P, d)`` m/s.
        piola, F, volume: P(F_p) ``(P, d, d)`` Pa, F_p ``(P, d, d)``, V_p^0 ``(P,)`` m^d.
    """
    n_p, k = nodes.shape
    d = velocity.shape[1]
    m = np.zeros((n_materials, n_nodes))
    mom = np.zeros((n_materials, n_nodes, d))
    force = np.zeros((n_materials, n_nodes, d))
    tau = np.empty((d, d))
    for p in range(n_p):
        a = material[p]
        _kirchhoff_volume(piola, F, volume, p, tau)
        for e in range(k):
            i = nodes[p, e]
            w = weights[p, e]
            m[a, i] += w * mass[p]
            for r in range(d):
                mom[a, i, r] += w * mass[p] * velocity[p, r]
                acc = 0.0
                for s in range(d):
                    acc += tau[r, s] * grads[p, e, s]
                force[a, i, r] -= acc
    return m, mom, force


@njit(cache=True)
def p2g_nodal(
    nodes: np.ndarray,
    weights: np.ndarray,
    material: np.ndarray,
    mass: np.ndarray,
    velocity: np.ndarray,
    force: np.ndarray,
    grid_mass: np.ndarray,
    grid_momentum: np.ndarray,
    grid_force: np.ndarray,
) -> None:
    """Add FEM boundary nodes to the per-material grid in place (bfemp's FEM in LR):
    m_i^F += w_in m_n, p_i^F += w_in m_n v_n, f_i^F += w_in f_n (f_n the node's mechanical
    force, N, so that the grid acceleration is the node's own where one node dominates).

    Args:
        nodes, weights: stencils of the nodes ``(B, K)``; material ``(B,)``; mass ``(B,)`` kg;
            velocity, force ``(B, d)``; grid arrays ``(M, G)``, ``(M, G, d)``, ``(M, G, d)``.
    """
    n_b, k = nodes.shape
    d = velocity.shape[1]
    for b in range(n_b):
        a = material[b]
        for e in range(k):
            i = nodes[b, e]
            w = weights[b, e]
            grid_mass[a, i] += w * mass[b]
            for r in range(d):
                grid_momentum[a, i, r] += w * mass[b] * velocity[b, r]
                grid_force[a, i, r] += w * force[b, r]


@serial_or_parallel(PARALLEL_MIN_POINTS)
def g2p_field(
    nodes: np.ndarray, weights: np.ndarray, material: np.ndarray, field: np.ndarray
) -> np.ndarray:
    """S u: ``(P, d)`` values sum_i w_ip u_i^{a(p)} of a per-material field ``(M, G, d)``."""
    n_p, k = nodes.shape
    d = field.shape[2]
    out = np.zeros((n_p, d))
    for p in prange(n_p):
        a = material[p]
        for e in range(k):
            i = nodes[p, e]
            w = weights[p, e]
            for r in range(d):
                out[p, r] += w * field[a, i, r]
    return out


@njit(cache=True)
def mass_moments(
    nodes: np.ndarray,
    weights: np.ndarray,
    mass: np.ndarray,
    x: np.ndarray,
    material: np.ndarray,
    n_nodes: int,
    n_materials: int,
) -> np.ndarray:
    """sum_{p in alpha} w_ip m_p x_p ``(n_materials, n_nodes, d)`` for particle values ``x (P,
    d)`` (stencil entries with node -1 skipped): with positions, in kg m, the numerator of
    x^alpha = S^+alpha X (LR eq. 11); ``p2g_field``'s numerator for any field."""
    n_p, n_s = nodes.shape
    d = x.shape[1]
    out = np.zeros((n_materials, n_nodes, d))
    for p in range(n_p):
        mat = material[p]
        for s in range(n_s):
            i = nodes[p, s]
            if i < 0:
                continue
            wm = weights[p, s] * mass[p]
            for a in range(d):
                out[mat, i, a] += wm * x[p, a]
    return out


@njit(cache=True)
def p2g_field(
    nodes: np.ndarray,
    weights: np.ndarray,
    material: np.ndarray,
    mass: np.ndarray,
    values: np.ndarray,
    inv_grid_mass: np.ndarray,
) -> np.ndarray:
    """S+^a u: the mass-weighted field ``(M, G, d)`` sum_{p in a} w_ip m_p u_p / m_i^a.

    Args:
        values: particle values ``(P, d)``.
        inv_grid_mass: 1 / m_i^a ``(M, G)`` (0 on massless nodes).
    """
    n_m, n_g = inv_grid_mass.shape
    d = values.shape[1]
    out = mass_moments(nodes, weights, mass, values, material, n_g, n_m)
    for a in range(n_m):
        for i in range(n_g):
            for r in range(d):
                out[a, i, r] *= inv_grid_mass[a, i]
    return out


@serial_or_parallel(PARALLEL_MIN_POINTS)
def g2p_update(
    nodes: np.ndarray,
    weights: np.ndarray,
    grads: np.ndarray,
    material: np.ndarray,
    grid_v: np.ndarray,
    grid_v_end: np.ndarray,
    dt: float,
    F: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The grid sums of the particle update ``(S v (P, d), S v+ (P, d), F^{n+1} (P, d, d))``.

    S v = sum_i w_ip v_i^a (after the first correction), S v+ = sum_i w_ip v_i^{a+} (after the
    second), F^{n+1} = (I + dt sum_i v_i^{a+} grad w_ip^T) F_p^n (USL, LR section 2.2 step 11).
    """
    n_p, k = nodes.shape
    d = grid_v.shape[2]
    sv = np.zeros((n_p, d))
    sv_end = np.zeros((n_p, d))
    out_F = np.empty((n_p, d, d))
    for p in prange(n_p):
        a = material[p]
        L = np.zeros((d, d))
        for e in range(k):
            i = nodes[p, e]
            w = weights[p, e]
            for r in range(d):
                sv[p, r] += w * grid_v[a, i, r]
                sv_end[p, r] += w * grid_v_end[a, i, r]
                for s in range(d):
                    L[r, s] += grid_v_end[a, i, r] * grads[p, e, s]
        for r in range(d):
            for s in range(d):
                acc = F[p, r, s]
                for q in range(d):
                    acc += dt * L[r, q] * F[p, q, s]
                out_F[p, r, s] = acc
    return sv, sv_end, out_F
