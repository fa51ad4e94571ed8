"""The contact pairs of an ``"lr"`` step, their planes and the contact law's corrections (LR)."""

from __future__ import annotations

import numpy as np

from bfemp.model import Model
from bfemp.steppers._lr_options import LROptions
from bfemp.steppers._lr_points import Pairs, Points

__all__ = ["PairContact"]


class PairContact:
    """The contact pairs of an ``"lr"`` step with their planes (docstring steps 2-4 of
    ``bfemp.steppers.lr``) and the corrections of the contact law on them, for ``n_materials``
    fields under ``options`` (``LROptions``) with the Coulomb coefficient ``mu`` (or the
    scene's per-pair table)."""

    def __init__(self, model: Model, options: LROptions, mu: float, n_materials: int) -> None:
        self.model, self.options, self.mu, self.n_materials = model, options, mu, n_materials
        self.mu_table = self.friction_table(model)

    def friction_table(self, model: Model) -> np.ndarray | None:
        """mu per pair of materials ``(M, M)`` from ``scene.set_friction``, or None (one mu).

        Materials are the MPM bodies, then the FEM bodies (``n_mpm + index``); pairs the scene
        does not name keep ``self.mu`` (``LROptions.mu`` or ``scene.set_contact(mu=...)``).
        """
        pairs = getattr(model.contact, "pair_mu", ())
        if not pairs:
            return None
        n_mpm = len(model.mpm_bodies)
        table = np.full((self.n_materials, self.n_materials), self.mu)
        for code_a, code_b, mu in pairs:
            a, b = (n_mpm + c if c >= 0 else -1 - c for c in (code_a, code_b))
            table[a, b] = table[b, a] = mu
        return table

    def pair_mu(self, a: np.ndarray, b: np.ndarray, mass: np.ndarray) -> float | np.ndarray:
        """mu of each contact ``(C,)`` of material ``a`` against ``b`` (-1: the lumped others,
        then the mass-weighted mean of a's coefficients with them); ``mass (M, C)`` in kg."""
        if self.mu_table is None:
            return self.mu
        lumped = b < 0
        mu = self.mu_table[a, np.maximum(b, 0)]
        if lumped.any():
            la, m = a[lumped], mass[:, lumped].copy()
            m[la, np.arange(la.size)] = 0.0
            mu[lumped] = (self.mu_table[la].T * m).sum(axis=0) / m.sum(axis=0)
        return mu

    # ------------------------------------------------------------------ contact detection
    def pairs(self, pts: Points, grid_x: np.ndarray, mass: np.ndarray) -> Pairs:
        """The contact pairs of this step with their planes (step 2 of the docstring)."""
        opts, d = self.options, self.model.dim
        total = mass.sum(axis=0)
        # a perfect interface joins every material with mass (so that it is exactly one body)
        fraction = 0.0 if opts.interface == "perfect" else opts.mass_fraction
        present = (mass > fraction * total[None, :]) & (mass > 0.0)
        count = present.sum(axis=0)
        two = np.flatnonzero(count == 2)
        many = np.flatnonzero(count >= 3)
        M = self.n_materials
        first = np.argmax(present[:, two], axis=0)
        last = M - 1 - np.argmax(present[::-1, two], axis=0)
        many_a, many_node = np.nonzero(present[:, many])
        node = np.concatenate([two, many[many_node]]).astype(np.int64)
        a = np.concatenate([first, many_a]).astype(np.int64)
        b = np.concatenate([last, np.full(many_a.size, -1)]).astype(np.int64)
        k = node.size
        planes = Pairs(
            node=node,
            a=a,
            b=b,
            normal=np.zeros((k, d)),
            separation=np.full(k, np.nan),
            iterations=np.zeros(k, dtype=np.int64),
            converged=np.ones(k, dtype=bool),
            fallback=np.zeros(k, dtype=bool),
        )
        if k == 0 or opts.interface == "perfect":
            return planes
        from bfemp.contact import lr as lr_contact  # the LR kernels (numba)

        if opts.detector == "lr":
            st = pts.stencils
            ptr, idx, side = lr_contact.contact_point_clouds(
                st.nodes, st.weights, pts.material, node, a, b, grid_x.shape[0]
            )
            fit = lr_contact.lr_planes(
                grid_x[node],
                ptr,
                idx,
                side,
                pts.x,
                pts.F,
                pts.radius0,
                self.model.grid.dx,
                penalty=opts.penalty,
                tol=opts.lr_tol,
                max_iterations=opts.lr_max_iterations,
                thin=opts.thin_cloud,
            )
            for name in ("normal", "separation", "iterations", "converged", "fallback"):
                setattr(planes, name, getattr(fit, name))
            return planes
        # the grid detectors compare two materials: a lumped pair takes the heaviest other
        partner = b.copy()
        lumped = np.flatnonzero(b < 0)
        if lumped.size:
            others = mass[:, node[lumped]].copy()
            others[a[lumped], np.arange(lumped.size)] = -1.0
            partner[lumped] = np.argmax(others, axis=0)
        st = pts.stencils
        grads = lr_contact.mass_gradient_normals(
            st.nodes, st.grads, pts.mass, pts.material, grid_x.shape[0], M
        )
        planes.normal = lr_contact.ag_normals(grads, node, a, partner)
        if opts.detector == "cp":
            moments = lr_contact.material_mass_moments(
                st.nodes, st.weights, pts.mass, pts.x, pts.material, grid_x.shape[0], M
            )
            planes.separation = lr_contact.cp_separation(
                grid_x[node],
                node,
                a,
                partner,
                mass,
                moments,
                planes.normal,
                opts.cp_offset,
                self.model.grid.dx,
            )
        return planes

    # ------------------------------------------------------------------ the contact law
    def correct(
        self, planes: Pairs, mass: np.ndarray, mom: np.ndarray, kinematic: np.ndarray | None
    ) -> tuple[np.ndarray, int, np.ndarray, np.ndarray]:
        """The contact law on momenta ``mom (M, G, d)``: the momentum changes ``(M, G, d)``
        applied, the number of pairs in contact, the net momentum change (lumping's drift)
        ``(d,)`` and the momentum ``(M, G, d)`` the scripted fields take and do not apply.

        ``kinematic (M, G)`` bool (``_kinematic_fields``; None: none) marks the scripted
        fields. A pair against one takes it as infinitely heavy (``contact_momentum``'s
        ``rigid_a``/``rigid_b``, NairnMPM's rigid-material contact); the scripted field's
        reaction -dp is returned in the last array, never applied (its velocity is the
        script). A lumped pair (LR eq. 50) whose others include a scripted field meets that field
        alone (the heaviest there, as NairnMPM picks one rigid material per node); a scripted
        a of a lumped pair is not corrected.
        """
        from bfemp.contact import lr as lr_contact  # the LR kernels (numba)

        opts = self.options
        delta = np.zeros_like(mom)
        absorbed = np.zeros_like(mom)
        node, a, b = planes.node, planes.a, planes.b
        if node.size == 0:
            return delta, 0, np.zeros(mom.shape[2]), absorbed
        m_a, p_a = mass[a, node], mom[a, node]
        lumped = b < 0
        partner = b.copy()  # the material that takes -dp; -1: the lumped others
        m_b = np.where(lumped, mass[:, node].sum(axis=0) - m_a, mass[np.maximum(b, 0), node])
        p_b = np.where(lumped[:, None], mom[:, node].sum(axis=0) - p_a, mom[np.maximum(b, 0), node])
        rigid_a = rigid_b = None
        if kinematic is not None:
            rigid_a = kinematic[a, node]
            rigid_b = kinematic[np.maximum(b, 0), node] & ~lumped
            rows = np.flatnonzero(lumped & ~rigid_a)
            if rows.size:  # lumped others holding a scripted field: that field alone
                kin_mass = np.where(kinematic[:, node[rows]], mass[:, node[rows]], 0.0)
                kin_mass[a[rows], np.arange(rows.size)] = 0.0
                heavy = np.argmax(kin_mass, axis=0)
                hit = kin_mass[heavy, np.arange(rows.size)] > 0.0
                rows, heavy = rows[hit], heavy[hit]
                m_b[rows], p_b[rows] = mass[heavy, node[rows]], mom[heavy, node[rows]]
                partner[rows] = heavy
                rigid_b[rows] = True
        if opts.interface == "perfect":
            normal, sep, mu = np.zeros_like(p_a), None, 0.0
            law, detector = "perfect", "velocity"
        else:
            most = self.mu if self.mu_table is None else float(self.mu_table.max())
            law = "frictionless" if opts.law == "frictionless" or most == 0.0 else "coulomb"
            normal, sep, detector = planes.normal, planes.separation, opts.detector
            if detector == "velocity":  # no separation measured; the law ignores it
                sep = np.zeros_like(sep)
            mu = self.pair_mu(a, b, mass[:, node])
        dp, touching = lr_contact.contact_momentum(
            m_a,
            m_b,
            p_a,
            p_b,
            normal,
            sep,
            mu=mu,
            law=law,
            detector=detector,
            rigid_a=rigid_a,
            rigid_b=rigid_b,
        )
        if rigid_a is not None:
            stays = lumped & rigid_a  # a scripted a keeps its script (LR eq. 50 corrects a alone)
            dp[stays] = 0.0
            touching = touching & ~stays
        lumped = partner < 0
        np.add.at(delta, (a, node), dp)
        pair = ~lumped
        np.add.at(delta, (partner[pair], node[pair]), -dp[pair])
        if opts.lump == "conservative" and lumped.any():
            ln, la, ldp = node[lumped], a[lumped], dp[lumped]
            share = mass[:, ln] / m_b[lumped][None, :]  # (M, L)
            share[la, np.arange(ln.size)] = 0.0
            mats = np.repeat(np.arange(self.n_materials), ln.size)
            nodes_rep = np.tile(ln, self.n_materials)
            spread = (share[..., None] * ldp[None]).reshape(-1, ldp.shape[1])
            np.add.at(delta, (mats, nodes_rep), -spread)
        drift = delta.sum(axis=(0, 1))
        if kinematic is not None:  # the scripted fields' reactions: reported, not applied
            absorbed = np.where(kinematic[..., None], delta, 0.0)
            delta = np.where(kinematic[..., None], 0.0, delta)
        return delta, int(touching.sum()), drift, absorbed
