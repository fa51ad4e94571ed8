"""The augury contact operator H and the augury correction (AUG eqs. 10-46), physics only.

Foreground particles p (positions x_p, masses m_p, velocities v_p, APIC matrices B_p) are
transferred to a background contact grid of spacing ``dx`` (origin 0) and back:
H = one P2G (AUG eqs. 10, 17) and one G2P (AUG eqs. 19-20) at fixed positions, ``ContactOperator``.
With the generalised velocity V_p = {v_p, B_p} (AUG eq. 21) and the prediction V-bar (AUG eq.
27), the augury correction (AUG eqs. 29, 36-46) is

    V^_0 = H V-bar;   for m = 0..N-1:  W_{m+1} = undesirable part of (V^_m - V-bar),
                                       V^_{m+1} = V^_m + H W_{m+1} - W_{m+1}
    A^ = (V^_N - V-bar) / tau.

The undesirable part (``undesirable``): mode ``"separate"`` (AUG eq. 38): W = {dv, dB} where
dv . n > 0 (a tensile correction, pulling the particle toward the other body), else 0; mode
``"friction"`` (AUG eqs. 42-46 with their misprints fixed):
dv^t = (I - n n^T) dv, s = min(|dv^t|, -mu dv.n), dv^u = dv^t - s dv^t/|dv^t| where
dv . n <= 0, dv^u = dv otherwise; dB^u = dB always.

Measured limits (issue 14; design note ``measurements``, augury, with the numbers). With
mu = 0 and a fixed set of tensile particles the undesirable part is P e (P: the per-particle
tangential projection) and P e_{m+1} = P H P e_m; H is self-adjoint in the (generalised) mass
inner product with 0 <= H <= I, so this converges to 0, but slowly where P H P has eigenvalues
near 1. H acts on the whole V-bar, not on its increment, so N iterations leave a fixed fraction
of the sliding velocity every step: the loss per unit time does not fall with h. Static
friction goes the other way: the iterations that free the sliding also free the sticking.

Energy guard (bfemp's, ``energy_guard=True``): an iterate V^_{m+1} whose generalised kinetic
energy 1/2 sum m (|v|^2 + B D^-1 : B) exceeds that of V-bar is not taken, the iterations stop at
V^_m. Measured (design note ``measurements``, augury): without it the correction added
kinetic energy with friction and N > 1 and a block on a 30 degree incline left the plate; not
explained (AUG eq. 44 keeps the normal part of a change outside the cone, so H W can add normal
pushes). Every partial sum V^_m conserves momentum, so the guard keeps the conservation.

Every G = H - I term carries no net linear momentum (both transfers) and, with APIC and the B
term, no net angular momentum (AUG eq. 36), so A^ carries none whatever N and the mode.

Kernels per axis (tensor products in d dimensions): ``"quadratic"`` (bfemp's quadratic
B-spline, 3 nodes, D = dx^2/4 I), ``"aug_b2avg"`` (AUG App. B: the quadratic B-spline averaged
over copies shifted by +-dx/2, 4 nodes, D = dx^2/2 I; AUG eq. 62's /8 is a misprint for /4) and
``"linear"`` (hats, 2 nodes, D_p depends on x_p; the 1D gap test of AUG section 3.1).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from bfemp.contact._augury_kernels import (
    KERNEL_IDS,
    compact_dense,
    g2p,
    index_bounds,
    p2g,
    stencil_weights,
)
from bfemp.mpm.transfer import apic_inertia

__all__ = [
    "KERNELS",
    "MODES",
    "ContactOperator",
    "ContactStencils",
    "augury_correction",
    "contact_stencils",
    "facet_normals",
    "undesirable",
]

#: contact-grid kernels and their nodes per axis
KERNELS = {"quadratic": 3, "aug_b2avg": 4, "linear": 2}
#: augury modes (AUG eq. 38 and AUG eqs. 42-46)
MODES = ("friction", "separate")


@dataclass(frozen=True)
class ContactStencils:
    """Stencils of foreground particles on the contact grid.

    Attributes:
        nodes: compact node indices ``(P, K^d)`` into ``node_x``.
        weights: N_ip ``(P, K^d)``.
        grads: grad N_ip ``(P, K^d, d)`` in 1/m.
        node_x: positions of the touched nodes ``(G, d)`` in m.
        D: the APIC inertia D_p = sum_i N_ip (x_i - x_p)(x_i - x_p)^T ``(P, d, d)`` in m^2
            (AUG eq. 18).
        dx: grid spacing in m.
    """

    nodes: np.ndarray
    weights: np.ndarray
    grads: np.ndarray
    node_x: np.ndarray
    D: np.ndarray
    dx: float

    @property
    def n_nodes(self) -> int:
        """Number of touched contact-grid nodes."""
        return self.node_x.shape[0]


@functools.cache
def _stencil_offsets(d: int, k: int) -> np.ndarray:
    """Node offsets ``(k^d, d)`` of a tensor-product stencil, row-major."""
    grid = np.meshgrid(*[np.arange(k)] * d, indexing="ij")
    return np.ascontiguousarray(np.stack(grid, axis=-1).reshape(-1, d), dtype=np.int64)


def _compact_sorted(
    ijk: np.ndarray, lo: np.ndarray, span: np.ndarray, dx: float
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`compact_dense`'s result by a sort, for boxes too large for a dense map."""
    lin = np.ravel_multi_index(tuple(np.moveaxis(ijk - lo, -1, 0)), tuple(span))
    uniq, inverse = np.unique(lin.reshape(-1), return_inverse=True)
    node_ijk = np.stack(np.unravel_index(uniq, tuple(span)), axis=1)
    return inverse.reshape(lin.shape).astype(np.int64), (node_ijk + lo) * dx


def contact_stencils(x: np.ndarray, dx: float, kernel: str = "quadratic") -> ContactStencils:
    """Tensor-product stencils of the points ``x (P, d)`` on the grid of spacing ``dx`` (origin 0).

    Any d >= 1 and any kernel of ``KERNELS``; numba kernels for the weights, the compact node
    numbering (a dense map over the bounding box, a sort for far-apart points) and D_p.
    """
    x = np.ascontiguousarray(x, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] < 1:
        raise ValueError(f"contact_stencils: x must have shape (P, d), got {x.shape}")
    if kernel not in KERNELS:
        raise ValueError(
            f"contact_stencils: kernel must be one of {sorted(KERNELS)}, got {kernel!r}"
        )
    n_p, d = x.shape
    k = KERNELS[kernel]
    offsets = _stencil_offsets(d, k)
    ijk, weights, grads = stencil_weights(x, float(dx), KERNEL_IDS[kernel], k, offsets)
    if n_p == 0:
        return ContactStencils(
            np.zeros((0, offsets.shape[0]), np.int64),
            weights,
            grads,
            np.zeros((0, d)),
            np.zeros((0, d, d)),
            float(dx),
        )
    lo, span = index_bounds(ijk)
    if float(np.prod(span.astype(np.float64))) <= max(1 << 20, 8 * ijk.shape[0] * ijk.shape[1]):
        nodes, node_x = compact_dense(ijk, lo, span, float(dx))  # a dense map over the box
    else:  # far-apart points: a sort of the linear indices
        nodes, node_x = _compact_sorted(ijk, lo, span, float(dx))
    D = apic_inertia(nodes, weights, node_x, x)
    return ContactStencils(nodes, weights, grads, node_x, D, float(dx))


class ContactOperator:
    """H at fixed positions and masses (module docstring): ``apply(v, B) -> (v~, B~)``.

    Args:
        stencils: ``contact_stencils`` of the particles at x_p.
        x: particle positions ``(P, d)`` in m.
        mass: particle masses ``(P,)`` in kg (> 0).
        apic: H_APIC (True) or H_PIC (False: B is ignored on input and returned as zeros).
        kinematic: ``(P,)`` bool, particles of infinite inertia (scripted FEM nodes; None:
            none). A contact node that any of them touches takes their mass-weighted velocity
            (and affine part) alone, sum_k w_ik m_k (v_k + C_k (x_i - x_k)) / sum_k w_ik m_k over
            the kinematic k, so contact cannot move a scripted body, whatever its density. H
            then conserves momentum only among the other particles; the momentum the kinematic
            ones exchange is the caller's to report. Their own energy is left out of
            ``kinetic_energy`` (it is scripted). Not in AUG, which has no scripted bodies.
    """

    def __init__(
        self,
        stencils: ContactStencils,
        x: np.ndarray,
        mass: np.ndarray,
        apic: bool = True,
        kinematic: np.ndarray | None = None,
    ) -> None:
        self.stencils = stencils
        self.x = np.ascontiguousarray(x, dtype=np.float64)
        self.mass = np.ascontiguousarray(mass, dtype=np.float64)
        self.apic = bool(apic)
        self.applications = 0
        d = self.x.shape[1]
        if kinematic is not None:
            kinematic = np.asarray(kinematic, dtype=bool)
            if kinematic.shape != (self.x.shape[0],):
                raise ValueError(
                    f"ContactOperator: kinematic must have shape ({self.x.shape[0]},), "
                    f"got {kinematic.shape}"
                )
        self.kinematic = kinematic if kinematic is not None and kinematic.any() else None
        if self.apic and self.x.shape[0]:
            det = np.linalg.det(stencils.D)
            if np.any(np.abs(det) <= 1e-14 * stencils.dx ** (2 * d)):
                bad = np.flatnonzero(np.abs(det) <= 1e-14 * stencils.dx ** (2 * d))
                raise ValueError(
                    f"ContactOperator: APIC inertia D_p is singular at particles "
                    f"{bad[:10].tolist()} (a linear-hat stencil with the particle on a node)"
                )
            self.D_inv = np.linalg.inv(stencils.D)
        else:
            self.D_inv = np.zeros((self.x.shape[0], d, d))
        self._zero_C = np.zeros((self.x.shape[0], d, d))

    def kinetic_energy(self, v: np.ndarray, B: np.ndarray) -> float:
        """Generalised kinetic energy 1/2 sum_p m_p (|v_p|^2 + B_p D_p^-1 : B_p) in J of
        ``v (P, d)`` and ``B (P, d, d)`` (PIC: the velocity term only)."""
        mass = self.mass if self.kinematic is None else np.where(self.kinematic, 0.0, self.mass)
        e = np.einsum("p,pd,pd->", mass, v, v)
        if self.apic:
            e += np.einsum("p,pab,pbc,pac->", mass, B, self.D_inv, B)
        return 0.5 * float(e)

    def apply(self, v: np.ndarray, B: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """H {v, B}: ``(v~ (P, d), B~ (P, d, d))``; B~ is zero for PIC."""
        st = self.stencils
        self.applications += 1
        if self.apic and B is not None:
            C = np.ascontiguousarray(np.matmul(B, self.D_inv))
        else:
            C = self._zero_C
        v = np.ascontiguousarray(v, dtype=np.float64)
        mass, mom = p2g(st.nodes, st.weights, st.node_x, self.x, self.mass, v, C, self.apic)
        grid_v = np.zeros_like(mom)
        heavy = mass > 0.0
        grid_v[heavy] = mom[heavy] / mass[heavy, None]
        if self.kinematic is not None:  # infinite inertia: the scripted velocity alone
            k = self.kinematic
            mass_k, mom_k = p2g(
                st.nodes[k],
                st.weights[k],
                st.node_x,
                self.x[k],
                self.mass[k],
                v[k],
                C[k],
                self.apic,
            )
            held = mass_k > 0.0
            grid_v[held] = mom_k[held] / mass_k[held, None]
        out_v, out_B = g2p(st.nodes, st.weights, st.node_x, self.x, grid_v)
        if not self.apic:
            out_B[:] = 0.0
        return out_v, out_B


def facet_normals(x: np.ndarray, facets: np.ndarray, opposite: np.ndarray) -> np.ndarray:
    """Area-weighted outward facet normals ``(k, d)`` (length = facet length or area).

    Args:
        x: node positions ``(N, d)`` in m.
        facets: boundary facets ``(k, d)`` (edges in 2D, triangles in 3D), node indices.
        opposite: the vertex of each facet's cell that is not on the facet ``(k,)``: the normal
            points away from it.
    """
    d = x.shape[1]
    p = x[facets]
    if d == 2:
        e = p[:, 1] - p[:, 0]
        n = np.stack([e[:, 1], -e[:, 0]], axis=1)
    elif d == 3:
        n = 0.5 * np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    else:
        raise ValueError(f"facet_normals: d must be 2 or 3, got {d}")
    inward = np.einsum("kd,kd->k", x[opposite] - p[:, 0], n) > 0.0
    n[inward] *= -1.0
    return n


def undesirable(
    dv: np.ndarray, dB: np.ndarray, normals: np.ndarray, mode: str, mu: float
) -> tuple[np.ndarray, np.ndarray]:
    """The undesirable part W = {dv^u, dB^u} of a change {dv, dB} (AUG eq. 38 or AUG eqs. 42-46).

    Args:
        dv: velocity changes ``(P, d)`` in m/s (measured from V-bar, AUG eq. 37).
        dB: B changes ``(P, d, d)`` in m^2/s.
        normals: outward unit normals of each particle's own body ``(P, d)``; a zero normal
            gives dv . n = 0 (compressive), so ``"separate"`` keeps the whole change and
            ``"friction"`` removes its tangential part (all of dv).
        mode: ``"separate"`` or ``"friction"``.
        mu: Coulomb coefficient (``"friction"`` only), >= 0.
    """
    dvn = np.einsum("pd,pd->p", dv, normals)
    tension = dvn > 0.0
    if mode == "separate":
        return dv * tension[:, None], dB * tension[:, None, None]
    if mode != "friction":
        raise ValueError(f"undesirable: mode must be one of {MODES}, got {mode!r}")
    dvt = dv - dvn[:, None] * normals  # (I - n n^T) dv  (A3)
    norm_t = np.sqrt(np.einsum("pd,pd->p", dvt, dvt))
    s = np.minimum(norm_t, np.maximum(-mu * dvn, 0.0))
    scale = np.zeros_like(norm_t)
    np.divide(s, norm_t, out=scale, where=norm_t > 0.0)
    dvu = dvt * (1.0 - scale)[:, None]
    dvu[tension] = dv[tension]
    return dvu, dB.copy()


def augury_correction(
    op: ContactOperator,
    v_bar: np.ndarray,
    B_bar: np.ndarray,
    normals: np.ndarray,
    iterations: int,
    mode: str,
    mu: float,
    movable: np.ndarray | None = None,
    energy_guard: bool = False,
    stats: dict | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """V^_N from the prediction V-bar (AUG eqs. 29, 36-46): ``(v^ (P, d), B^ (P, d, d))``.

    ``movable (P,)`` bool: particles that take a correction (kinematic foreground has False:
    its undesirable part is zero, its V^ is discarded by the caller). ``energy_guard``: stop
    before an iterate with more generalised kinetic energy than V-bar (module docstring).
    ``stats``: when given, receives ``"iterations"`` (the iterations taken).
    """
    v_hat, B_hat = op.apply(v_bar, B_bar)
    if not op.apic:
        B_bar = np.zeros_like(B_hat)
    e_bar = op.kinetic_energy(v_bar, B_bar) if energy_guard else 0.0
    taken = 0
    for _ in range(iterations):
        w_v, w_B = undesirable(v_hat - v_bar, B_hat - B_bar, normals, mode, mu)
        if not op.apic:
            w_B[:] = 0.0
        if movable is not None:
            w_v[~movable] = 0.0
            w_B[~movable] = 0.0
        hw_v, hw_B = op.apply(w_v, w_B)
        v_next = v_hat + hw_v - w_v
        B_next = B_hat + hw_B - w_B
        if energy_guard and op.kinetic_energy(v_next, B_next) > e_bar:
            break
        v_hat, B_hat = v_next, B_next
        taken += 1
    if stats is not None:
        stats["iterations"] = taken
    return v_hat, B_hat
