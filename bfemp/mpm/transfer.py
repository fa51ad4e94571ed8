"""MPM particle-grid transfers: P2G and G2P for APIC, PIC and FLIP (BFEMP paper, Tables 1-3).

A time step of the barrier strategy is P2G at the start positions, one implicit solve for the end
positions x~_i^{n+1} and velocities v~_i^{n+1} of the active grid nodes, then G2P. Both transfers
use the particle stencils of the step start: ``nodes (P, K)`` into the active grid nodes,
``weights (P, K)`` = w_ip^n (a partition of unity that reproduces linear functions, as the
quadratic B-spline does) and ``grads (P, K, d)`` = grad w_ip^n in 1/m.

The explicit strategies take variants of the same transfers, in this family (numba, each
kernel's module says why it exists, with its measurement): ``p2g_with_forces``/``g2p_explicit``
(``_explicit_kernels``: P2G fused with the internal forces, allocation-free G2P, general
stencils), ``dense_p2g``/``dense_g2p`` (``_dense2d_kernels``: 2D, weights recomputed on a dense
node box) and the multimaterial transfers of ``lr``, one field per body (``p2g_materials``,
``p2g_nodal``, ``p2g_field``, ``g2p_field``, ``g2p_update``: ``_multimaterial_kernels``).

Choices made here (choices the paper leaves open):

- The APIC state is C_p = B_p D_p^-1 (``mpm_C``), not B_p. D_p = sum_i w_ip (x_i - x_p)(x_i - x_p)^T
  is computed from the given weights (it equals dx^2/4 I for quadratic B-splines, so the D_p^n used
  to form C_p at the end of a step is also the D_p^{n+1} of the next P2G).
- APIC G2P uses the symmetrised B_p of Table 1, which conserves angular momentum for any grid
  motion: the particles' sum_p m_p (x_p x v_p + eps : B_p^T) equals the grid's
  sum_i m_i x~_i x v~_i (the antisymmetric part of B_p is sum_i w_ip (x~_i - x_p^{n+1}) x v~_i).
- FLIP is pure FLIP (Table 3, no PIC blending); the P2G of PIC and FLIP is the same.
- Accelerations (Newmark) cross in the same pass as the velocity. Given with their APIC affine
  matrices (``mpm_Ca``) and, in G2P, with the particles' own ``mpm_a``, they are transferred
  exactly like the velocity (APIC affine, FLIP increments, PIC interpolation): what the barrier
  step does (``bfemp.mpm.step``). Without them they are transferred as PIC transfers the
  velocity: P2G a_i = sum_p w_ip m_p a_p / m_i, G2P a_p = sum_i w_ip a_i, for every scheme.
- A grid node whose mass is below ``MASS_FLOOR_REL`` x the largest node mass (only possible when
  all its weights vanish: round-off weights of particles a hair off a cell-centre line) keeps
  its mass but gets zero velocity and acceleration; ``GridFields.zero_mass_nodes`` counts them
  (logged at DEBUG: a step's report names them, and a run warns once, ``P2G_ZERO_MASS``).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from bfemp.mpm._dense2d_kernels import DenseBox, dense_g2p, dense_p2g
from bfemp.mpm._explicit_kernels import g2p_explicit, p2g_with_forces
from bfemp.mpm._multimaterial_kernels import (
    g2p_field,
    g2p_update,
    p2g_field,
    p2g_materials,
    p2g_nodal,
)
from bfemp.mpm._transfer_kernels import _apic_inertia, _g2p, _p2g

__all__ = [
    "DenseBox",
    "dense_g2p",
    "dense_p2g",
    "g2p_explicit",
    "g2p_field",
    "g2p_update",
    "p2g_field",
    "p2g_materials",
    "p2g_nodal",
    "p2g_with_forces",
    "SCHEMES",
    "MASS_FLOOR_REL",
    "GridFields",
    "ParticleUpdate",
    "particles_to_grid",
    "grid_to_particles",
    "apic_inertia",
]

logger = logging.getLogger(__name__)

#: Transfer schemes: affine (APIC), particle-in-cell (PIC), fluid-implicit particle (FLIP).
SCHEMES = ("apic", "pic", "flip")

#: Grid nodes lighter than this fraction of the heaviest node get zero velocity.
MASS_FLOOR_REL = 1e-14


@dataclass(frozen=True, kw_only=True)
class GridFields:
    """Grid fields after P2G.

    Attributes:
        mass: node masses m_i ``(G,)`` in kg (kg/m in 2D plane strain).
        velocity: node velocities v_i ``(G, d)`` in m/s.
        acceleration: node accelerations a_i ``(G, d)`` in m/s^2, or None when none was transferred.
        zero_mass_nodes: nodes below ``MASS_FLOOR_REL`` x the largest mass (zero velocity).
    """

    mass: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray | None = None
    zero_mass_nodes: int = 0

    def __post_init__(self) -> None:
        n = self.mass.shape[0]
        if self.mass.ndim != 1:
            raise ValueError(f"GridFields.mass must have shape (G,), got {self.mass.shape}")
        if self.velocity.ndim != 2 or self.velocity.shape[0] != n:
            raise ValueError(
                f"GridFields.velocity must have shape ({n}, d), got {self.velocity.shape}"
            )
        if self.acceleration is not None and self.acceleration.shape != self.velocity.shape:
            raise ValueError(
                f"GridFields.acceleration must have shape {self.velocity.shape}, "
                f"got {self.acceleration.shape}"
            )


class ParticleUpdate(NamedTuple):
    """Particle state at the end of a step after G2P (unpacks as a tuple in this order).

    Attributes:
        mpm_x: positions x_p^{n+1} ``(P, d)`` in m.
        mpm_v: velocities v_p^{n+1} ``(P, d)`` in m/s.
        mpm_F: deformation gradients F_p^{n+1} ``(P, d, d)`` (dimensionless).
        mpm_C: APIC affine velocities C_p^{n+1} ``(P, d, d)`` in 1/s; zeros for PIC and FLIP.
        mpm_a: accelerations a_p^{n+1} ``(P, d)`` in m/s^2, or None when no grid one was given.
        mpm_Ca: APIC affine accelerations ``(P, d, d)`` in 1/s^2 when the acceleration was
            transferred like the velocity under APIC, else None.
    """

    mpm_x: np.ndarray
    mpm_v: np.ndarray
    mpm_F: np.ndarray
    mpm_C: np.ndarray
    mpm_a: np.ndarray | None
    mpm_Ca: np.ndarray | None = None


# --------------------------------------------------------------------------- validation
def _check_scheme(scheme: str) -> str:
    if scheme not in SCHEMES:
        raise ValueError(f"scheme must be one of {SCHEMES}, got {scheme!r}")
    return scheme


def _stencil(
    nodes: np.ndarray, weights: np.ndarray, grid_x: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Validated contiguous (nodes int64 (P, K), weights (P, K), grid_x (G, d))."""
    nodes = np.asarray(nodes)
    if nodes.ndim != 2 or not np.issubdtype(nodes.dtype, np.integer):
        raise ValueError(
            f"nodes must be an integer array of shape (P, K), got {nodes.dtype} {nodes.shape}"
        )
    grid_x = np.ascontiguousarray(grid_x, dtype=np.float64)
    if grid_x.ndim != 2 or grid_x.shape[1] < 1:
        raise ValueError(f"grid_x must have shape (G, d), got {grid_x.shape}")
    n_grid = grid_x.shape[0]
    if nodes.size and (nodes.min() < 0 or nodes.max() >= n_grid):
        bad = np.flatnonzero(((nodes < 0) | (nodes >= n_grid)).any(axis=1))
        raise ValueError(
            f"nodes must index the {n_grid} grid nodes; out of range at particles {bad[:10]}"
        )
    weights = _float(weights, "weights", nodes.shape)
    return np.ascontiguousarray(nodes, dtype=np.int64), weights, grid_x


def _float(a: np.ndarray, name: str, shape: tuple[int, ...]) -> np.ndarray:
    """``a`` as C-contiguous float64 of exactly ``shape``; ValueError naming ``name`` if not."""
    arr = np.ascontiguousarray(a, dtype=np.float64)
    if arr.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
    return arr


# --------------------------------------------------------------------------- transfers
def particles_to_grid(
    scheme: str,
    nodes: np.ndarray,
    weights: np.ndarray,
    grid_x: np.ndarray,
    mpm_x: np.ndarray,
    mpm_mass: np.ndarray,
    mpm_v: np.ndarray,
    mpm_C: np.ndarray | None = None,
    mpm_a: np.ndarray | None = None,
    *,
    mpm_Ca: np.ndarray | None = None,
) -> GridFields:
    """P2G (Tables 1-3): grid masses, velocities and optionally accelerations.

    m_i = sum_p w_ip m_p and m_i v_i = sum_p w_ip m_p (v_p + C_p (x_i - x_p)) for APIC, without the
    C_p term for PIC and FLIP. Accelerations, in the same pass: m_i a_i = sum_p w_ip m_p (a_p +
    Ca_p (x_i - x_p)) with ``mpm_Ca`` under APIC, m_i a_i = sum_p w_ip m_p a_p without it.

    Args:
        scheme: ``"apic"``, ``"pic"`` or ``"flip"``.
        nodes: stencil node indices ``(P, K)`` into the active grid nodes.
        weights: B-spline weights w_ip^n ``(P, K)`` at the particle positions.
        grid_x: active grid node positions x_i^n ``(G, d)`` in m.
        mpm_x: particle positions x_p^n ``(P, d)`` in m.
        mpm_mass: particle masses m_p ``(P,)`` in kg (kg/m in 2D), positive.
        mpm_v: particle velocities v_p^n ``(P, d)`` in m/s.
        mpm_C: APIC affine velocities C_p^n ``(P, d, d)`` in 1/s; required for APIC, ignored
            otherwise.
        mpm_a: particle accelerations a_p^n ``(P, d)`` in m/s^2 (Newmark), or None.
        mpm_Ca: APIC affine accelerations ``(P, d, d)`` in 1/s^2 (with ``mpm_a`` under APIC:
            the acceleration then crosses affinely, like the velocity), or None.

    Returns:
        ``GridFields`` with mass ``(G,)``, velocity ``(G, d)`` and acceleration ``(G, d)`` or None.
    """
    _check_scheme(scheme)
    nodes, weights, grid_x = _stencil(nodes, weights, grid_x)
    n_p, d = nodes.shape[0], grid_x.shape[1]
    mpm_x = _float(mpm_x, "mpm_x", (n_p, d))
    mpm_mass = _float(mpm_mass, "mpm_mass", (n_p,))
    if not np.all(mpm_mass > 0.0):
        raise ValueError(
            f"mpm_mass must be positive; not at particles {np.flatnonzero(~(mpm_mass > 0))[:10]}"
        )
    mpm_v = _float(mpm_v, "mpm_v", (n_p, d))
    affine = scheme == "apic"
    if affine:
        if mpm_C is None:
            raise ValueError("mpm_C (P, d, d) is required for scheme 'apic'")
        mpm_C = _float(mpm_C, "mpm_C", (n_p, d, d))
    else:
        mpm_C = np.zeros((0, d, d))
    with_a = mpm_a is not None
    mpm_a = _float(mpm_a, "mpm_a", (n_p, d)) if with_a else np.zeros((0, d))
    affine_a = affine and with_a and mpm_Ca is not None
    mpm_Ca = _float(mpm_Ca, "mpm_Ca", (n_p, d, d)) if affine_a else np.zeros((0, d, d))

    n_grid = grid_x.shape[0]
    grid_mass = np.zeros(n_grid)
    grid_mom = np.zeros((n_grid, d))
    grid_ma = np.zeros((n_grid, d) if with_a else (0, d))
    particles = (mpm_x, mpm_mass, mpm_v, mpm_C, affine, mpm_a, with_a, mpm_Ca, affine_a)
    _p2g(nodes, weights, grid_x, *particles, grid_mass, grid_mom, grid_ma)

    # v_i = (m_i v_i) / m_i on nodes with mass; zero (and warn) where the weights vanished.
    floor = MASS_FLOOR_REL * (grid_mass.max() if n_grid else 0.0)
    heavy = grid_mass > floor
    inv_mass = np.zeros(n_grid)
    inv_mass[heavy] = 1.0 / grid_mass[heavy]
    light = int(n_grid - np.count_nonzero(heavy))
    if light:  # every step of such a scene: the caller's step report names them (once a run)
        logger.debug(
            "P2G: %d grid nodes with (near) zero mass get zero velocity: %s",
            light,
            np.flatnonzero(~heavy)[:10],
        )
    velocity = grid_mom * inv_mass[:, None]
    acceleration = grid_ma * inv_mass[:, None] if with_a else None
    return GridFields(
        mass=grid_mass, velocity=velocity, acceleration=acceleration, zero_mass_nodes=light
    )


def grid_to_particles(
    scheme: str,
    nodes: np.ndarray,
    weights: np.ndarray,
    grads: np.ndarray,
    grid_x: np.ndarray,
    grid_x_new: np.ndarray,
    grid_v_old: np.ndarray | None,
    grid_v_new: np.ndarray,
    grid_a_new: np.ndarray | None,
    mpm_x: np.ndarray,
    mpm_v: np.ndarray,
    mpm_F: np.ndarray,
    *,
    grid_a_old: np.ndarray | None = None,
    mpm_a: np.ndarray | None = None,
) -> ParticleUpdate:
    """G2P (Tables 1-3): end-of-step particle positions, velocities, F, APIC C and accelerations.

    For every scheme x_p^{n+1} = sum_i w_ip x~_i and F_p^{n+1} = (sum_i x~_i grad w_ip^T) F_p^n.
    PIC and APIC: v_p = sum_i w_ip v~_i; FLIP: v_p = v_p^n + sum_i w_ip (v~_i - v_i^n). APIC:
    C_p = B_p D_p^-1 with B_p = 1/2 sum_i w_ip [v~_i (x_i^n - x_p^n + x~_i - x_p^{n+1})^T
    + (x_i^n - x_p^n - x~_i + x_p^{n+1}) v~_i^T]. Accelerations (when given), in the same pass:
    with the particles' ``mpm_a`` exactly like the velocity (FLIP: a_p^n + sum_i w_ip (a_i^{n+1}
    - a_i^n), needing ``grid_a_old``; APIC: also Ca_p from B^a_p with a in place of v), without
    it a_p = sum_i w_ip a_i.

    Args:
        scheme: ``"apic"``, ``"pic"`` or ``"flip"``.
        nodes: stencil node indices ``(P, K)`` (of the step start) into the active grid nodes.
        weights: weights w_ip^n ``(P, K)`` at the start positions x_p^n.
        grads: weight gradients grad w_ip^n ``(P, K, d)`` in 1/m.
        grid_x: start positions x_i^n of the active grid nodes ``(G, d)`` in m.
        grid_x_new: solved end positions x~_i^{n+1} ``(G, d)`` in m.
        grid_v_old: P2G velocities v_i^n ``(G, d)`` in m/s; required for FLIP, ignored otherwise.
        grid_v_new: solved end velocities v~_i^{n+1} ``(G, d)`` in m/s.
        grid_a_new: end accelerations a_i^{n+1} ``(G, d)`` in m/s^2 (Newmark), or None.
        mpm_x: start positions x_p^n ``(P, d)`` in m.
        mpm_v: start velocities v_p^n ``(P, d)`` in m/s (used by FLIP).
        mpm_F: start deformation gradients F_p^n ``(P, d, d)``.
        grid_a_old: P2G accelerations a_i^n ``(G, d)`` in m/s^2 (FLIP with ``mpm_a``).
        mpm_a: start accelerations a_p^n ``(P, d)`` in m/s^2: given, the acceleration is
            transferred like the velocity.

    Returns:
        ``ParticleUpdate(mpm_x (P, d), mpm_v (P, d), mpm_F (P, d, d), mpm_C (P, d, d),
        mpm_a (P, d) or None, mpm_Ca (P, d, d) or None)``; ``mpm_C`` is zero for PIC and FLIP,
        ``mpm_Ca`` is set only for APIC with ``mpm_a``.
    """
    _check_scheme(scheme)
    nodes, weights, grid_x = _stencil(nodes, weights, grid_x)
    (n_p, k), (n_grid, d) = nodes.shape, grid_x.shape
    grads = _float(grads, "grads", (n_p, k, d))
    grid_x_new = _float(grid_x_new, "grid_x_new", (n_grid, d))
    grid_v_new = _float(grid_v_new, "grid_v_new", (n_grid, d))
    flip = scheme == "flip"
    if flip:
        if grid_v_old is None:
            raise ValueError("grid_v_old (G, d) is required for scheme 'flip'")
        grid_v_old = _float(grid_v_old, "grid_v_old", (n_grid, d))
    else:
        grid_v_old = np.zeros((0, d))
    with_a = grid_a_new is not None
    grid_a_new = _float(grid_a_new, "grid_a_new", (n_grid, d)) if with_a else np.zeros((0, d))
    a_like_v = with_a and mpm_a is not None
    mpm_a = _float(mpm_a, "mpm_a", (n_p, d)) if a_like_v else np.zeros((0, d))
    if a_like_v and flip:
        if grid_a_old is None:
            raise ValueError("grid_a_old (G, d) is required for scheme 'flip' with mpm_a")
        grid_a_old = _float(grid_a_old, "grid_a_old", (n_grid, d))
    else:
        grid_a_old = np.zeros((0, d))
    mpm_x = _float(mpm_x, "mpm_x", (n_p, d))
    mpm_v = _float(mpm_v, "mpm_v", (n_p, d))
    mpm_F = _float(mpm_F, "mpm_F", (n_p, d, d))

    out_x = np.empty((n_p, d))
    out_v = np.empty((n_p, d))
    out_F = np.empty((n_p, d, d))
    out_C = np.zeros((n_p, d, d))
    out_a = np.empty((n_p, d) if with_a else (0, d))
    affine_a = a_like_v and scheme == "apic"
    out_Ca = np.zeros((n_p, d, d) if affine_a else (0, d, d))
    singular = np.zeros(n_p, dtype=np.bool_)
    grid = (grid_x, grid_x_new, grid_v_old, grid_v_new, grid_a_new)
    flags = (flip, scheme == "apic", with_a, grid_a_old, mpm_a, a_like_v)
    out = (out_x, out_v, out_F, out_C, out_a, out_Ca, singular)
    _g2p(nodes, weights, grads, *grid, mpm_x, mpm_v, mpm_F, *flags, *out)
    if singular.any():
        raise ValueError(
            "APIC inertia D_p = sum_i w_ip (x_i - x_p)(x_i - x_p)^T is singular at particles "
            f"{np.flatnonzero(singular)[:10]} (degenerate stencil weights or grid_x)"
        )
    return ParticleUpdate(
        out_x, out_v, out_F, out_C, out_a if with_a else None, out_Ca if affine_a else None
    )


def apic_inertia(
    nodes: np.ndarray, weights: np.ndarray, grid_x: np.ndarray, mpm_x: np.ndarray
) -> np.ndarray:
    """APIC inertia D_p = sum_i w_ip (x_i - x_p)(x_i - x_p)^T ``(P, d, d)`` in m^2 (Table 1).

    With it B_p = C_p D_p, and a particle's angular momentum is m_p (x_p x v_p + eps : B_p^T).

    Args:
        nodes: stencil node indices ``(P, K)``.
        weights: weights w_ip ``(P, K)`` at ``mpm_x``.
        grid_x: grid node positions ``(G, d)`` in m.
        mpm_x: particle positions ``(P, d)`` in m.
    """
    nodes, weights, grid_x = _stencil(nodes, weights, grid_x)
    mpm_x = _float(mpm_x, "mpm_x", (nodes.shape[0], grid_x.shape[1]))
    return _apic_inertia(nodes, weights, grid_x, mpm_x)
