"""numba kernels of the MPM particle-grid transfers (Tables 1-3 of the BFEMP paper).

Every particle p has a stencil of K = 3**d grid nodes n(p, a) with weights w_pa = w_ip^n and
gradients g_pa = grad w_ip^n, all evaluated at the start-of-step position x_p^n. P2G scatters
(serial: several particles write the same node); G2P gathers (prange: each particle writes only
its own rows).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

#: A Cholesky pivot of D_p below this fraction of tr(D_p)/d marks D_p as singular.
_PIVOT_REL = 1e-12


@njit(cache=True)
def _affine_value(
    v: np.ndarray,
    C: np.ndarray,
    affine: bool,
    p: int,
    r: int,
    node_x: np.ndarray,
    i: int,
    x: np.ndarray,
) -> float:
    """Component r of v_p + C_p (x_i - x_p) (the APIC affine extrapolation of a particle value
    ``v (P, d)`` to node i; ``v[p, r]`` alone unless ``affine``)."""
    val = v[p, r]
    if affine:
        for c in range(x.shape[1]):
            val += C[p, r, c] * (node_x[i, c] - x[p, c])
    return val


@njit(cache=True)
def _kirchhoff_volume(
    piola: np.ndarray, F: np.ndarray, volume: np.ndarray, p: int, tau: np.ndarray
) -> None:
    """tau (d, d) = V_p^0 P_p F_p^T, the Kirchhoff stress times the rest volume (N m), whose
    product with grad w_ip is particle p's internal force on node i (BFEMP eq. 25)."""
    d = tau.shape[0]
    for r in range(d):
        for s in range(d):
            acc = 0.0
            for m in range(d):
                acc += piola[p, r, m] * F[p, s, m]
            tau[r, s] = volume[p] * acc


@njit(cache=True)
def _gathered(w: float, new: np.ndarray, old: np.ndarray, i: int, r: int, flip: bool) -> float:
    """Node i's share of a G2P gather, component r: w (u_i - u_i^n) (FLIP, added to the
    particle's own value) or w u_i (PIC, APIC)."""
    return w * (new[i, r] - old[i, r]) if flip else w * new[i, r]


@njit(cache=True)
def _deformation_update(G: np.ndarray, F: np.ndarray, p: int, out: np.ndarray) -> None:
    """out[p] (d, d) = G F_p^n, with G = sum_i x~_i grad w_ip^T the grid's deformation."""
    d = G.shape[0]
    for r in range(d):
        for c in range(d):
            acc = 0.0
            for m in range(d):
                acc += G[r, m] * F[p, m, c]
            out[p, r, c] = acc


@njit(cache=True)
def _p2g(
    nodes: np.ndarray,
    weights: np.ndarray,
    grid_x: np.ndarray,
    mpm_x: np.ndarray,
    mpm_mass: np.ndarray,
    mpm_v: np.ndarray,
    mpm_C: np.ndarray,
    affine: bool,
    mpm_a: np.ndarray,
    with_a: bool,
    mpm_Ca: np.ndarray,
    affine_a: bool,
    grid_mass: np.ndarray,
    grid_mom: np.ndarray,
    grid_ma: np.ndarray,
) -> None:
    """Accumulate m_i, m_i v_i and m_i a_i into the zeroed ``grid_*`` outputs.

    m_i v_i += w_ip m_p (v_p + C_p (x_i - x_p)), the affine term only when ``affine`` (APIC);
    m_i a_i += w_ip m_p (a_p + Ca_p (x_i - x_p)) when ``with_a``, the affine term only when
    ``affine_a``.
    """
    n_p, k = nodes.shape
    d = grid_x.shape[1]
    for p in range(n_p):
        m = mpm_mass[p]
        for a in range(k):
            i = nodes[p, a]
            wm = weights[p, a] * m
            grid_mass[i] += wm
            for r in range(d):
                grid_mom[i, r] += wm * _affine_value(mpm_v, mpm_C, affine, p, r, grid_x, i, mpm_x)
                if with_a:
                    acc = _affine_value(mpm_a, mpm_Ca, affine_a, p, r, grid_x, i, mpm_x)
                    grid_ma[i, r] += wm * acc


@njit(cache=True)
def _cholesky_solve_rows(D: np.ndarray, B: np.ndarray, C: np.ndarray) -> bool:
    """C = B D^-1 for symmetric positive definite D (d, d); False when D is numerically singular.

    D is overwritten by its lower Cholesky factor L. Since D is symmetric, each row c_r of C solves
    D c_r = b_r, i.e. L y = b_r then L^T c_r = y.
    """
    d = D.shape[0]
    scale = 0.0
    for r in range(d):
        scale += D[r, r]
    tiny = _PIVOT_REL * scale / d
    for j in range(d):
        s = D[j, j]
        for m in range(j):
            s -= D[j, m] * D[j, m]
        if not s > tiny:
            return False
        D[j, j] = np.sqrt(s)
        for r in range(j + 1, d):
            t = D[r, j]
            for m in range(j):
                t -= D[r, m] * D[j, m]
            D[r, j] = t / D[j, j]
    for row in range(d):
        for j in range(d):
            t = B[row, j]
            for m in range(j):
                t -= D[j, m] * C[row, m]
            C[row, j] = t / D[j, j]
        for j in range(d - 1, -1, -1):
            t = C[row, j]
            for m in range(j + 1, d):
                t -= D[m, j] * C[row, m]
            C[row, j] = t / D[j, j]
    return True


@njit(cache=True)
def _affine_matrix(D: np.ndarray, B: np.ndarray, C: np.ndarray, out: np.ndarray) -> bool:
    """out (d, d) = C = B D^-1 (Table 1's APIC C_p; ``C`` is scratch, D is overwritten), or
    zeros and False when D is numerically singular."""
    d = D.shape[0]
    solved = _cholesky_solve_rows(D, B, C)
    for r in range(d):
        for c in range(d):
            out[r, c] = C[r, c] if solved else 0.0
    return solved


@njit(cache=True, parallel=True)
def _g2p(
    nodes: np.ndarray,
    weights: np.ndarray,
    grads: np.ndarray,
    grid_x: np.ndarray,
    grid_x_new: np.ndarray,
    grid_v_old: np.ndarray,
    grid_v_new: np.ndarray,
    grid_a_new: np.ndarray,
    mpm_x: np.ndarray,
    mpm_v: np.ndarray,
    mpm_F: np.ndarray,
    flip: bool,
    apic: bool,
    with_a: bool,
    grid_a_old: np.ndarray,
    mpm_a: np.ndarray,
    a_like_v: bool,
    out_x: np.ndarray,
    out_v: np.ndarray,
    out_F: np.ndarray,
    out_C: np.ndarray,
    out_a: np.ndarray,
    out_Ca: np.ndarray,
    singular: np.ndarray,
) -> None:
    """Gather the end-of-step particle state into the ``out_*`` arrays (Tables 1-3).

    x_p = sum_i w x~_i;  F_p = (sum_i x~_i g^T) F_p^n;  v_p = sum_i w v~_i (PIC, APIC) or
    v_p^n + sum_i w (v~_i - v_i^n) (FLIP);  APIC: C_p = B_p D_p^-1 with the symmetrised B_p of
    Table 1, ``singular[p]`` set where D_p is not positive definite. Accelerations (``with_a``):
    a_p = sum_i w a_i, or with ``a_like_v`` exactly like the velocity (FLIP: a_p^n + sum_i w
    (a_i^{n+1} - a_i^n); APIC: also Ca_p = B^a_p D_p^-1 with a in place of v).
    """
    n_p, k = nodes.shape
    d = grid_x.shape[1]
    for p in prange(n_p):
        grid_def = np.zeros((d, d))  # sum_i x~_i g_ip^T
        for r in range(d):
            out_x[p, r] = 0.0
            out_v[p, r] = mpm_v[p, r] if flip else 0.0
            if with_a:
                out_a[p, r] = mpm_a[p, r] if (a_like_v and flip) else 0.0
        for a in range(k):
            i = nodes[p, a]
            w = weights[p, a]
            for r in range(d):
                out_x[p, r] += w * grid_x_new[i, r]
                out_v[p, r] += _gathered(w, grid_v_new, grid_v_old, i, r, flip)
                if with_a:
                    out_a[p, r] += _gathered(w, grid_a_new, grid_a_old, i, r, a_like_v and flip)
                for c in range(d):
                    grid_def[r, c] += grid_x_new[i, r] * grads[p, a, c]
        _deformation_update(grid_def, mpm_F, p, out_F)
        singular[p] = False
        if not apic:
            continue
        # Table 1: B_p = 1/2 sum_i w [v~_i (a_i + b_i)^T + (a_i - b_i) v~_i^T] with
        # a_i = x_i^n - x_p^n and b_i = x~_i - x_p^{n+1}; D_p = sum_i w a_i a_i^T.
        affine_a = with_a and a_like_v
        B = np.zeros((d, d))
        Ba = np.zeros((d, d))
        D = np.zeros((d, d))
        for a in range(k):
            i = nodes[p, a]
            w = weights[p, a]
            for r in range(d):
                ar = grid_x[i, r] - mpm_x[p, r]
                br = grid_x_new[i, r] - out_x[p, r]
                for c in range(d):
                    ac = grid_x[i, c] - mpm_x[p, c]
                    bc = grid_x_new[i, c] - out_x[p, c]
                    vr, vc = grid_v_new[i, r], grid_v_new[i, c]
                    B[r, c] += 0.5 * w * (vr * (ac + bc) + (ar - br) * vc)
                    D[r, c] += w * ar * ac
                    if affine_a:
                        ur, uc = grid_a_new[i, r], grid_a_new[i, c]
                        Ba[r, c] += 0.5 * w * (ur * (ac + bc) + (ar - br) * uc)
        D_a = D.copy()  # the solve overwrites D with its factor
        C = np.empty((d, d))
        singular[p] = not _affine_matrix(D, B, C, out_C[p])
        if affine_a and _cholesky_solve_rows(D_a, Ba, C):
            for r in range(d):
                for c in range(d):
                    out_Ca[p, r, c] = C[r, c]


@njit(cache=True, parallel=True)
def _apic_inertia(
    nodes: np.ndarray, weights: np.ndarray, grid_x: np.ndarray, mpm_x: np.ndarray
) -> np.ndarray:
    """D_p (P, d, d) = sum_i w_ip (x_i - x_p)(x_i - x_p)^T (Table 1)."""
    n_p, k = nodes.shape
    d = grid_x.shape[1]
    out = np.zeros((n_p, d, d))
    for p in prange(n_p):
        for a in range(k):
            i = nodes[p, a]
            w = weights[p, a]
            for r in range(d):
                ar = grid_x[i, r] - mpm_x[p, r]
                for c in range(d):
                    out[p, r, c] += w * ar * (grid_x[i, c] - mpm_x[p, c])
    return out


@njit(cache=True, parallel=True)
def _largest_particle_increment(
    node_moves: np.ndarray,
    nodes: np.ndarray,
    weights: np.ndarray,
    grads: np.ndarray,
    spacing: float,
) -> float:
    """max over particles p of |sum_i w_ip u_i|_inf and spacing |sum_i u_i grad w_ip^T|_inf for
    grid-node increments ``node_moves (G, d)`` in m (``bfemp.potential.increment_norm``)."""
    n_p, n_k = nodes.shape
    d = node_moves.shape[1]
    n_chunks = max(1, min(n_p // 2048, 64))
    best = np.zeros(n_chunks)
    for c in prange(n_chunks):
        lo = c * n_p // n_chunks
        hi = (c + 1) * n_p // n_chunks
        u = np.empty(d)
        strain = np.empty((d, d))
        m = 0.0
        for p in range(lo, hi):
            for a in range(d):
                u[a] = 0.0
                for b in range(d):
                    strain[a, b] = 0.0
            for k in range(n_k):
                i = nodes[p, k]
                w = weights[p, k]
                for a in range(d):
                    ua = node_moves[i, a]
                    u[a] += w * ua
                    for b in range(d):
                        strain[a, b] += ua * grads[p, k, b]
            for a in range(d):
                m = max(m, abs(u[a]))
                for b in range(d):
                    m = max(m, spacing * abs(strain[a, b]))
        best[c] = m
    return best.max()
