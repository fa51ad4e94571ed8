"""2D fast path of the explicit engine: P2G with forces and G2P on a dense box grid.

The general path (``_explicit_kernels``) stores each step's stencils ``(P, 9)`` weights and
``(P, 9, 2)`` gradients and compacts the active nodes; in 2D that memory traffic dominated the
step (measured at 131k particles). Here, as in Taichi's MLS-MPM, each kernel recomputes the
quadratic B-spline weights of its particle from x_p and indexes a dense box of nodes
``[lo, lo + extent)`` (the stencils' bounding box) directly, node id = (i - lo0) * extent1 +
(j - lo1); the active nodes are the box nodes with mass > 0, in the same (lexicographic) order
as ``particle_stencils``' active nodes.

With quadratic B-splines, sum_i w_ip (x_i - x_p)(x_i - x_p)^T = dx^2 / 4 I and the symmetrised
APIC B_p of Table 1 equals sum_i w_ip v_i (x_i - x_p)^T when x~_i = x_i + dt v_i (the dt terms
cancel by sum_i w_ip v_i = v_p^{n+1}), so G2P is C_p = 4 / dx^2 sum_i w_ip v_i (x_i - x_p)^T,
x_p += dt v_p, F_p <- (I + dt sum_i v_i grad w_ip^T) F_p: the same update as the general path
up to round-off (tested). P2G scatters into per-chunk slabs (``_explicit_kernels``), race-free.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from bfemp.mpm._explicit_kernels import SLAB_BUDGET, _reduce_slabs


@njit(cache=True)
def _weights(fx: float) -> tuple:
    """Weights of the nodes base, base+1, base+2 on one axis (``fx`` in [0.5, 1.5))."""
    a = 1.5 - fx
    b = fx - 1.0
    c = fx - 0.5
    return (0.5 * a * a, 0.75 - b * b, 0.5 * c * c)


@njit(cache=True)
def _derivatives(fx: float, inv_dx: float) -> tuple:
    """Derivatives in 1/m of the weights of ``_weights``."""
    return (-(1.5 - fx) * inv_dx, -2.0 * (fx - 1.0) * inv_dx, (fx - 0.5) * inv_dx)


@njit(cache=True)
def _stencil(xi: np.ndarray, p: int, inv_dx: float, lo0: int, lo1: int, stride: int) -> tuple:
    """Particle p's offsets ``fx0, fx1`` from its base node (grid units), per-axis weights
    ``w0, w1`` and derivatives ``d0, d1`` (1/m) of the 3 x 3 stencil, and the box id of its
    base node."""
    f0 = np.floor(xi[p, 0] - 0.5)
    f1 = np.floor(xi[p, 1] - 0.5)
    fx0 = xi[p, 0] - f0
    fx1 = xi[p, 1] - f1
    node0 = (np.int64(f0) - lo0) * stride + (np.int64(f1) - lo1)
    w0, w1 = _weights(fx0), _weights(fx1)
    return fx0, fx1, w0, w1, _derivatives(fx0, inv_dx), _derivatives(fx1, inv_dx), node0


@njit(cache=True, parallel=True)
def _grid_units(x, o0, o1, inv_dx, n_chunks, xi):  # noqa: ANN001, ANN201
    """xi = (x - origin) / dx ``(P, 2)``; the smallest and largest base node ``(4,)`` (i_min,
    j_min, i_max, j_max), and per chunk of particles the lexicographically first and last base
    node ``(C, 2)`` each: with the box's row stride above any j spread, their box ids are the
    chunk's smallest and largest (``_box_ranges`` in one pass with the units: a parallel
    region fewer, whose thread wake-ups cost about 0.15 ms a step at 33k particles)."""
    n_p = x.shape[0]
    lo = np.empty((n_chunks, 2), dtype=np.int64)
    hi = np.empty((n_chunks, 2), dtype=np.int64)
    first = np.empty((n_chunks, 2), dtype=np.int64)
    last = np.empty((n_chunks, 2), dtype=np.int64)
    for c in prange(n_chunks):
        mn0 = mn1 = f0 = f1 = np.int64(1) << 62
        mx0 = mx1 = l0 = l1 = -(np.int64(1) << 62)
        for p in range(c * n_p // n_chunks, (c + 1) * n_p // n_chunks):
            a = (x[p, 0] - o0) * inv_dx
            b = (x[p, 1] - o1) * inv_dx
            xi[p, 0] = a
            xi[p, 1] = b
            b0 = np.int64(np.floor(a - 0.5))
            b1 = np.int64(np.floor(b - 0.5))
            mn0 = min(mn0, b0)
            mn1 = min(mn1, b1)
            mx0 = max(mx0, b0)
            mx1 = max(mx1, b1)
            if b0 < f0 or (b0 == f0 and b1 < f1):
                f0, f1 = b0, b1
            if b0 > l0 or (b0 == l0 and b1 > l1):
                l0, l1 = b0, b1
        lo[c, 0], lo[c, 1], hi[c, 0], hi[c, 1] = mn0, mn1, mx0, mx1
        first[c, 0], first[c, 1], last[c, 0], last[c, 1] = f0, f1, l0, l1
    # scalar loops: in a parallel function an array reduction such as lo[:, 0].min() is a
    # parallel region of its own (four of them cost 0.2 ms a step at 33k particles)
    out = np.empty(4, dtype=np.int64)
    out[0], out[1], out[2], out[3] = lo[0, 0], lo[0, 1], hi[0, 0], hi[0, 1]
    for c in range(1, n_chunks):
        out[0] = min(out[0], lo[c, 0])
        out[1] = min(out[1], lo[c, 1])
        out[2] = max(out[2], hi[c, 0])
        out[3] = max(out[3], hi[c, 1])
    return out, first, last


@njit(cache=True, parallel=True)
def _box_ranges(xi: np.ndarray, lo0: int, lo1: int, stride: int, n_chunks: int):  # noqa: ANN201
    """Node-id range [lo_c, hi_c] of each chunk of particles (grid units ``xi (P, 2)``)."""
    n_p = xi.shape[0]
    lo = np.empty(n_chunks, dtype=np.int64)
    hi = np.empty(n_chunks, dtype=np.int64)
    for c in prange(n_chunks):
        mn = np.int64(1) << 62
        mx = np.int64(-1)
        for p in range(c * n_p // n_chunks, (c + 1) * n_p // n_chunks):
            b0 = np.int64(np.floor(xi[p, 0] - 0.5)) - lo0
            b1 = np.int64(np.floor(xi[p, 1] - 0.5)) - lo1
            node = b0 * stride + b1
            mn = min(mn, node)
            mx = max(mx, node + 2 * stride + 2)
        if mx < 0:
            mn = 0
        lo[c] = mn
        hi[c] = mx
    return lo, hi


@njit(cache=True, parallel=True)
def _p2g_2d(
    xi: np.ndarray,
    dx: float,
    lo0: int,
    lo1: int,
    stride: int,
    mpm_mass: np.ndarray,
    mpm_v: np.ndarray,
    mpm_C: np.ndarray,
    affine: bool,
    piola: np.ndarray,
    mpm_F: np.ndarray,
    volume: np.ndarray,
    lo: np.ndarray,
    offset: np.ndarray,
    scratch: np.ndarray,
) -> None:
    """Slab rows [m, m v (2), f (2)]; f_i -= V_p P F^T grad w_ip (see ``_explicit_kernels``)."""
    n_p = xi.shape[0]
    n_chunks = lo.shape[0]
    inv_dx = 1.0 / dx
    for c in prange(n_chunks):
        base_row = offset[c] - lo[c]
        for p in range(c * n_p // n_chunks, (c + 1) * n_p // n_chunks):
            fx0, fx1, w0, w1, d0, d1, node0 = _stencil(xi, p, inv_dx, lo0, lo1, stride)
            # tau = V_p^0 P F^T
            P = piola[p]
            F = mpm_F[p]
            vol = volume[p]
            t00 = vol * (P[0, 0] * F[0, 0] + P[0, 1] * F[0, 1])
            t01 = vol * (P[0, 0] * F[1, 0] + P[0, 1] * F[1, 1])
            t10 = vol * (P[1, 0] * F[0, 0] + P[1, 1] * F[0, 1])
            t11 = vol * (P[1, 0] * F[1, 0] + P[1, 1] * F[1, 1])
            m = mpm_mass[p]
            v0 = mpm_v[p, 0]
            v1 = mpm_v[p, 1]
            c00 = c01 = c10 = c11 = 0.0
            if affine:
                c00 = mpm_C[p, 0, 0]
                c01 = mpm_C[p, 0, 1]
                c10 = mpm_C[p, 1, 0]
                c11 = mpm_C[p, 1, 1]
            for a in range(3):
                r0 = (a - fx0) * dx
                for b in range(3):
                    r1 = (b - fx1) * dx
                    w = w0[a] * w1[b]
                    g0 = d0[a] * w1[b]
                    g1 = w0[a] * d1[b]
                    row = base_row + node0 + a * stride + b
                    wm = w * m
                    scratch[row, 0] += wm
                    scratch[row, 1] += wm * (v0 + c00 * r0 + c01 * r1)
                    scratch[row, 2] += wm * (v1 + c10 * r0 + c11 * r1)
                    scratch[row, 3] -= t00 * g0 + t01 * g1
                    scratch[row, 4] -= t10 * g0 + t11 * g1


@njit(cache=True, parallel=True)
def _g2p_2d(
    xi: np.ndarray,
    dx: float,
    lo0: int,
    lo1: int,
    stride: int,
    box_v_old: np.ndarray,
    box_v: np.ndarray,
    dt: float,
    mpm_x: np.ndarray,
    mpm_v: np.ndarray,
    mpm_F: np.ndarray,
    flip: bool,
    out_x: np.ndarray,
    out_v: np.ndarray,
    out_F: np.ndarray,
    out_C: np.ndarray,
) -> None:
    """x_p += dt v_p, v_p (PIC/APIC, FLIP), F_p <- (I + dt grad v) F_p, C_p (module doc; PIC
    and FLIP: ``out_C`` is the APIC C_p, set to zero by the caller: forming it unconditionally
    costs less than a branch per node, 8 % of the kernel at 33k particles)."""
    n_p = xi.shape[0]
    inv_dx = 1.0 / dx
    scale = 4.0 * inv_dx * inv_dx
    for p in prange(n_p):
        fx0, fx1, w0, w1, d0, d1, node0 = _stencil(xi, p, inv_dx, lo0, lo1, stride)
        v0 = v1 = 0.0
        u0 = u1 = 0.0  # FLIP increment
        g00 = g01 = g10 = g11 = 0.0
        b00 = b01 = b10 = b11 = 0.0
        for a in range(3):
            r0 = (a - fx0) * dx
            for b in range(3):
                r1 = (b - fx1) * dx
                node = node0 + a * stride + b
                w = w0[a] * w1[b]
                gr0 = d0[a] * w1[b]
                gr1 = w0[a] * d1[b]
                vi0 = box_v[node, 0]
                vi1 = box_v[node, 1]
                v0 += w * vi0
                v1 += w * vi1
                if flip:
                    u0 += w * (vi0 - box_v_old[node, 0])
                    u1 += w * (vi1 - box_v_old[node, 1])
                g00 += vi0 * gr0
                g01 += vi0 * gr1
                g10 += vi1 * gr0
                g11 += vi1 * gr1
                wv0 = w * vi0  # the APIC sums (PIC and FLIP: dropped by the caller)
                wv1 = w * vi1
                b00 += wv0 * r0
                b01 += wv0 * r1
                b10 += wv1 * r0
                b11 += wv1 * r1
        out_x[p, 0] = mpm_x[p, 0] + dt * v0
        out_x[p, 1] = mpm_x[p, 1] + dt * v1
        if flip:
            out_v[p, 0] = mpm_v[p, 0] + u0
            out_v[p, 1] = mpm_v[p, 1] + u1
        else:
            out_v[p, 0] = v0
            out_v[p, 1] = v1
        a00 = 1.0 + dt * g00
        a01 = dt * g01
        a10 = dt * g10
        a11 = 1.0 + dt * g11
        F = mpm_F[p]
        out_F[p, 0, 0] = a00 * F[0, 0] + a01 * F[1, 0]
        out_F[p, 0, 1] = a00 * F[0, 1] + a01 * F[1, 1]
        out_F[p, 1, 0] = a10 * F[0, 0] + a11 * F[1, 0]
        out_F[p, 1, 1] = a10 * F[0, 1] + a11 * F[1, 1]
        out_C[p, 0, 0] = scale * b00
        out_C[p, 0, 1] = scale * b01
        out_C[p, 1, 0] = scale * b10
        out_C[p, 1, 1] = scale * b11


#: the dense box may hold at most this many nodes per particle stencil entry (else: general path)
BOX_BUDGET = 8


@dataclass(frozen=True)
class DenseBox:
    """The dense node box of one 2D step and the particles in grid units.

    Attributes:
        xi: particle positions in grid units ``(x - origin) / dx`` ``(P, 2)``.
        lo: integer coordinates of the box's first node ``(2,)``.
        extent: nodes per axis ``(2,)``.
        active: box ids of the nodes with mass ``(G,)``, increasing.
        node_x: positions of the active nodes ``(G, 2)`` in m (``Grid.node_positions``).
    """

    xi: np.ndarray
    lo: np.ndarray
    extent: np.ndarray
    active: np.ndarray
    node_x: np.ndarray

    @property
    def size(self) -> int:
        """Number of box nodes."""
        return int(self.extent[0] * self.extent[1])

    def scatter(self, values: np.ndarray) -> np.ndarray:
        """Per-active-node ``values (G, 2)`` as a box array ``(size, 2)``, zero elsewhere."""
        return _scatter(self.active, np.ascontiguousarray(values, dtype=np.float64), self.size)


def dense_p2g(
    origin: np.ndarray,
    dx: float,
    mpm_x: np.ndarray,
    mpm_mass: np.ndarray,
    mpm_v: np.ndarray,
    mpm_C: np.ndarray | None,
    piola: np.ndarray,
    mpm_F: np.ndarray,
    volume: np.ndarray,
    n_chunks: int,
    alloc: Callable[[tuple[int, ...]], np.ndarray] = np.empty,
) -> tuple[DenseBox, np.ndarray, np.ndarray, np.ndarray] | None:
    """2D P2G with internal forces on a dense box: ``(box, mass (G,), momentum (G, 2),
    force (G, 2))`` on the active nodes, or None when the box would exceed ``BOX_BUDGET``.
    ``alloc(shape)`` gives the particle-sized work arrays (``BufferPool.empty``)."""
    n_p = mpm_x.shape[0]
    xi = alloc((n_p, 2))
    n_chunks = max(1, min(int(n_chunks), n_p))
    origin_x, origin_y = float(origin[0]), float(origin[1])
    bounds, first, last = _grid_units(mpm_x, origin_x, origin_y, 1.0 / dx, n_chunks, xi)
    lo = bounds[:2].copy()
    extent = bounds[2:] - lo + 3
    if float(extent[0]) * float(extent[1]) > BOX_BUDGET * 9 * n_p:
        return None
    stride = int(extent[1])
    size = int(extent[0]) * stride
    ranges = ((first - lo) @ [stride, 1], (last - lo) @ [stride, 1] + 2 * stride + 2)
    sizes = ranges[1] - ranges[0] + 1
    while n_chunks > 1 and sizes.sum() > SLAB_BUDGET * size:
        n_chunks //= 2
        ranges = _box_ranges(xi, int(lo[0]), int(lo[1]), stride, n_chunks)
        sizes = ranges[1] - ranges[0] + 1
    offset = np.zeros(n_chunks, dtype=np.int64)
    offset[1:] = np.cumsum(sizes)[:-1]
    scratch = alloc((int(sizes.sum()), 5))
    scratch.fill(0.0)
    affine = mpm_C is not None
    C = mpm_C if affine else np.zeros((0, 2, 2))
    _p2g_2d(
        xi,
        dx,
        int(lo[0]),
        int(lo[1]),
        stride,
        mpm_mass,
        mpm_v,
        C,
        affine,
        piola,
        mpm_F,
        volume,
        ranges[0],
        offset,
        scratch,
    )
    out = np.empty((size, 5))
    _reduce_slabs(scratch, ranges[0], ranges[1], offset, out)
    origin = np.asarray(origin, dtype=np.float64)
    active, node_x, mass, momentum, force = _active_rows(out, origin, float(dx), lo, stride)
    box = DenseBox(xi=xi, lo=lo, extent=extent, active=active, node_x=node_x)
    return box, mass, momentum, force


@njit(cache=True)
def _active_rows(out, origin, dx, lo, stride):  # noqa: ANN001, ANN202
    """The box nodes with mass: ids ``(G,)`` (increasing), positions origin + dx ijk ``(G,
    2)`` m, and their rows of ``out (size, 5)``: mass ``(G,)``, momentum ``(G, 2)``, force
    ``(G, 2)``. One pass: numpy's mask, gathers, copies and node positions took 0.2 ms at 33k
    particles, as long as the stresses of a fifth of them."""
    n = 0
    for i in range(out.shape[0]):
        if out[i, 0] > 0.0:
            n += 1
    active = np.empty(n, dtype=np.int64)
    node_x = np.empty((n, 2))
    mass = np.empty(n)
    momentum = np.empty((n, 2))
    force = np.empty((n, 2))
    k = 0
    for i in range(out.shape[0]):
        if out[i, 0] > 0.0:
            active[k] = i
            node_x[k, 0] = origin[0] + dx * np.float64(i // stride + lo[0])
            node_x[k, 1] = origin[1] + dx * np.float64(i % stride + lo[1])
            mass[k] = out[i, 0]
            momentum[k, 0] = out[i, 1]
            momentum[k, 1] = out[i, 2]
            force[k, 0] = out[i, 3]
            force[k, 1] = out[i, 4]
            k += 1
    return active, node_x, mass, momentum, force


@njit(cache=True)
def _scatter(active: np.ndarray, values: np.ndarray, size: int) -> np.ndarray:
    """``values (G, 2)`` of the active nodes as a box array ``(size, 2)``, zero elsewhere."""
    out = np.zeros((size, 2))
    for k in range(active.shape[0]):
        out[active[k], 0] = values[k, 0]
        out[active[k], 1] = values[k, 1]
    return out


def dense_g2p(
    box: DenseBox,
    dx: float,
    scheme: str,
    grid_v_old: np.ndarray,
    grid_v: np.ndarray,
    dt: float,
    mpm_x: np.ndarray,
    mpm_v: np.ndarray,
    mpm_F: np.ndarray,
    alloc: Callable[[tuple[int, ...]], np.ndarray] = np.empty,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(mpm_x, mpm_v, mpm_F, mpm_C)`` after the 2D G2P (active-node velocities in m/s);
    ``alloc(shape)`` gives the output arrays."""
    n_p = mpm_x.shape[0]
    flip = scheme == "flip"
    out_x = alloc((n_p, 2))
    out_v = alloc((n_p, 2))
    out_F = alloc((n_p, 2, 2))
    out_C = alloc((n_p, 2, 2))
    box_v_old = box.scatter(grid_v_old) if flip else np.zeros((0, 2))
    _g2p_2d(
        box.xi,
        dx,
        int(box.lo[0]),
        int(box.lo[1]),
        int(box.extent[1]),
        box_v_old,
        box.scatter(grid_v),
        float(dt),
        mpm_x,
        mpm_v,
        mpm_F,
        flip,
        out_x,
        out_v,
        out_F,
        out_C,
    )
    if scheme != "apic":
        out_C[:] = 0.0
    return out_x, out_v, out_F, out_C
