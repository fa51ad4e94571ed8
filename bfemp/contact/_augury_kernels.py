"""numba kernels of the augury contact operator H (AUG eqs. 10-20), in any dimension d >= 1.

H is one P2G followed by one G2P at fixed particle positions x_p and masses m_p on the contact
grid (stencils: node indices ``nodes (P, K)`` and weights ``weights (P, K)``, any K):

    m_i     = sum_p N_ip m_p                                    (AUG eq. 10)
    m_i v_i = sum_p N_ip m_p (v_p + C_p (x_i - x_p))            (AUG eq. 17, C_p = B_p D_p^-1)
    v~_p    = sum_i N_ip v_i                                    (AUG eq. 19)
    B~_p    = sum_i N_ip v_i (x_i - x_p)^T                      (AUG eq. 20)

PIC is the same with C_p = 0 (AUG eqs. 10-12). Race-freedom: the scatter is one serial loop over
the particles (the foreground set is a few thousand particles, the loop a few microseconds per
thousand); the gather is parallel over particles (from ``PARALLEL_MIN`` on), each writing only
its own rows. The sums depend on the particle order only (bit-for-bit reproducible whatever
the thread count).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from bfemp._njit import serial_or_parallel
from bfemp.mpm._transfer_kernels import _affine_value


@njit(cache=True)
def p2g(
    nodes: np.ndarray,
    weights: np.ndarray,
    node_x: np.ndarray,
    x: np.ndarray,
    m: np.ndarray,
    v: np.ndarray,
    C: np.ndarray,
    apic: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """Node masses ``(G,)`` in kg and momenta ``(G, d)`` in kg m/s (serial scatter)."""
    n_p, k = nodes.shape
    d = x.shape[1]
    g = node_x.shape[0]
    mass = np.zeros(g)
    mom = np.zeros((g, d))
    for p in range(n_p):
        for s in range(k):
            w = weights[p, s]
            if w == 0.0:
                continue
            i = nodes[p, s]
            wm = w * m[p]
            mass[i] += wm
            for a in range(d):
                mom[i, a] += wm * _affine_value(v, C, apic, p, a, node_x, i, x)
    return mass, mom


#: below this many particles the gather runs serially (thread start-up costs ~1 ms per call on a
#: loaded machine, measured: the 2-particle gap test spent 1.5 ms per parallel call)
PARALLEL_MIN = 4096


@serial_or_parallel(PARALLEL_MIN)
def g2p(
    nodes: np.ndarray,
    weights: np.ndarray,
    node_x: np.ndarray,
    x: np.ndarray,
    grid_v: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Particle velocities ``(P, d)`` in m/s and B ``(P, d, d)`` in m^2/s (AUG eqs. 19-20)."""
    n_p, k = nodes.shape
    d = x.shape[1]
    out_v = np.zeros((n_p, d))
    out_B = np.zeros((n_p, d, d))
    for p in prange(n_p):  # a plain range in the serial build
        for s in range(k):
            w = weights[p, s]
            if w == 0.0:
                continue
            i = nodes[p, s]
            for a in range(d):
                wv = w * grid_v[i, a]
                out_v[p, a] += wv
                for b in range(d):
                    out_B[p, a, b] += wv * (node_x[i, b] - x[p, b])
    return out_v, out_B


@njit(cache=True)
def node_body_ranges(
    nodes: np.ndarray, weights: np.ndarray, body: np.ndarray, v: np.ndarray, n_nodes: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per contact node: whether particles of two or more bodies touch it ``(G,)`` and the
    componentwise smallest and largest velocity of the particles touching it ``(G, d)`` each
    (one serial pass over the stencils; entries of zero weight do not touch)."""
    n_p, k = nodes.shape
    d = v.shape[1]
    lo_b = np.full(n_nodes, np.iinfo(np.int64).max)
    hi_b = np.full(n_nodes, -1)
    v_lo = np.full((n_nodes, d), np.inf)
    v_hi = np.full((n_nodes, d), -np.inf)
    for p in range(n_p):
        b = body[p]
        for s in range(k):
            if weights[p, s] == 0.0:
                continue
            i = nodes[p, s]
            lo_b[i] = min(lo_b[i], b)
            hi_b[i] = max(hi_b[i], b)
            for a in range(d):
                v_lo[i, a] = min(v_lo[i, a], v[p, a])
                v_hi[i, a] = max(v_hi[i, a], v[p, a])
    shared = np.zeros(n_nodes, dtype=np.bool_)
    for i in range(n_nodes):
        shared[i] = hi_b[i] > lo_b[i]
    return shared, v_lo, v_hi


# ------------------------------------------------------------------ stencils on the contact grid
#: kernel ids of :func:`stencil_weights` (the order of ``bfemp.contact.augury.KERNELS``)
KERNEL_IDS = {"quadratic": 0, "aug_b2avg": 1, "linear": 2}


@njit(cache=True)
def _b2(r: float) -> tuple[float, float]:
    """Quadratic B-spline and its derivative at the distance ``r`` in cells."""
    a = abs(r)
    if a < 0.5:
        return 0.75 - a * a, -2.0 * r
    if a < 1.5:
        s = 1.0 if r > 0.0 else (-1.0 if r < 0.0 else 0.0)
        return 0.5 * (1.5 - a) ** 2, -(1.5 - a) * s
    return 0.0, 0.0


@njit(cache=True)
def _weight_1d(kernel: int, r: float) -> tuple[float, float]:
    if kernel == 0:
        return _b2(r)
    if kernel == 1:  # AUG App. B: the average of two shifted quadratic B-splines
        wa, da = _b2(r - 0.5)
        wb, db = _b2(r + 0.5)
        return 0.5 * (wa + wb), 0.5 * (da + db)
    a = abs(r)
    if a < 1.0:
        s = 1.0 if r > 0.0 else (-1.0 if r < 0.0 else 0.0)
        return 1.0 - a, -s
    return 0.0, 0.0


@njit(cache=True)
def stencil_weights(
    x: np.ndarray, dx: float, kernel: int, k: int, offsets: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tensor-product stencils of the points ``x (P, d)`` (grid origin 0, spacing ``dx`` m):
    grid indices ``ijk (P, K^d, d)``, weights ``(P, K^d)`` and gradients ``(P, K^d, d)`` in 1/m.
    ``offsets (K^d, d)``: the node offsets of the stencil, ``k`` nodes per axis."""
    n_p, d = x.shape
    n_s = offsets.shape[0]
    ijk = np.empty((n_p, n_s, d), dtype=np.int64)
    weights = np.ones((n_p, n_s))
    grads = np.ones((n_p, n_s, d))
    base = np.empty(d, dtype=np.int64)
    w1 = np.empty((d, k))
    dw1 = np.empty((d, k))
    for p in range(n_p):
        for a in range(d):
            xi = x[p, a] / dx
            if kernel == 0:
                b = np.int64(np.floor(xi - 0.5))
            else:
                b = np.int64(np.floor(xi)) - (k // 2 - 1)
            base[a] = b
            for j in range(k):
                w, dw = _weight_1d(kernel, xi - (b + j))
                w1[a, j] = w
                dw1[a, j] = dw / dx
        for s in range(n_s):
            for a in range(d):
                o = offsets[s, a]
                ijk[p, s, a] = base[a] + o
                weights[p, s] *= w1[a, o]
                for c in range(d):
                    grads[p, s, c] *= dw1[a, o] if a == c else w1[a, o]
    return ijk, weights, grads


@njit(cache=True)
def index_bounds(ijk: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lowest grid index per axis ``(d,)`` and the span of the box of ``ijk (P, S, d)``."""
    d = ijk.shape[2]
    lo = np.full(d, np.iinfo(np.int64).max, dtype=np.int64)
    hi = np.full(d, np.iinfo(np.int64).min, dtype=np.int64)
    for p in range(ijk.shape[0]):
        for s in range(ijk.shape[1]):
            for a in range(d):
                lo[a] = min(lo[a], ijk[p, s, a])
                hi[a] = max(hi[a], ijk[p, s, a])
    return lo, hi - lo + 1


@njit(cache=True)
def compact_dense(
    ijk: np.ndarray, lo: np.ndarray, span: np.ndarray, dx: float
) -> tuple[np.ndarray, np.ndarray]:
    """Compact node numbering of the grid indices ``ijk (P, S, d)`` inside the box ``lo``,
    ``span``: each entry's node ``(P, S)`` and the node positions ``(G, d)`` in m, nodes in
    increasing row-major grid order (what a sort of the linear indices gives, by a dense map
    over the box instead)."""
    n_p, n_s, d = ijk.shape
    strides = np.ones(d, dtype=np.int64)
    for a in range(d - 2, -1, -1):
        strides[a] = strides[a + 1] * span[a + 1]
    n_cells = strides[0] * span[0]
    slot = np.full(n_cells, -1, dtype=np.int64)
    lin = np.empty((n_p, n_s), dtype=np.int64)
    for p in range(n_p):
        for s in range(n_s):
            c = 0
            for a in range(d):
                c += (ijk[p, s, a] - lo[a]) * strides[a]
            lin[p, s] = c
            slot[c] = 0
    g = 0
    for c in range(n_cells):
        if slot[c] == 0:
            slot[c] = g
            g += 1
    node_x = np.empty((g, d))
    for c in range(n_cells):
        i = slot[c]
        if i >= 0:
            rest = c
            for a in range(d):
                node_x[i, a] = (rest // strides[a] + lo[a]) * dx
                rest = rest % strides[a]
    nodes = np.empty((n_p, n_s), dtype=np.int64)
    for p in range(n_p):
        for s in range(n_s):
            nodes[p, s] = slot[lin[p, s]]
    return nodes, node_x
