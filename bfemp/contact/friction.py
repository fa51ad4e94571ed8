"""Lagged friction (BFEMP paper section 4.3, BFEMP eqs. 34-37): the pseudo-potential D(x).

For every active contact, lagged at the iterate x^j of the outer friction loop (Algorithm 1):
the normal force magnitude lambda_k = -omega_q b'(d_k), an orthonormal tangent basis T_k and the
closest-point weights c_k (so that the relative sliding of the pair is sum_a c_ka U_a). Then

    D(x) = sum_k mu lambda_k f0(|u_k|) / s,   u_k = T_k^T sum_a c_ka U_a(x),

with f0' = f1 the mollifier of BFEMP eq. 36 (width eps_v dt). U_a is the point's sliding over the
step, Delta t v^{n+1} = Delta t v^n + Delta t^2 ((1 - gamma) a^n + gamma a^{n+1}) (BFEMP eq. 37),
affine in the unknowns: U = s x + c with s = gamma / (2 alpha beta) (backward Euler: U = x - x^n).
The 1 / s makes -dD/dx the friction force of BFEMP eq. 37, mu lambda_k T_k f1(|u_k|) u_k / |u_k|,
whatever the integrator: without it the chain rule through U scales the force by s (2 under
mid-point Newmark, which then doubled mu: a box on a slope with mu = 0.1 and tan theta = 0.2 stuck).
For MPM it is the interpolated grid motion at the particle, not the particle velocity (section 4.3),
which makes friction independent of the transfer scheme.

Contacts for friction are the barrier's facet pairs classified by their closest feature
(vertex, edge or facet interior) and de-duplicated, so a point nearest to a vertex has one contact.

Contact data and evaluation are apart: ``lag_contacts`` builds the lagged contacts from
(collision set, point positions, active pairs, barrier parameters, mu), and ``friction_energy``,
``friction_pair_gradients`` and ``friction_pair_hessians`` evaluate f0 on (contacts, sliding U,
eps) without any state; ``FrictionTerm`` (the implicit energy term) holds the step's sliding map
and chains them to nodes. Any strategy with lagged friction (``two_stage``) calls the same code.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bfemp.contact._assembly_kernels import _chain_hessian, _scatter_gradient
from bfemp.contact.barrier import barrier_derivative
from bfemp.contact.collision import CollisionSet
from bfemp.contact.friction_kernels import friction_local
from bfemp.contact.pair_friction import PairFriction
from bfemp.contact.pairs import ContactPairs, find_pairs
from bfemp.contact.term import BarrierTerm
from bfemp.terms.base import StepContext
from geometry import distance as dist
from geometry import frames
from solvers.assembly import Triplets

__all__ = [
    "FrictionContacts",
    "FrictionTerm",
    "friction_energy",
    "friction_pair_gradients",
    "friction_pair_hessians",
    "lag_contacts",
]


def _feature_keys(kind: str, pts: np.ndarray, pos: np.ndarray) -> np.ndarray:
    """Closest feature of barrier terms as keys ``(n, 5)``: (kind, point, v0, v1, v2).

    kind 0: vertex (v0), 1: edge (v0 < v1), 2: face (v0 v1 v2 as stored); unused slots -1.
    """
    n = pts.shape[0]
    keys = np.full((n, 5), -1, dtype=np.int64)
    keys[:, 1] = pts[:, 0]
    rows = np.arange(n)
    if kind == "pp":
        keys[:, 0] = 0
        keys[:, 2] = pts[:, 1]
        return keys
    args = [pos[pts[:, a]] for a in range(pts.shape[1])]
    if kind == "pe":
        typ = dist.point_edge_type(*args)
        vertex = typ <= 1
        keys[:, 0] = np.where(vertex, 0, 1)
        keys[vertex, 2] = pts[rows[vertex], 1 + typ[vertex]]
        edge = np.sort(pts[~vertex][:, 1:3], axis=1)
        keys[~vertex, 2:4] = edge
        return keys
    typ = dist.point_triangle_type(*args)  # 0-2 vertices, 3-5 edges, 6 face
    vertex, edge, face = typ <= 2, (typ >= 3) & (typ <= 5), typ == 6
    keys[vertex, 0] = 0
    keys[vertex, 2] = pts[rows[vertex], 1 + typ[vertex]]
    local = np.array([[1, 2], [2, 3], [3, 1]])[typ[edge] - 3]
    keys[edge, 0] = 1
    keys[edge, 2:4] = np.sort(pts[rows[edge][:, None], local], axis=1)
    keys[face, 0] = 2
    keys[face, 2:5] = pts[face][:, 1:4]
    return keys


@dataclass(frozen=True)
class FrictionGroup:
    """Lagged contacts of one closest-feature kind (vertex, edge or face; m = 2, 3, 4 points).

    Attributes:
        points: collision points of each contact ``(n, m)`` (the point first).
        coef: closest-point weights ``(n, m)``: the relative sliding is sum_a coef_a U_a.
        T: orthonormal tangent bases ``(n, d, d - 1)``.
        mu_lambda: mu times the lagged normal force ``(n,)`` in N (N/m in 2D).
    """

    points: np.ndarray
    coef: np.ndarray
    T: np.ndarray
    mu_lambda: np.ndarray


@dataclass(frozen=True)
class FrictionContacts:
    """The lagged friction contacts of one outer-loop iterate (BFEMP eqs. 34-35)."""

    groups: tuple[FrictionGroup, ...] = ()

    @property
    def n_contacts(self) -> int:
        """Number of contacts with a positive normal force."""
        return int(sum(g.points.shape[0] for g in self.groups))


def lag_contacts(
    collisions: CollisionSet,
    positions: np.ndarray,
    pairs: ContactPairs,
    dhat: float,
    kappa: float,
    mu: float | PairFriction,
) -> FrictionContacts:
    """Contacts, normal forces and tangent bases at ``positions`` (Algorithm 1, lines 5/9).

    Every barrier term (facet pairs and the signed duplicate-removal terms of BFEMP eqs. 31-32) is
    mapped to its closest feature (vertex, edge or face) and the signed coefficients are summed
    per (point, feature): a point over a shared vertex gets one vertex contact (2 - 1), a point
    over an edge interior next to a vertex gets none from that vertex (1 - 1), so friction sees
    exactly the contacts the barrier has.

    Args:
        collisions: the collision set.
        positions: collision-point positions ``(C, d)`` in m.
        pairs: the barrier's active pairs at ``positions``.
        dhat: barrier activation distance in m; ``kappa``: its stiffness in Pa.
        mu: friction coefficient, one for every pair or per pair of bodies (the bodies of a
            contact's point and of its closest feature).
    """
    rows, coefs = [], []
    for kind, pts in pairs.points.items():
        if kind == "ee" or pts.shape[0] == 0:
            continue
        rows.append(_feature_keys(kind, pts, positions))
        coefs.append(pairs.coef[kind])
    if not rows:
        return FrictionContacts()
    keys = np.concatenate(rows)
    unique, inverse = np.unique(keys, axis=0, return_inverse=True)
    mult = np.zeros(unique.shape[0])
    np.add.at(mult, inverse.ravel(), np.concatenate(coefs))
    keep = mult > 0.5  # multiplicities are integers: 0 where the barrier cancels
    return _contacts(positions, collisions, unique[keep], np.rint(mult[keep]), dhat, kappa, mu)


def _contacts(pos, cs, keys, mult, dhat, kappa, mu) -> FrictionContacts:  # noqa: ANN001
    """Friction groups of contacts keyed (kind, point, v0, v1, v2) with multiplicities."""
    groups = []
    kind = keys[:, 0]
    for code in (0, 1, 2):
        sel = kind == code
        if not sel.any():
            continue
        m = code + 2  # points per contact: vertex 2, edge 3, face 4
        points = np.ascontiguousarray(keys[sel][:, 1 : 1 + m])
        args = [pos[points[:, a]] for a in range(m)]
        if code == 0:
            coef = np.tile([1.0, -1.0], (points.shape[0], 1))
            T = frames.point_point_tangent_basis(*args)
            d = dist.point_point_distance(*args)
        elif code == 1:
            beta = frames.point_edge_closest_parameter(*args)
            coef = np.column_stack([np.ones(len(beta)), beta - 1.0, -beta])
            T = frames.point_edge_tangent_basis(*args)
            d = dist.point_edge_distance(*args)
        else:
            bary = frames.point_triangle_closest_barycentric(*args)
            b1, b2 = bary[:, 0], bary[:, 1]
            coef = np.column_stack([np.ones(len(b1)), b1 + b2 - 1.0, -b1, -b2])
            T = frames.point_triangle_tangent_basis(*args)
            d = dist.point_triangle_distance(*args)
        lam = -mult[sel] * cs.omega[points[:, 0]] * barrier_derivative(d, dhat, kappa)
        if isinstance(mu, PairFriction):  # the bodies of the point and of its closest feature
            mu_lam = mu.of(cs.point_body[points[:, 0]], cs.point_body[points[:, 1]]) * lam
        else:
            mu_lam = mu * lam
        keep = mu_lam > 0.0  # no normal force, or a frictionless pair
        kept = (np.ascontiguousarray(a[keep]) for a in (points, coef, T))
        groups.append(FrictionGroup(*kept, mu_lam[keep]))
    return FrictionContacts(tuple(groups))


def _sliding(group: FrictionGroup, U: np.ndarray) -> np.ndarray:
    """Tangential relative sliding u ``(n, d - 1)`` in m of each contact of ``group``."""
    rel = np.einsum("nm,nmi->ni", group.coef, U[group.points])
    return np.einsum("nik,ni->nk", group.T, rel)


def friction_energy(contacts: FrictionContacts, U: np.ndarray, eps: float) -> float:
    """sum_k mu lambda_k f0(|u_k|) in J (J/m in 2D), for point slidings ``U (C, d)`` in m and the
    mollifier width ``eps`` = eps_v dt in m (BFEMP eq. 36)."""
    total = 0.0
    for g in contacts.groups:
        if g.points.size:
            total += float(friction_local(_sliding(g, U), g.mu_lambda, eps)[0].sum())
    return total


def friction_pair_gradients(
    contacts: FrictionContacts, U: np.ndarray, eps: float
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per-contact gradients of mu lambda f0(|u|) with respect to the contact's point slidings:
    ``[(points (n, m), grad (n, m d))]`` in N, one entry per group."""
    out = []
    for g in contacts.groups:
        if not g.points.size:
            continue
        _, g_u, _ = friction_local(_sliding(g, U), g.mu_lambda, eps)
        g_rel = np.einsum("nik,nk->ni", g.T, g_u)  # (n, d)
        out.append((g.points, (g.coef[:, :, None] * g_rel[:, None, :]).reshape(len(g.coef), -1)))
    return out


def friction_pair_hessians(
    contacts: FrictionContacts, U: np.ndarray, eps: float, psd: bool, scale: float = 1.0
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per-contact Hessians scale (c c^T) (x) (T H_u T^T) with respect to the point slidings:
    ``[(points (n, m), hess (n, m d, m d))]`` in N/m; H_u projected to PSD when ``psd``."""
    out = []
    for g in contacts.groups:
        if not g.points.size:
            continue
        _, _, h_u = friction_local(_sliding(g, U), g.mu_lambda, eps, psd)
        h_rel = np.einsum("nik,nkl,njl->nij", g.T, h_u, g.T)  # (n, d, d)
        m, d = g.coef.shape[1], g.T.shape[1]
        cc = scale * (g.coef[:, :, None, None, None] * g.coef[:, None, None, :, None])
        local = cc * h_rel[:, None, :, None, :]
        out.append((g.points, np.ascontiguousarray(local.reshape(len(g.coef), m * d, m * d))))
    return out


class FrictionTerm:
    """Lagged friction of the barrier's contacts (the energy term of the implicit strategies).

    Args:
        mu: friction coefficient, one for every pair or per pair of bodies (``PairFriction``).
        eps_v: static threshold velocity in m/s.
        barrier: the barrier term whose contacts rub (its collision set and parameters; the
            friction term never changes it).
    """

    name = "friction"
    contact = True  # weighted by the integrator's contact_weight

    def __init__(self, mu: float | PairFriction, eps_v: float, barrier: BarrierTerm) -> None:
        self.mu = mu if isinstance(mu, PairFriction) else float(mu)
        self.eps_v = float(eps_v)
        self.barrier = barrier
        self.contacts = FrictionContacts()

    @property
    def n_contacts(self) -> int:
        """Number of lagged contacts."""
        return self.contacts.n_contacts

    def begin_step(self, ctx: StepContext) -> None:
        """Sliding map U = s x + c of this step; contacts are lagged later with ``lag``."""
        self._layout = ctx.layout
        self._fixed = ctx.fixed_positions
        self._eps = self.eps_v * ctx.dt
        self._s, self._c = ctx.sliding
        self.contacts = FrictionContacts()

    # ------------------------------------------------------------------ lagging
    def lag(self, x: np.ndarray) -> None:
        """Lag the contacts at unknowns ``x (n_dof,)`` (``lag_contacts``)."""
        bar = self.barrier
        pos = bar.collision_positions(x)
        pairs = find_pairs(bar.collisions, pos, bar.dhat)
        self.contacts = lag_contacts(bar.collisions, pos, pairs, bar.dhat, bar.kappa, self.mu)

    # ------------------------------------------------------------------ energy
    def solution_changed(self, x: np.ndarray) -> None:
        """Sliding of every collision point at x: U = s x + c, gathered through the stencils."""
        if not self.n_contacts:
            return
        y = self._layout.positions(x, self._fixed)
        self._U = self.barrier.collisions.positions(self._s * y + self._c)

    def value(self, x: np.ndarray) -> float:
        """D(x) in J (BFEMP eq. 37, divided by s: see the module docstring)."""
        if not self.n_contacts:
            return 0.0
        return friction_energy(self.contacts, self._U, self._eps) / self._s

    def gradient(self, x: np.ndarray) -> np.ndarray:
        """dD/dx ``(n_dof,)`` in N (minus the lagged friction force)."""
        out = np.zeros((self._layout.n_all, self._layout.dim))
        if self.n_contacts:
            cs = self.barrier.collisions
            # d/dx of f0(|u|) / s: the chain rule's s cancels the 1 / s
            for points, local in friction_pair_gradients(self.contacts, self._U, self._eps):
                _scatter_gradient(out, local, points, cs.nodes, cs.weights)
        return self._layout.restrict(out)

    def hessian(self, x: np.ndarray, psd: bool) -> Triplets:
        """s (c c^T) (x) (T H_u T^T) per contact (s^2 from the chain rule, 1 / s from D),
        chained to node DOFs."""
        parts = []
        if self.n_contacts:
            cs = self.barrier.collisions
            dof_node = self._layout.dof_node
            blocks = friction_pair_hessians(self.contacts, self._U, self._eps, psd, self._s)
            for points, local in blocks:
                rows, cols, vals = _chain_hessian(local, points, cs.nodes, cs.weights, dof_node)
                parts.append(Triplets(rows, cols, vals))
        return Triplets.concatenate(parts) if parts else Triplets.empty()

    def max_step_size(self, x: np.ndarray, p: np.ndarray) -> float:
        """No feasibility constraint."""
        return 1.0
