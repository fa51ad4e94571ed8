"""Lagged friction (BFEMP paper section 4.3, eqs. 34-37): the pseudo-potential D(x).

For every active contact, lagged at the iterate x^j of the outer friction loop (Algorithm 1):
the normal force magnitude lambda_k = -omega_q b'(d_k), an orthonormal tangent basis T_k and the
closest-point weights c_k (so that the relative sliding of the pair is sum_a c_ka U_a). Then

    D(x) = sum_k mu lambda_k f0(|u_k|) / s,   u_k = T_k^T sum_a c_ka U_a(x),

with f0' = f1 the mollifier of eq. 36 (width eps_v dt). U_a is the point's sliding over the
step, Delta t v^{n+1} = Delta t v^n + Delta t^2 ((1 - gamma) a^n + gamma a^{n+1}) (eq. 37), affine
in the unknowns: U = s x + c with s = gamma / (2 alpha beta) (backward Euler: U = x - x^n). The
1 / s makes -dD/dx the friction force of eq. 37, mu lambda_k T_k f1(|u_k|) u_k / |u_k|, whatever
the integrator: without it the chain rule through U scales the force by s (2 under mid-point
Newmark, which then doubled mu: a box on a slope with mu = 0.1 and tan theta = 0.2 stuck). For MPM
it is the interpolated grid motion at the particle, not the particle velocity (section 4.3), which
makes friction independent of the transfer scheme.

Contacts for friction are the barrier's facet pairs classified by their closest feature
(vertex, edge or facet interior) and de-duplicated, so a point nearest to a vertex has one contact.
"""

from __future__ import annotations

import numpy as np

from bfemp.contact._assembly_kernels import _chain_hessian, _scatter_gradient
from bfemp.contact.barrier import barrier_derivative
from bfemp.contact.friction_kernels import friction_local, friction_local_psd
from bfemp.contact.term import BarrierTerm
from bfemp.terms.base import StepContext
from geometry import distance as dist
from geometry import frames
from solvers.assembly import Triplets

__all__ = ["FrictionTerm"]


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


class FrictionTerm:
    """Lagged friction of the barrier's contacts.

    Args:
        mu: friction coefficient.
        eps_v: static threshold velocity in m/s.
        barrier: the barrier term whose contacts rub.
    """

    name = "friction"
    contact = True  # weighted by the integrator's contact_weight

    def __init__(self, mu: float, eps_v: float, barrier: BarrierTerm) -> None:
        self.mu = float(mu)
        self.eps_v = float(eps_v)
        self.barrier = barrier
        self.n_contacts = 0

    def begin_step(self, ctx: StepContext) -> None:
        """Sliding map U = s x + c of this step; contacts are lagged later with ``lag``."""
        self._layout = ctx.layout
        self._fixed = ctx.fixed_positions
        self._eps = self.eps_v * ctx.dt
        self._s, self._c = ctx.sliding
        self._clear()

    def _clear(self) -> None:
        d = self._layout.dim
        self._points = np.zeros((0, 2), dtype=np.int64)
        self._coef = np.zeros((0, 2))
        self._T = np.zeros((0, d, d - 1))
        self._mu_lambda = np.zeros(0)
        self.n_contacts = 0

    # ------------------------------------------------------------------ lagging
    def lag(self, x: np.ndarray) -> None:
        """Contacts, normal forces and tangent bases at positions x (Algorithm 1, lines 5/9).

        Every barrier term (facet pairs and the signed duplicate-removal terms of eqs. 31-32) is
        mapped to its closest feature (vertex, edge or face) and the signed coefficients are
        summed per (point, feature): a point over a shared vertex gets one vertex contact
        (2 - 1), a point over an edge interior next to a vertex gets none from that vertex
        (1 - 1), so friction sees exactly the contacts the barrier has.
        """
        bar = self.barrier
        bar.solution_changed(x)
        pos = bar._pos
        pairs = bar.pairs
        rows, coefs = [], []
        for kind, pts in pairs.points.items():
            if kind == "ee" or pts.shape[0] == 0:
                continue
            rows.append(_feature_keys(kind, pts, pos))
            coefs.append(pairs.coef[kind])
        if not rows:
            self._clear()
            return
        keys = np.concatenate(rows)
        unique, inverse = np.unique(keys, axis=0, return_inverse=True)
        mult = np.zeros(unique.shape[0])
        np.add.at(mult, inverse.ravel(), np.concatenate(coefs))
        keep = mult > 0.5  # multiplicities are integers: 0 where the barrier cancels
        self._build(pos, bar.collisions, unique[keep], np.rint(mult[keep]))

    def _build(self, pos, cs, keys, mult) -> None:  # noqa: ANN001
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
            groups.append((points, coef, T, d, mult[sel]))
        self._groups = []
        n = 0
        for points, coef, T, dvals, k in groups:
            lam = (
                -k
                * cs.omega[points[:, 0]]
                * barrier_derivative(dvals, self.barrier.dhat, self.barrier.kappa)
            )
            keep = lam > 0.0
            self._groups.append(
                (
                    np.ascontiguousarray(points[keep]),
                    np.ascontiguousarray(coef[keep]),
                    np.ascontiguousarray(T[keep]),
                    self.mu * lam[keep],
                )
            )
            n += int(keep.sum())
        self.n_contacts = n

    # ------------------------------------------------------------------ energy
    def solution_changed(self, x: np.ndarray) -> None:
        """Sliding of every collision point at x: U = s x + c, gathered through the stencils."""
        if not self.n_contacts:
            return
        y = self._layout.positions(x, self._fixed)
        self._U = self.barrier.collisions.positions(self._s * y + self._c)

    def _u(self, points: np.ndarray, coef: np.ndarray, T: np.ndarray) -> np.ndarray:
        rel = np.einsum("nm,nmi->ni", coef, self._U[points])
        return np.einsum("nik,ni->nk", T, rel)

    def value(self, x: np.ndarray) -> float:
        """D(x) in J (eq. 37, divided by s: see the module docstring)."""
        total = 0.0
        for points, coef, T, ml in getattr(self, "_groups", []) if self.n_contacts else []:
            u = self._u(points, coef, T)
            total += float(friction_local(u, ml, self._eps)[0].sum())
        return total / self._s

    def gradient(self, x: np.ndarray) -> np.ndarray:
        """dD/dx ``(n_dof,)`` in N (minus the lagged friction force)."""
        out = np.zeros((self._layout.n_all, self._layout.dim))
        if self.n_contacts:
            cs = self.barrier.collisions
            for points, coef, T, ml in self._groups:
                if not points.size:
                    continue
                _, g_u, _ = friction_local(self._u(points, coef, T), ml, self._eps)
                g_rel = np.einsum("nik,nk->ni", T, g_u)  # (n, d)
                # d/dx of f0(|u|) / s: the chain rule's s cancels the 1 / s
                local = (coef[:, :, None] * g_rel[:, None, :]).reshape(len(coef), -1)
                _scatter_gradient(out, local, points, cs.nodes, cs.weights)
        return self._layout.restrict(out)

    def hessian(self, x: np.ndarray, psd: bool) -> Triplets:
        """s (c c^T) (x) (T H_u T^T) per contact (s^2 from the chain rule, 1 / s from D),
        chained to node DOFs."""
        parts = []
        if self.n_contacts:
            cs = self.barrier.collisions
            dof_node = self._layout.dof_node
            d = self._layout.dim
            local_fn = friction_local_psd if psd else friction_local
            for points, coef, T, ml in self._groups:
                if not points.size:
                    continue
                _, _, h_u = local_fn(self._u(points, coef, T), ml, self._eps)
                h_rel = np.einsum("nik,nkl,njl->nij", T, h_u, T)  # (n, d, d)
                m = coef.shape[1]
                local = (
                    self._s
                    * (coef[:, :, None, None, None] * coef[:, None, None, :, None])
                    * h_rel[:, None, :, None, :]
                )
                local = np.ascontiguousarray(local.reshape(len(coef), m * d, m * d))
                rows, cols, vals = _chain_hessian(local, points, cs.nodes, cs.weights, dof_node)
                parts.append(Triplets(rows, cols, vals))
        return Triplets.concatenate(parts) if parts else Triplets.empty()

    def max_step_size(self, x: np.ndarray, p: np.ndarray) -> float:
        """No feasibility constraint."""
        return 1.0
